"""The Python API checks what the command line checks (issue 38): integer counts and their scale,
angles in radians, bands last, a class map on another grid, a reference in radians; and its
messages name Python arguments (``wavelengths=``), not command-line flags."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from brdfcorr._entry import entered
from brdfcorr.correction import normalize
from brdfcorr.errors import GridMismatchError, InputError, ParameterError
from brdfcorr.testing import example_table, synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")


@pytest.fixture(scope="module")
def scene():
    return synthetic_scene(ny=24, nx=32)


def _angles(scene) -> dict:
    return {name: scene[name] for name in ANGLES}


def test_integer_counts_without_a_scale_are_refused_in_python_words(scene):
    counts = (scene["reflectance"] * 10000).astype(np.uint16)
    with pytest.raises(InputError, match=r"integer counts \(uint16\) without a scale_factor") as caught:
        normalize(counts, scene["classes"], _angles(scene), example_table())
    assert "reflectance * scale + offset" in str(caught.value) and "--scale" not in str(caught.value)


def test_integer_counts_with_scale_and_offset_are_corrected_as_factors(scene):
    # Sentinel-2 L2A from baseline 04.00: reflectance = counts * 0.0001 - 0.1 (an offset left out
    # would shift every corrected value by 0.1 * (factor - 1)).
    factors = scene["reflectance"].clip(0, 5)
    counts = np.round((factors + 0.1) / 0.0001).astype(np.uint16)
    counts.attrs.update(scale_factor=0.0001, add_offset=-0.1)
    stored = counts * 0.0001 - 0.1  # what the counts stand for, exactly
    expected = normalize(stored.astype(np.float32), scene["classes"], _angles(scene), example_table()).reflectance
    corrected = normalize(counts, scene["classes"], _angles(scene), example_table()).reflectance
    np.testing.assert_allclose(corrected.values, expected.values, rtol=1e-5, atol=1e-6)
    assert corrected.attrs["brdf_input_offset"] == -0.1


def test_angles_in_radians_are_refused_numpy_at_once_dask_when_computed(scene):
    radians = {name: np.radians(scene[name]) for name in ANGLES}
    with pytest.raises(InputError, match=r"angles: the angles look like radians \(sza 0\.5"):
        normalize(scene["reflectance"], scene["classes"], radians, example_table())
    chunked = {name: layer.chunk({"y": 12}) for name, layer in radians.items()}
    lazy = normalize(scene["reflectance"].chunk({"y": 12}), scene["classes"], chunked, example_table())
    with pytest.raises(InputError, match="look like radians.*np.degrees converts them"):
        lazy.reflectance.compute()
    # The same layers in degrees pass, numpy and dask alike.
    normalize(scene["reflectance"].chunk({"y": 12}), scene["classes"], _angles(scene), example_table()).qa.compute()


@pytest.mark.parametrize("as_numpy", [True, False])
def test_bands_last_is_refused_with_the_transpose_that_fixes_it(scene, as_numpy):
    cube = scene["reflectance"].transpose("y", "x", "band")
    if as_numpy:
        with pytest.raises(InputError, match=r"bands last, \(y, x, band\); transpose to \(band, y, x\): "
                                             r"np.moveaxis\(reflectance, -1, 0\)"):
            normalize(cube.values, scene["classes"].values, {n: scene[n].values for n in ANGLES}, example_table())
    else:
        with pytest.raises(InputError, match=r"transpose to \(band, y, x\): reflectance.transpose\('band', 'y', 'x'\)"):
            normalize(cube, scene["classes"], _angles(scene), example_table())


def test_messages_name_python_arguments_in_python_and_flags_in_the_cli(scene):
    bare = scene["reflectance"].drop_vars("wavelength")  # the table's class 2 is per wavelength
    with pytest.raises(ParameterError, match="wavelengths=") as caught:
        normalize(bare, scene["classes"], _angles(scene), example_table())
    assert "--wavelengths" not in str(caught.value)
    with entered("cli"), pytest.raises(ParameterError, match="--wavelengths"):
        normalize(bare, scene["classes"], _angles(scene), example_table())
    with entered("chain"), pytest.raises(ParameterError, match="inputs.wavelengths"):
        normalize(bare, scene["classes"], _angles(scene), example_table())


def test_a_class_map_on_another_grid_names_align_class_map(scene):
    other = scene["classes"].rio.write_crs("EPSG:32633")
    with pytest.raises(GridMismatchError, match=r"brdfcorr.strata.align_class_map\(classes, reflectance\)"):
        normalize(scene["reflectance"], other, _angles(scene), example_table())


def test_a_reference_sun_zenith_in_radians_is_refused(scene):
    with pytest.raises(ParameterError, match=r"reference sza = 0.78 looks like radians \(44.69 deg\)"):
        normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table(), reference={"sza": 0.78})
    normalize(scene["reflectance"], scene["classes"], _angles(scene), example_table(), reference={"sza": 0})


def test_a_coefficient_set_by_name_and_no_class_map_correct_every_pixel(scene):
    from brdfcorr.models.coefficients import load_coefficients
    from brdfcorr.params import ClassEntry, ParameterTable

    table = ParameterTable(classes=[ClassEntry(**load_coefficients("roy2017").table_entry(1))])
    ones = xr.ones_like(scene["classes"])
    expected = normalize(scene["reflectance"], ones, _angles(scene), table, reference={"sza": 45})
    corrected = normalize(scene["reflectance"], None, _angles(scene), "roy2017", reference={"sza": 45})
    np.testing.assert_array_equal(corrected.reflectance.values, expected.reflectance.values)
    assert not np.any(corrected.reflectance.values == scene["reflectance"].values)  # every pixel corrected
    with pytest.raises(Exception, match="roy2071"):
        normalize(scene["reflectance"], None, _angles(scene), "roy2071")
