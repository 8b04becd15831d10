"""Class names as legends show them (brdfcorr.plot._display.display_name), NDVI strata included."""

import pytest

from brdfcorr.plot._display import display_name
from brdfcorr.strata import _bin_names


def test_the_names_classes_ndvi_writes_read_as_ranges():
    # The names of the strata module itself (edges -0.05, 0.3, 0.7): below, between and above.
    names = _bin_names((-0.05, 0.3, 0.7))
    assert [display_name(names[k]) for k in sorted(names)] == [
        "NDVI < -0.05", "NDVI -0.05–0.30", "NDVI 0.30–0.70", "NDVI ≥ 0.70"]


@pytest.mark.parametrize("name, shown", [("roof_tile", "roof tile"), ("class_2", "class 2"),
                                         ("ndvi_high", "ndvi high")])
def test_other_names_lose_their_underscores(name, shown):
    assert display_name(name) == shown
