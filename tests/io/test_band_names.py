"""Bands found by their names (issue 16): angle bands by their descriptions, Sentinel-2 and Landsat
OLI band names as wavelengths; ``validate`` refuses what ``run`` refuses."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
import xarray as xr
from click.testing import CliRunner

from brdfcorr import io
from brdfcorr.cli import main
from brdfcorr.errors import InputError
from brdfcorr.testing import synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")


@pytest.fixture(scope="module")
def scene():
    return synthetic_scene(ny=24, nx=32)


@pytest.fixture(scope="module")
def files(scene, tmp_path_factory, write_example_scene):
    return write_example_scene(tmp_path_factory.mktemp("names"), scene)


def write_angles(path, scene, order, descriptions):
    """A 4-band angle raster with the layers of ``order`` and the band descriptions given (None:
    none written)."""
    stack = xr.concat([scene[name] for name in order], dim="band").assign_coords(band=[1, 2, 3, 4])
    stack.name = None  # else rioxarray describes every band by the name
    stack.attrs = {} if descriptions is None else {"long_name": tuple(descriptions)}
    stack.rio.write_nodata(np.nan, encoded=False, inplace=True).rio.to_raster(path)
    return path


def correct(files, angles, output):
    return CliRunner().invoke(main, [str(a) for a in (
        "correct", files["image"], "--angles", angles, "--classes", files["classes"], "--params", files["params"],
        "-o", output, "--chunk", 16, "--ref-sza", 35)])


# ------------------------------------------------------------------------------------ angle bands
@pytest.mark.parametrize("descriptions", [
    ("vza", "vaa", "sza", "saa"),
    ("View Zenith", "sensor_azimuth_angle", "SOLAR_ZENITH", "sun-azimuth"),
], ids=["short names", "synonyms"])
def test_angle_bands_are_read_by_name(files, scene, tmp_path, descriptions):
    path = write_angles(tmp_path / "angles.tif", scene, ("vza", "vaa", "sza", "saa"), descriptions)
    layers = io.open_angles(path)
    for name in ANGLES:
        np.testing.assert_array_equal(layers[name].values, scene[name].values)
    standard, named = tmp_path / "standard.tif", tmp_path / "named.tif"
    assert correct(files, files["angles"], standard).exit_code == 0
    result = correct(files, path, named)
    assert result.exit_code == 0, result.output
    with rasterio.open(standard) as a, rasterio.open(named) as b:
        np.testing.assert_array_equal(a.read(), b.read())


@pytest.mark.parametrize("descriptions", [
    ("vza", "vaa", "sza", "Band 4"),  # partial
    ("sza", "sza", "vza", "vaa"),  # one angle twice, one missing
    ("solar_zenith", "sza", "vza", "vaa"),  # synonyms contradicting each other
], ids=["partial", "twice", "contradictory"])
def test_partial_or_contradictory_angle_names_are_one_line_errors(files, scene, tmp_path, descriptions):
    path = write_angles(tmp_path / "angles.tif", scene, ANGLES, descriptions)
    with pytest.raises(InputError, match="do not name each of sza, saa, vza, vaa once"):
        io.open_angles(path)
    result = correct(files, path, tmp_path / "out.tif")
    assert result.exit_code == 2
    errors = [line for line in result.output.splitlines() if "band descriptions" in line]
    assert len(errors) == 1 and str(path) in errors[0] and repr(descriptions[0]) in errors[0]
    assert not (tmp_path / "out.tif").exists()


@pytest.mark.parametrize("descriptions", [None, ("Band 1", "Band 2", "Band 3", "Band 4"), ("sza",) * 4],
                         ids=["none", "generic", "array name on every band"])
def test_angle_bands_without_names_are_positional(scene, tmp_path, descriptions):
    path = write_angles(tmp_path / "angles.tif", scene, ANGLES, descriptions)
    with rasterio.open(path) as dataset:
        assert dataset.descriptions == (descriptions or (None,) * 4)
    layers = io.open_angles(path)
    for name in ANGLES:
        np.testing.assert_array_equal(layers[name].values, scene[name].values)


# --------------------------------------------------------------------------- validate agrees with run
def _exit_codes(chain):
    validate = CliRunner().invoke(main, ["validate", str(chain)])
    run = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    return validate, run


def test_validate_refuses_a_glob_matching_nothing_as_run_does(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    for images in (["scenes/*/imagee.tif"], ["scenes/*/image.tif", "scenes/*/other.tif"]):
        chain = write_chain(tmp_path, inputs={"images": images, "angles": {"path": "{dir}/angles.tif"},
                                              "classes": "{dir}/classes.tif"})
        validate, run = _exit_codes(chain)
        assert validate.exit_code == run.exit_code == 2, (validate.output, run.output)
        assert "matches no file" in validate.output and "matches no file" in run.output
    assert not (tmp_path / "out").exists()


def test_validate_warns_only_for_a_folder_not_there_yet(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path, inputs={"images": ["later/*/image.tif"], "angles": {"path": "{dir}/angles.tif"},
                                          "classes": "{dir}/classes.tif"})
    result = CliRunner().invoke(main, ["validate", str(chain)])
    assert result.exit_code == 0, result.output
    assert "warning" in result.output and "matches no file" in result.output


def test_quicklook_bands_beyond_the_image_are_refused_by_validate_and_run(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2)  # 4-band images
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}, "quicklook": {"bands": [5, 3, 2]}})
    validate, run = _exit_codes(chain)
    assert validate.exit_code == run.exit_code == 2, (validate.output, run.output)
    for result in (validate, run):
        assert "steps.quicklook.bands [5, 3, 2] needs 5 bands" in result.output
        assert "has 4 (and 1 more)" in result.output
    assert not (tmp_path / "out").exists()  # refused before anything was corrected
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}, "quicklook": {"bands": [4, 3, 2]}})
    validate, run = _exit_codes(chain)
    assert validate.exit_code == run.exit_code == 0, (validate.output, run.output)


# ------------------------------------------------------------------------------------- wavelengths
def write_image(path, descriptions, tags=None):
    image = synthetic_scene(8, 8, wavelengths=tuple(range(500, 500 + 10 * len(descriptions), 10)))["reflectance"]
    image = image.drop_vars("wavelength")
    image.attrs = {"long_name": tuple(descriptions), **(tags or {})}
    image.rio.to_raster(path)
    return path


def test_sentinel2_band_names_give_the_s2a_centres(tmp_path):
    # ESA S2 MSI spectral responses, Sentinel-2A central wavelengths [nm]
    path = write_image(tmp_path / "s2.tif", ["B02", "b3", "B4", "B8A", "B11", "B12", "B01"])
    expected = [492.4, 559.8, 664.6, 864.7, 1613.7, 2202.4, 442.7]
    np.testing.assert_array_equal(io.band_wavelengths(io.open_image(path), path), expected)
    np.testing.assert_array_equal(io.open_image(path)["wavelength"].values, expected)


def test_landsat_band_names_need_the_sensor(tmp_path):
    names = ["SR_B2", "SR_B3", "SR_B4", "SR_B5"]
    plain = write_image(tmp_path / "plain.tif", names)
    assert io.band_wavelengths(io.open_image(plain), plain) is None
    stated = write_image(tmp_path / "oli.tif", names, {"SENSOR_ID": "OLI_TIRS"})
    np.testing.assert_array_equal(io.band_wavelengths(io.open_image(stated), stated),
                                  [482.0, 562.0, 655.0, 865.0])  # Landsat 8 Data Users Handbook
    stated = write_image(tmp_path / "oli_b.tif", ["B2", "B3", "B4", "B5"], {"sensor": "OLI"})
    np.testing.assert_array_equal(io.band_wavelengths(io.open_image(stated), stated),
                                  [482.0, 562.0, 655.0, 865.0])
    explicit = io.band_wavelengths(io.open_image(plain), plain, [480, 560, 650, 860])
    np.testing.assert_array_equal(explicit, [480, 560, 650, 860])


@pytest.mark.parametrize("descriptions", [
    ["B2", "B3", "SR_B4"],  # a mix of Sentinel-2 and Landsat names
    ["B2", "B3", "red"],
    ["B13", "B2", "B3"],  # no Sentinel-2 band 13
    ["Band 1", "Band 2", "Band 3"],
], ids=["s2 and landsat", "s2 and words", "no such band", "generic"])
def test_ambiguous_band_names_give_no_wavelengths(tmp_path, descriptions):
    path = write_image(tmp_path / "image.tif", descriptions)
    assert io.band_wavelengths(io.open_image(path), path) is None
    assert "wavelength" not in io.open_image(path).coords


def test_output_bands_are_described_by_wavelength_when_the_input_has_no_descriptions(tmp_path,
                                                                                   write_example_scene):
    # rioxarray writes the array's name on every band without descriptions: "reflectance" x N.
    paths = write_example_scene(tmp_path, synthetic_scene(ny=16, nx=16))
    with rasterio.open(paths["image"], "r+") as dataset:
        for band in range(1, dataset.count + 1):
            dataset.set_band_description(band, "")
    result = CliRunner().invoke(main, ["correct", str(paths["image"]), "--angles", str(paths["angles"]),
                                       "--classes", str(paths["classes"]), "--params", str(paths["params"]),
                                       "--wavelengths", "480,560,660,830", "-o", str(tmp_path / "out.tif")])
    assert result.exit_code == 0, result.output
    with rasterio.open(tmp_path / "out.tif") as dataset:
        assert dataset.descriptions == ("480 nm", "560 nm", "660 nm", "830 nm")
