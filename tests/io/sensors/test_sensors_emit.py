"""EMIT L2A reflectance and L1B OBS NetCDF as image and angle sources, on small granules written
here in the layout of EMIT's V001 NetCDF (brdfcorr/io/sensors/emit.py names the items).

The orthorectification is checked against a direct loop over the GLT cells (EMIT's rule: the cell
(i, j) shows swath pixel (glt_y - 1, glt_x - 1), none where a GLT value is 0); the correction factor
against the public model function at the looped-up angles."""

from __future__ import annotations

import dask.array as da
import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import SensorInputError
from brdfcorr.io.rasters import open_image
from brdfcorr.io.sensors import read_angles
from brdfcorr.io.sensors.emit import apply_glt, read_emit_image, read_emit_obs
from brdfcorr.models import torrance_sparrow
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable
from brdfcorr.testing.products import EMIT_OBS_BAND_NAMES

DOWNTRACK, CROSSTRACK = 8, 6
ORTHO_Y, ORTHO_X = 9, 11
FILL = -9999.0
WAVELENGTH = np.array([452.3, 551.4, 660.1, 857.8, 1245.6])
FWHM = np.array([8.4, 8.5, 8.5, 8.6, 8.8])
GEOTRANSFORM = [-116.2, 0.000542232520256, 0.0, 36.4, 0.0, -0.000542232520256]
OBS_BANDS = list(EMIT_OBS_BAND_NAMES)  # the real granules' band names, in order


def glt(seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A GLT of the ortho grid: every swath pixel placed once at a shuffled cell (a rotated swath
    lands on scattered cells), the rest 0, and a few cells showing the same pixel twice (as
    nearest-neighbour GLTs do at the swath's edges)."""
    rng = np.random.default_rng(seed)
    glt_x = np.zeros((ORTHO_Y, ORTHO_X), "int32")
    glt_y = np.zeros((ORTHO_Y, ORTHO_X), "int32")
    cells = rng.permutation(ORTHO_Y * ORTHO_X)[: DOWNTRACK * CROSSTRACK + 3]
    rows, cols = np.meshgrid(np.arange(DOWNTRACK), np.arange(CROSSTRACK), indexing="ij")
    pixel_rows = np.concatenate([rows.ravel(), [0, 7, 4]])
    pixel_cols = np.concatenate([cols.ravel(), [0, 5, 2]])
    glt_y.flat[cells], glt_x.flat[cells] = pixel_rows + 1, pixel_cols + 1
    return glt_x, glt_y


def swath_reflectance(seed: int = 4) -> np.ndarray:
    rng = np.random.default_rng(seed)
    cube = rng.uniform(0.02, 0.6, size=(DOWNTRACK, CROSSTRACK, WAVELENGTH.size)).astype("float32")
    cube[2, 3, :] = FILL
    return cube


def swath_obs() -> np.ndarray:
    """(downtrack, crosstrack, 11) obs: sun fixed, view zenith across track, the sensor towards
    100 deg (left) or 280 deg (right of the track), one filled pixel."""
    obs = np.zeros((DOWNTRACK, CROSSTRACK, len(OBS_BANDS)), "float32")
    across = np.arange(CROSSTRACK) - (CROSSTRACK - 1) / 2
    obs[..., 0] = 400000.0
    obs[..., 1] = np.where(across < 0, 100.0, 280.0)[None, :]
    obs[..., 2] = (np.abs(across) * 3.0)[None, :]
    obs[..., 3] = 160.0 + np.arange(DOWNTRACK)[:, None] * 0.5
    obs[..., 4] = 40.0 - np.arange(DOWNTRACK)[:, None] * 0.25
    obs[5, 1, :] = FILL
    return obs


def write_granule(path, name: str, cube: np.ndarray, band_parameters: dict, glt_arrays=None) -> None:
    """A granule in EMIT's NetCDF layout: root variable, sensor_band_parameters, location (GLT)."""
    glt_x, glt_y = glt() if glt_arrays is None else glt_arrays
    root = xr.Dataset({name: (("downtrack", "crosstrack", "bands"), cube)},
                      attrs={"geotransform": GEOTRANSFORM, "spatial_ref": rasterio.crs.CRS.from_epsg(4326).to_wkt(),
                             "title": "EMIT L2A Estimated Surface Reflectance 60 m"})
    root.to_netcdf(path, engine="h5netcdf", encoding={name: {"_FillValue": np.float32(FILL)}})
    xr.Dataset({key: ("bands", values) for key, values in band_parameters.items()}).to_netcdf(
        path, mode="a", group="sensor_band_parameters", engine="h5netcdf")
    rng = np.random.default_rng(0)
    xr.Dataset({
        "glt_x": (("ortho_y", "ortho_x"), glt_x), "glt_y": (("ortho_y", "ortho_x"), glt_y),
        "lat": (("downtrack", "crosstrack"), rng.uniform(36.39, 36.4, (DOWNTRACK, CROSSTRACK))),
        "lon": (("downtrack", "crosstrack"), rng.uniform(-116.2, -116.19, (DOWNTRACK, CROSSTRACK))),
    }).to_netcdf(path, mode="a", group="location", engine="h5netcdf")


@pytest.fixture
def granules(tmp_path):
    rfl = tmp_path / "EMIT_L2A_RFL_001_20230612T201034_2316313_005.nc"
    obs = tmp_path / "EMIT_L1B_OBS_001_20230612T201034_2316313_005.nc"
    write_granule(rfl, "reflectance", swath_reflectance(),
                  {"wavelengths": WAVELENGTH, "fwhm": FWHM, "good_wavelengths": np.array([1, 1, 1, 1, 0], "uint8")})
    write_granule(obs, "obs", swath_obs(), {"observation_bands": np.array(OBS_BANDS, dtype=object)})
    return rfl, obs


def loop_ortho(swath: np.ndarray) -> np.ndarray:
    """(bands, ortho_y, ortho_x) by a loop over the GLT cells, fill -> NaN."""
    glt_x, glt_y = glt()
    out = np.full((swath.shape[2], ORTHO_Y, ORTHO_X), np.nan)
    for i in range(ORTHO_Y):
        for j in range(ORTHO_X):
            if glt_x[i, j] != 0 and glt_y[i, j] != 0:
                pixel = swath[glt_y[i, j] - 1, glt_x[i, j] - 1, :].astype(float)
                out[:, i, j] = np.where(pixel == FILL, np.nan, pixel)
    return out


def test_apply_glt_matches_a_direct_loop():
    swath = np.random.default_rng(5).normal(size=(DOWNTRACK, CROSSTRACK, 3))
    glt_x, glt_y = glt()
    np.testing.assert_array_equal(apply_glt(swath, glt_x, glt_y), loop_ortho(swath))
    # A box of the swath with its offset gives the same cells.
    box = swath[1:, 2:, :]
    inside = (glt_y > 1) & (glt_x > 2)
    np.testing.assert_array_equal(apply_glt(box, glt_x * inside, glt_y * inside, 1, 2),
                                  loop_ortho(swath) * np.where(inside, 1.0, np.nan))


def test_image_on_the_glt_grid_with_wavelengths_and_georeferencing(granules):
    rfl, _ = granules
    image = read_emit_image(rfl, chunks=4)  # 3 x 3 output chunks: blocks read boxes of the swath
    assert image.dims == ("band", "y", "x") and image.shape == (5, ORTHO_Y, ORTHO_X)
    assert isinstance(image.data, da.Array) and image.data.numblocks == (1, 3, 3)
    values = image.values
    np.testing.assert_array_equal(values, loop_ortho(swath_reflectance()).astype("float32"))
    glt_x, _ = glt()
    assert np.isnan(values[:, glt_x == 0]).all()  # cells without a swath pixel: nodata
    assert np.isfinite(values).sum() == 5 * (DOWNTRACK * CROSSTRACK + 3 - 1)  # one filled pixel
    np.testing.assert_array_equal(image["wavelength"].values, WAVELENGTH)
    np.testing.assert_array_equal(image["fwhm"].values, FWHM)
    assert image.rio.crs.to_epsg() == 4326
    assert image.rio.transform() == Affine.from_gdal(*GEOTRANSFORM)
    assert image["x"].values[0] == pytest.approx(GEOTRANSFORM[0] + 0.5 * GEOTRANSFORM[1], abs=1e-12)
    np.testing.assert_array_equal(open_image(rfl).values, values)  # the image dispatch: same cube


def test_swath_without_ortho(granules):
    rfl, _ = granules
    swath = read_emit_image(rfl, ortho=False)
    expected = np.moveaxis(swath_reflectance(), 2, 0)
    expected = np.where(expected == FILL, np.nan, expected)
    np.testing.assert_array_equal(swath.values, expected)
    assert swath.rio.crs is None


def test_obs_angles_by_band_name_on_the_glt_grid(granules):
    _, obs = granules
    angles = read_angles("emit", obs)
    stored = swath_obs()
    for key, index in (("vaa", 1), ("vza", 2), ("saa", 3), ("sza", 4)):
        expected = loop_ortho(stored[..., index:index + 1])[0]
        np.testing.assert_array_equal(angles[key].values, expected.astype("float32"), err_msg=key)
    assert angles["vaa"].attrs["source_band"] == OBS_BANDS[1]
    assert angles["sza"].rio.transform() == Affine.from_gdal(*GEOTRANSFORM)
    flipped = read_emit_obs(obs, view_azimuth="from_sensor")
    valid = np.isfinite(angles["vaa"].values)
    np.testing.assert_array_equal(flipped["vaa"].values[valid], (angles["vaa"].values[valid] + 180) % 360)


def test_obs_band_missing_is_named(tmp_path):
    path = tmp_path / "obs.nc"
    names = [name.replace("To-sun zenith", "Sun elevation") for name in OBS_BANDS]
    write_granule(path, "obs", swath_obs(), {"observation_bands": np.array(names, dtype=object)})
    with pytest.raises(SensorInputError, match="no obs band for sza"):
        read_emit_obs(path)


@pytest.mark.parametrize(("change", "message"), [
    (lambda x, y: (x * 0 - 1, y), "negative values"),
    (lambda x, y: (x, np.where(y > 0, y + DOWNTRACK, 0)), "points beyond the swath of 8 x 6"),
])
def test_bad_glt_is_one_clear_error(tmp_path, change, message):
    path = tmp_path / "rfl.nc"
    write_granule(path, "reflectance", swath_reflectance(), {"wavelengths": WAVELENGTH, "fwhm": FWHM},
                  glt_arrays=change(*glt()))
    with pytest.raises(SensorInputError, match=message):
        read_emit_image(path)


def test_glt_cells_holding_its_declared_fill_are_no_pixel(granules, tmp_path):
    # EMIT's NetCDF converter declares _FillValue -9999 on the GLT; a subset saved again through
    # xarray holds it where the granule held 0 (no pixel): refused as "negative values".
    import h5py

    rfl, _ = granules
    filled = tmp_path / "EMIT_L2A_RFL_001_filled.nc"
    filled.write_bytes(rfl.read_bytes())
    with h5py.File(filled, "r+") as h5file:
        for name in ("glt_x", "glt_y"):
            values = h5file[f"location/{name}"][()]
            del h5file[f"location/{name}"]
            dataset = h5file.create_dataset(f"location/{name}", data=np.where(values == 0, -9999, values))
            dataset.attrs["_FillValue"] = np.array(-9999, dtype=values.dtype)
    np.testing.assert_array_equal(read_emit_image(filled).values, read_emit_image(rfl).values)


def test_cli_correct_an_emit_granule_with_its_obs(granules, tmp_path):
    rfl, obs = granules
    image = read_emit_image(rfl)
    classes = xr.full_like(image.isel(band=0, drop=True), 1, dtype="uint8").compute().rio.write_nodata(255)
    classes.attrs = {}
    classes.rio.to_raster(tmp_path / "classes.tif")
    tile = load_material("roof_tile")
    ParameterTable(classes=[{"id": 1, "name": "roof_tile", "model": "torrance_sparrow",
                             "params": tile.params}]).save(tmp_path / "params.yaml")
    result = CliRunner().invoke(main, [
        "correct", str(rfl), "--angles", str(obs), "--angles-kind", "emit",
        "--classes", str(tmp_path / "classes.tif"), "--params", str(tmp_path / "params.yaml"),
        "-o", str(tmp_path / "out.tif"), "--no-limits", "--ref-vza", "0", "--no-progress",
    ])
    assert result.exit_code == 0, result.output

    stored = swath_obs()
    vaa, vza, saa, sza = (loop_ortho(stored[..., i:i + 1])[0] for i in (1, 2, 3, 4))
    phi = np.abs(saa - vaa)
    phi = np.where(phi > 180, 360 - phi, phi)
    with np.errstate(invalid="ignore"):
        factor = torrance_sparrow(sza, 0.0, 0.0, **tile.params) / torrance_sparrow(sza, vza, phi, **tile.params)
    expected = loop_ortho(swath_reflectance()) * factor[None]
    with rasterio.open(tmp_path / "out.tif") as output:
        corrected = output.read().astype(float)
        assert output.crs.to_epsg() == 4326
        assert output.transform.almost_equals(Affine.from_gdal(*GEOTRANSFORM))
        assert output.tags()["wavelength"] == "452.3,551.4,660.1,857.8,1245.6"
    valid = np.isfinite(expected)
    assert valid[0].sum() == DOWNTRACK * CROSSTRACK + 3 - 2  # a filled reflectance and a filled obs pixel
    assert np.isnan(corrected[~valid]).all()
    np.testing.assert_allclose(corrected[valid], expected[valid], rtol=2e-6)
    assert np.ptp(factor[valid[0]]) > 0.01
