"""NEON AOP reflectance HDF5 as image and angle source, on small files written here in the layout of
NEON's DP1.30006.001 HDF5 (brdfcorr/io/sensors/neon.py names the items).

Expected values are computed independently of the reader: reflectance = stored / Scale_Factor
(NEON's definition of its Scale_Factor), the transform from the ENVI map-info rule written out by
hand, the correction factor from the public model function at the stored angles."""

from __future__ import annotations

import re
import sys

import dask.array as da
import h5py
import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import InputError, SensorInputError
from brdfcorr.geometry import relative_azimuth
from brdfcorr.io.rasters import open_image
from brdfcorr.io.scene import SceneSources, open_scene
from brdfcorr.io.sensors import read_angles
from brdfcorr.io.sensors.neon import parse_map_info, read_neon_angles, read_neon_image
from brdfcorr.models import torrance_sparrow
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable

ROWS, COLS = 7, 9
WAVELENGTH = np.array([381.6, 561.2, 851.7, 1601.4])
FWHM = np.array([5.1, 5.3, 5.5, 6.0])
SCALE_FACTOR = 10000.0
IGNORE = -9999.0
MAP_INFO = "UTM,  1.000,  1.000,  368000.00,  4307000.00,  1.0000000000e+000,  1.0000000000e+000,  18,  North,  WGS-84,  units=Meters, rotation=0.000"
SUN = {"162512": (34.5, 151.25)}  # flight line: (Solar_Zenith_Angle, Solar_Azimuth_Angle) [deg]


def stored_cube(seed: int = 1) -> np.ndarray:
    """(rows, columns, bands) int16 as NEON stores it: reflectance x 10000, two ignored pixels."""
    rng = np.random.default_rng(seed)
    cube = rng.integers(200, 6000, size=(ROWS, COLS, WAVELENGTH.size)).astype("int16")
    cube[0, 0, :] = IGNORE
    cube[3, 5, :] = IGNORE
    return cube


def view_angles() -> tuple[np.ndarray, np.ndarray]:
    """to-sensor zenith and azimuth rasters [deg]: zenith across the line, azimuth 95 deg on the
    left half, 275 deg on the right (the sensor is overhead the middle column), one ignored pixel."""
    columns = np.arange(COLS) - (COLS - 1) / 2
    vza = np.broadcast_to(np.abs(columns) * 2.5, (ROWS, COLS)).astype("float32").copy()
    vaa = np.where(columns < 0, 95.0, 275.0)[None, :].repeat(ROWS, 0).astype("float32")
    vza[6, 8] = IGNORE
    return vza, vaa


def write_neon(path, cube=None, sun=SUN, site="SERC", logs_as_attrs=False, brdf_logs=False):
    """A reflectance file in NEON's layout: /SITE/Reflectance/{Reflectance_Data, Metadata/...}; with
    ``brdf_logs`` each log holds the FlexBRDF entries of the bidirectional (.002) product."""
    cube = stored_cube() if cube is None else cube
    vza, vaa = view_angles()
    with h5py.File(path, "w") as h5file:
        group = h5file.create_group(f"{site}/Reflectance")
        data = group.create_dataset("Reflectance_Data", data=cube, chunks=(4, 4, cube.shape[2]))
        data.attrs.update({"Scale_Factor": SCALE_FACTOR, "Data_Ignore_Value": IGNORE,
                           "Description": "Atmospherically corrected reflectance.",
                           "Dimension_Labels": "Line, Sample, Wavelength", "Interleave": "BIP"})
        metadata = group.create_group("Metadata")
        wavelength = metadata.create_dataset("Spectral_Data/Wavelength", data=WAVELENGTH)
        wavelength.attrs["Units"] = "nanometers"
        metadata.create_dataset("Spectral_Data/FWHM", data=FWHM)
        metadata.create_dataset("Coordinate_System/Map_Info", data=MAP_INFO.encode())
        metadata.create_dataset("Coordinate_System/EPSG Code", data=b"32618")
        for name, values in (("to-sensor_Zenith_Angle", vza), ("to-sensor_Azimuth_Angle", vaa)):
            metadata.create_dataset(name, data=values).attrs["Data_Ignore_Value"] = IGNORE
        for line, (zenith, azimuth) in sun.items():
            log = metadata.create_group(f"Logs/{line}")
            if logs_as_attrs:
                log.attrs.update({"Solar_Zenith_Angle": zenith, "Solar_Azimuth_Angle": azimuth})
            else:
                log.create_dataset("Solar_Zenith_Angle", data=zenith)
                log.create_dataset("Solar_Azimuth_Angle", data=azimuth)
            if brdf_logs:
                log.create_dataset("BRDF_COEFFS_JSON_for_Hytools", data=b'{"brdf": "coefficients"}')
                log.create_dataset("BRDF_Config_JSON_for_Hytools", data=b'{"brdf": "config"}')
    return path


@pytest.fixture
def neon_file(tmp_path):
    return write_neon(tmp_path / "NEON_D02_SERC_DP1_20210801_162512_reflectance.h5")


def test_map_info_transform_by_the_envi_rule():
    # Reference pixel (1, 1) is the upper-left corner of the upper-left pixel: origin = the tie point.
    assert parse_map_info(MAP_INFO) == Affine(1.0, 0.0, 368000.0, 0.0, -1.0, 4307000.0)
    # Tie point at pixel (1.5, 2.5) (1-based) with 2 m pixels: x0 = 500 - 0.5*2, y0 = 800 + 1.5*2.
    assert parse_map_info("UTM, 1.5, 2.5, 500.0, 800.0, 2.0, 2.0, 18, North") == Affine(2, 0, 499.0, 0, -2, 803.0)
    with pytest.raises(SensorInputError, match="rotated"):
        parse_map_info("UTM, 1, 1, 0, 0, 1, 1, 18, North, WGS-84, units=Meters, rotation=15.0")


def test_image_values_are_stored_over_scale_factor_with_nodata_as_nan(neon_file):
    cube = stored_cube()
    image = read_neon_image(neon_file, chunks=4)
    assert image.dims == ("band", "y", "x") and image.shape == (4, ROWS, COLS)
    assert isinstance(image.data, da.Array) and image.data.chunksize == (4, 4, 4)
    values = image.values
    expected = np.moveaxis(cube, 2, 0).astype("float32") / np.float32(SCALE_FACTOR)
    expected[:, cube[..., 0] == IGNORE] = np.nan
    np.testing.assert_array_equal(values, expected)  # stored / 10000 in float32, exactly
    assert np.isnan(values[:, 0, 0]).all() and np.isnan(values[:, 3, 5]).all()
    assert np.isfinite(values).sum() == 4 * (ROWS * COLS - 2)
    assert image.attrs["brdf_input_scale"] == 1e-4 and image.attrs["brdf_input_offset"] == 0.0
    np.testing.assert_array_equal(image["wavelength"].values, WAVELENGTH)
    np.testing.assert_array_equal(image["fwhm"].values, FWHM)
    assert image.rio.crs.to_epsg() == 32618
    assert image.rio.transform() == Affine(1.0, 0.0, 368000.0, 0.0, -1.0, 4307000.0)
    # Pixel centres: half a pixel inside the corner.
    assert image["x"].values[0] == 368000.5 and image["y"].values[0] == 4306999.5


def test_open_image_dispatches_by_content_and_honours_a_given_scale(neon_file, tmp_path):
    renamed = tmp_path / "scene.dat"  # no telling extension: the content decides
    renamed.write_bytes(neon_file.read_bytes())
    image = open_image(renamed)
    np.testing.assert_array_equal(image.values, read_neon_image(neon_file).values)
    assert image.encoding["source"] == str(renamed)
    scaled = open_image(neon_file, scale=2e-4, wavelengths=[400, 500, 600, 700])
    np.testing.assert_allclose(scaled.values[:, 1, 1], stored_cube()[1, 1, :] * np.float32(2e-4), rtol=1e-7)
    np.testing.assert_array_equal(scaled["wavelength"].values, [400, 500, 600, 700])
    with pytest.raises(InputError, match="4 finite values"):
        open_image(neon_file, wavelengths=[400, 500])


def test_angles_in_brdfcorr_convention(neon_file):
    vza, vaa = view_angles()
    angles = read_angles("neon", neon_file)
    assert set(angles.data_vars) == {"sza", "saa", "vza", "vaa"}
    assert all(isinstance(angles[name].data, da.Array) for name in angles.data_vars)
    np.testing.assert_array_equal(angles["sza"].values, np.full((ROWS, COLS), 34.5))
    np.testing.assert_array_equal(angles["saa"].values, np.full((ROWS, COLS), 151.25))
    expected_vza = np.where(vza == IGNORE, np.nan, vza)
    np.testing.assert_array_equal(angles["vza"].values, expected_vza)
    np.testing.assert_array_equal(angles["vaa"].values, vaa)
    # Sun at 151.25 deg, sensor towards 95 deg on the left half: phi = 56.25 deg (closer to the
    # backscatter side); towards 275 deg on the right: |151.25 - 275| = 123.75 deg.
    phi = relative_azimuth(angles["saa"].values, angles["vaa"].values)
    np.testing.assert_allclose(phi[:, 0], 56.25)
    np.testing.assert_allclose(phi[:, -1], 123.75)
    flipped = read_neon_angles(neon_file, view_azimuth="from_sensor")
    np.testing.assert_array_equal(flipped["vaa"].values, np.where(vaa == 95.0, 275.0, 95.0))
    assert angles["vaa"].rio.transform() == Affine(1.0, 0.0, 368000.0, 0.0, -1.0, 4307000.0)


def test_sun_angles_of_logs_written_as_attributes(tmp_path):
    path = write_neon(tmp_path / "attrs.h5", logs_as_attrs=True)
    angles = read_neon_angles(path)
    assert float(angles["sza"][0, 0]) == 34.5 and float(angles["saa"][0, 0]) == 151.25


def test_a_mosaic_of_several_flight_lines_needs_one_named(tmp_path):
    path = write_neon(tmp_path / "tile.h5", sun={"152012": (30.0, 140.0), "155530": (28.0, 150.0)})
    with pytest.raises(SensorInputError, match=r"2 flight lines .*152012, 155530.*flight_line="):
        read_neon_angles(path)
    chosen = read_neon_angles(path, flight_line=155530)  # as the CLI's YAML reads it: a number
    assert float(chosen["sza"][0, 0]) == 28.0 and chosen.attrs["flight_line"] == "155530"
    with pytest.raises(SensorInputError, match="no sun angles of flight line '999999'"):
        read_neon_angles(path, flight_line="999999")


def test_a_mosaic_tile_takes_each_pixel_s_sun_from_its_data_selection_index(tmp_path):
    # A DP3 tile of two flight lines said which line each pixel is from; every pixel took the sun of
    # the one line named (the other line's pixels 2 deg off in zenith). The index is a position in
    # Data_Files (negative: no line), as NEON's mosaic writes it.
    sun = {"152012": (30.0, 140.0), "155530": (28.0, 150.0)}
    path = write_neon(tmp_path / "tile.h5", sun=sun)
    selection = np.zeros((ROWS, COLS), "int8")
    selection[:, COLS // 2:] = 1
    selection[0, 0] = -1
    with h5py.File(path, "r+") as h5file:
        index = h5file.create_dataset("SERC/Reflectance/Metadata/Ancillary_Imagery/Data_Selection_Index",
                                      data=selection)
        index.attrs["Data_Files"] = (b"NEON_D02_SERC_DP1_20210801_155530_reflectance,"
                                     b"NEON_D02_SERC_DP1_20210801_152012_reflectance")
    angles = read_neon_angles(path, chunks=4)
    assert isinstance(angles["sza"].data, da.Array)
    expected_sza = np.where(selection == 1, 30.0, 28.0)
    expected_saa = np.where(selection == 1, 140.0, 150.0)
    expected_sza[0, 0] = expected_saa[0, 0] = np.nan
    np.testing.assert_array_equal(angles["sza"].values, expected_sza)
    np.testing.assert_array_equal(angles["saa"].values, expected_saa)
    assert angles.attrs["flight_line"] == "each pixel's (Data_Selection_Index)"
    # A line named is the user's word, for every pixel.
    assert np.all(read_neon_angles(path, flight_line="152012")["sza"].values == 30.0)


def test_not_a_neon_layout_is_one_clear_error(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as h5file:
        h5file.create_dataset("data", data=np.zeros((2, 2)))
    with pytest.raises(SensorInputError, match="0 root groups with Reflectance/Reflectance_Data"):
        read_neon_image(path)


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_missing_h5py_names_the_extra(neon_file, monkeypatch):
    monkeypatch.setitem(sys.modules, "h5py", None)  # import h5py now raises ImportError
    with pytest.raises(InputError, match=r"pip install 'brdfcorr\[hdf5\]'"):
        read_neon_image(neon_file)
    with pytest.raises(InputError, match=r"brdfcorr\[hdf5\]"):
        open_image(neon_file)  # falls back to GDAL, whose error then says what to install


def _write_classes(path, like: xr.DataArray, value: int = 1) -> None:
    classes = xr.full_like(like.isel(band=0, drop=True), value, dtype="uint8").compute()
    classes = classes.rio.write_nodata(255)
    classes.attrs = {}
    classes.rio.to_raster(path)


def test_open_scene_puts_image_angles_and_classes_on_one_grid(neon_file, tmp_path):
    _write_classes(tmp_path / "classes.tif", read_neon_image(neon_file))
    scene = open_scene(SceneSources(neon_file, tmp_path / "classes.tif", neon_file, angles_kind="neon"))
    assert scene.statistics.means["sza"] == pytest.approx(34.5)
    assert scene.statistics.ranges["vza"] == (0.0, 10.0)


def test_cli_correct_a_neon_file_with_its_own_angles(neon_file, tmp_path):
    image = read_neon_image(neon_file)
    _write_classes(tmp_path / "classes.tif", image)
    tile = load_material("roof_tile")
    ParameterTable(classes=[{"id": 1, "name": "roof_tile", "model": "torrance_sparrow",
                             "params": tile.params}]).save(tmp_path / "params.yaml")
    before = neon_file.read_bytes()
    result = CliRunner().invoke(main, [
        "correct", str(neon_file), "--angles", str(neon_file), "--angles-kind", "neon",
        "--classes", str(tmp_path / "classes.tif"), "--params", str(tmp_path / "params.yaml"),
        "-o", str(tmp_path / "out.tif"), "--no-limits", "--ref-vza", "0", "--no-progress",
    ])
    assert result.exit_code == 0, result.output
    assert neon_file.read_bytes() == before

    # Independent expectation: stored / 10000 times TS(sza, 0, 0) / TS(sza, vza, phi) at the stored angles.
    vza, vaa = view_angles()
    sza, saa = SUN["162512"]
    phi = np.abs(saa - vaa)  # both azimuths in [0, 360): fold by hand
    phi = np.where(phi > 180, 360 - phi, phi)
    factor = torrance_sparrow(sza, 0.0, 0.0, **tile.params) / torrance_sparrow(sza, vza, phi, **tile.params)
    cube = stored_cube()
    expected = np.moveaxis(cube, 2, 0) / SCALE_FACTOR * factor[None]
    with rasterio.open(tmp_path / "out.tif") as output:
        corrected = output.read().astype(float)
        assert output.crs.to_epsg() == 32618
        assert output.transform == Affine(1.0, 0.0, 368000.0, 0.0, -1.0, 4307000.0)
        assert output.tags()["wavelength"] == "381.6,561.2,851.7,1601.4"
        assert output.tags()["brdf_input_scale"] == "0.0001"
    nodata = (cube[..., 0] == IGNORE) | (vza == IGNORE)
    assert np.isnan(corrected[:, nodata]).all()
    np.testing.assert_allclose(corrected[:, ~nodata], expected[:, ~nodata], rtol=2e-6)
    assert np.ptp(factor[~nodata]) > 0.01  # the view geometry varies enough to matter


def test_the_bidirectional_product_is_normalized_already_and_a_correction_refuses_it(neon_file, tmp_path):
    # DP1/DP3.30006.002 is FlexBRDF-corrected by NEON: corrected again, its values took the factor a
    # second time (exit 0). Told by its logs or, where they are missing, by its name.
    by_logs = write_neon(tmp_path / "tile.h5", brdf_logs=True)
    by_name = write_neon(tmp_path / "NEON_D05_LIRO_DP3_290000_5097000_bidirectional_reflectance.h5")
    for path in (by_logs, by_name):
        assert "DP1/DP3.30006.002" in read_neon_image(path).attrs["brdf_normalized"]
    assert "brdf_normalized" not in read_neon_image(neon_file).attrs  # the directional .001 product
    _write_classes(tmp_path / "classes.tif", read_neon_image(by_logs))
    ParameterTable(classes=[{"id": 1, "name": "flat", "model": "lambertian", "params": {"t0": 0.1}}]).save(
        tmp_path / "params.yaml")
    result = CliRunner().invoke(main, [
        "correct", str(by_logs), "--angles", str(by_logs), "--angles-kind", "neon",
        "--classes", str(tmp_path / "classes.tif"), "--params", str(tmp_path / "params.yaml"),
        "-o", str(tmp_path / "out.tif"), "--no-progress",
    ])
    assert result.exit_code == 2, result.output
    assert re.search(r"tile\.h5 is BRDF-normalized already: NEON's bidirectional reflectance .*"
                     r"correct the directional DP1/DP3\.30006\.001", result.stderr)
    assert not (tmp_path / "out.tif").exists()
