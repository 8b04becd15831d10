"""The chain quicklook: legends name the table's classes (up to six, outside the data), bands are
chosen by wavelength, nodata has its own colour, and a north-up image says where west and east are."""

import numpy as np
import pytest

from brdfcorr.plot._display import NODATA_COLOUR, representative_bands, true_colour_bands
from brdfcorr.plot.quicklook import _stretch, quicklook_figure


def test_legend_names_the_most_frequent_classes():
    rng = np.random.default_rng(0)
    class_map = rng.choice(np.arange(0, 8), size=(30, 40), p=[0.02, 0.3, 0.2, 0.15, 0.12, 0.1, 0.08, 0.03])
    cube = rng.uniform(0.05, 0.3, (3, 30, 40))
    names = {1: "roof_tile", 2: "concrete", 3: "grass", 4: "trees", 5: "soil", 6: "water", 7: "rare"}
    figure = quicklook_figure(cube, cube * 0.9, class_map=class_map.astype(float), class_names=names)
    labels = [text.get_text() for text in figure.legends[0].get_texts()]
    shown = {label.rsplit(" ", 1)[0] for label in labels}
    assert shown == {"roof tile", "concrete", "grass", "trees", "soil", "water"}  # the 6 most frequent
    assert len(labels) == 12  # before and after for each
    assert all(axis.get_legend() is None for axis in figure.axes)  # the legend covers no data


@pytest.mark.parametrize(("wavelengths", "expected"), [
    ([450, 550, 650, 700, 750, 900], [3, 2, 1]),                 # the demo's bands: 650, 550, 450 nm
    (list(np.linspace(377, 2500, 425)), None),                   # AVIRIS-NG: ~665, 560, 490 nm
    ([443, 490, 560, 665, 705, 740, 783, 842, 865, 1610, 2190], [4, 3, 2]),  # Sentinel-2 B1-B12
    ([800, 900, 1000], [3, 2, 1]),                               # no visible bands: the default
    (None, [3, 2, 1]),
])
def test_true_colour_bands_are_chosen_by_wavelength(wavelengths, expected):
    bands = true_colour_bands(wavelengths, 3 if wavelengths is None else len(wavelengths))
    if expected is None:  # an imaging spectrometer: the band centres nearest the targets
        centres = np.asarray(wavelengths)[np.asarray(bands) - 1]
        assert np.all(np.abs(centres - [665, 560, 490]) <= (2500 - 377) / 424 / 2 + 1e-9)
    else:
        assert bands == expected
    assert true_colour_bands(None, 1) == [1]


def test_representative_bands_avoid_the_edges_of_a_spectrometer():
    wavelengths = np.linspace(377, 2500, 425)
    chosen = wavelengths[representative_bands(wavelengths, 425, 4)]
    assert chosen.min() > 450 and chosen.max() < 2300  # not the 377 and 2500 nm edge bands
    assert representative_bands(None, 10, 4) == [0, 3, 6, 9]


def test_nodata_is_drawn_in_its_own_colour_not_as_a_bright_pixel():
    cube = np.full((3, 4, 4), 0.2)
    cube[:, 0, 0] = np.nan
    cube[:, 1, 1] = 0.9  # a bright roof
    rgb = _stretch(cube, (1.0, 99.9))(cube)
    assert tuple(rgb[0, 0]) == NODATA_COLOUR
    assert tuple(rgb[1, 1]) != NODATA_COLOUR


def test_a_north_up_image_names_west_and_east():
    cube = np.random.default_rng(1).uniform(0.05, 0.3, (3, 10, 20))
    labels = [axis.get_xlabel() for axis in quicklook_figure(cube, cube, north_up=True).axes]
    assert sum("west" in label and "east" in label for label in labels) == 3  # both images and the profile
    assert not any("east" in axis.get_xlabel() for axis in quicklook_figure(cube, cube).axes)


@pytest.mark.parametrize(("azimuth", "side"), [(109.0, "east"), (250.0, "west")])
def test_the_profile_names_the_sun_side_as_forward_scattering(azimuth, side):
    # Sun in the east: pixels east of the track are seen from the west, the sensor looking away from
    # the sun (relative azimuth near 180 deg: forward scattering, docs/conventions.md).
    cube = np.random.default_rng(2).uniform(0.05, 0.3, (3, 10, 20))
    figure = quicklook_figure(cube, cube, north_up=True, sun_azimuth=azimuth)
    label = figure.axes[-1].get_xlabel()
    assert f"sun from the {side}" in label and f"{side} side forward scattering" in label
    assert sum(text.get_text().startswith("sun ") for axis in figure.axes[:2] for text in axis.texts) == 2


def test_the_scene_sun_is_a_circular_mean_read_back_from_the_tag():
    import xarray as xr

    from brdfcorr.plot._display import scene_sun_azimuth
    from brdfcorr.tasks.correct import _centre_sun

    azimuth = np.where(np.arange(8)[None, :] % 2, 350.0, 10.0) * np.ones((8, 1))  # north: mean 0, not 180
    angles = {name: xr.DataArray(values, dims=("y", "x")) for name, values in
              (("sza", np.full((8, 8), 40.0)), ("saa", azimuth))}
    zenith, mean_azimuth = _centre_sun(angles)
    assert zenith == 40.0 and min(mean_azimuth, 360.0 - mean_azimuth) < 1e-9
    assert scene_sun_azimuth({"brdf_scene_sun": "zenith 48.1, azimuth 108.7 (scene centre, deg)"}) == 108.7
    assert scene_sun_azimuth({}) is None
