"""`brdfcorr correct` with tilted surfaces (--dem, --slope-aspect, --topographic) and with
--uncertainty: the command writes what the library functions compute, and refuses bad combinations."""

from __future__ import annotations

import re

import numpy as np
import pytest
import rasterio
import rioxarray
import xarray as xr
from click.testing import CliRunner

from brdfcorr import normalize
from brdfcorr.cli import main
from brdfcorr.correction import QA
from brdfcorr.correction.terrain import slope_aspect
from brdfcorr.correction.topographic import topographic_correction
from brdfcorr.correction.uncertainty import correction_uncertainty
from brdfcorr.params import ParameterTable
from brdfcorr.testing import PIXEL, example_table, georeference, synthetic_scene


@pytest.fixture
def scene(scene):
    """A copy of the 32 x 32 template scene (tests/conftest.py) and its arrays as ``data`` (the same
    synthetic_scene, which depends on its seed only)."""
    return {**scene, "data": synthetic_scene(ny=32, nx=32)}


def _dem(tmp_path, heights: np.ndarray):
    dem = georeference(xr.DataArray(heights[None].astype(np.float32), dims=("band", "y", "x")))
    path = tmp_path / "scene" / "dem.tif"
    dem.rio.to_raster(path)
    return path


def _correct(scene, output, *extra):
    args = ["correct", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"],
            "--params", scene["params"], "-o", output, "--no-progress", *extra]
    return CliRunner().invoke(main, [str(a) for a in args])


def _read(path) -> np.ndarray:
    with rasterio.open(path) as dataset:
        return dataset.read()


def test_flat_dem_gives_the_horizontal_result(scene, tmp_path):
    # Slope 0 everywhere: cos i = cos sza (cosine factor 1) and the surface frame is the horizontal one.
    plain, flat = tmp_path / "plain.tif", tmp_path / "flat.tif"
    assert _correct(scene, plain).exit_code == 0
    result = _correct(scene, flat, "--dem", _dem(tmp_path, np.full((32, 32), 120.0)))
    assert result.exit_code == 0, result.output
    np.testing.assert_allclose(_read(flat), _read(plain), rtol=1e-6, equal_nan=True)
    assert "topographic correction cosine" in result.output


def test_tilted_plane_matches_the_library_chain(scene, tmp_path):
    # A plane rising 0.3 m per metre to the north (slope 16.7 deg facing south): the command's output
    # is the cosine correction followed by normalize in the surface frame, as computed here.
    rows = np.arange(32)[:, None] * np.ones((1, 32))
    dem_path = _dem(tmp_path, 100.0 - 0.3 * PIXEL * rows)
    output, qa = tmp_path / "tilted.tif", tmp_path / "qa.tif"
    result = _correct(scene, output, "--dem", dem_path, "--qa", qa, "--ref-sza", "35")
    assert result.exit_code == 0, result.output

    data = scene["data"]
    dem = rioxarray.open_rasterio(dem_path)[0]
    surface = slope_aspect(dem)
    np.testing.assert_allclose(surface.slope.values, np.degrees(np.arctan(0.3)), atol=1e-4)
    np.testing.assert_allclose(surface.aspect.values, 180.0, atol=1e-4)
    angles = {**{a: data[a] for a in ("sza", "saa", "vza", "vaa")}, "slope": surface.slope, "aspect": surface.aspect}
    topographic = topographic_correction(data["reflectance"], angles, method="cosine", classes=data["classes"])
    expected, expected_qa = normalize(
        topographic.reflectance, data["classes"].rio.write_nodata(255), angles, example_table(), {"sza": 35.0},
    )
    np.testing.assert_allclose(_read(output), expected.values, rtol=2e-6, equal_nan=True)
    assert not np.allclose(_read(output), _read_plain(scene, tmp_path), equal_nan=True)
    assert np.array_equal(_read(qa)[0] & ~np.uint8(QA.TOPOGRAPHY_UNCORRECTED), expected_qa.values)


def _read_plain(scene, tmp_path):
    plain = tmp_path / "plain_ref35.tif"
    assert _correct(scene, plain, "--ref-sza", "35").exit_code == 0
    return _read(plain)


def test_slope_aspect_raster_bands_are_found_by_name(scene, tmp_path):
    # Bands described "aspect", "slope" (reversed order): the names decide.
    slope, aspect = np.full((32, 32), 20.0), np.full((32, 32), 90.0)
    layers = georeference(xr.DataArray(np.stack([aspect, slope]).astype(np.float32), dims=("band", "y", "x")))
    layers.attrs["long_name"] = ("aspect", "slope")
    path = tmp_path / "scene" / "slope_aspect.tif"
    layers.rio.to_raster(path)
    by_name, by_dem = tmp_path / "named.tif", tmp_path / "dem.tif"
    assert _correct(scene, by_name, "--slope-aspect", path).exit_code == 0
    # The same surface from a DEM: a plane falling to the east by tan(20 deg).
    columns = np.ones((32, 1)) * np.arange(32)[None, :]
    dem_path = _dem(tmp_path, 100.0 - np.tan(np.radians(20.0)) * PIXEL * columns)
    assert _correct(scene, by_dem, "--dem", dem_path).exit_code == 0
    np.testing.assert_allclose(_read(by_name), _read(by_dem), rtol=1e-4, equal_nan=True)


def test_surface_facing_away_from_the_sun_is_flagged(scene, tmp_path):
    # 80 deg slopes facing away from the sun (saa 150 in the helpers' scene): sun behind the surface.
    slope_values, aspect_values = np.full((32, 32), 80.0), np.full((32, 32), 330.0)
    layers = georeference(xr.DataArray(np.stack([slope_values, aspect_values]).astype(np.float32),
                                       dims=("band", "y", "x")))
    path = tmp_path / "scene" / "steep.tif"
    layers.rio.to_raster(path)
    output, qa = tmp_path / "steep_out.tif", tmp_path / "steep_qa.tif"
    result = _correct(scene, output, "--slope-aspect", path, "--qa", qa)
    assert result.exit_code == 0, result.output
    assert np.all(_read(qa)[0] & QA.FACING_AWAY)
    assert np.isnan(_read(output)).all()


@pytest.mark.parametrize("extra, message", [
    (["--topographic", "scs"], "--topographic and --brdf-frame need --slope-aspect or --dem"),
    (["--dem", "DEM", "--slope-aspect", "DEM"], "give slope and aspect .* or a DEM, one of them"),
    (["--dem", "DEM", "--topographic", "c", "--brdf-frame", "surface"], "combine it with brdf_frame 'horizontal'"),
])
def test_bad_terrain_options_are_one_line_and_exit_2(scene, tmp_path, extra, message):
    dem = _dem(tmp_path, np.full((32, 32), 10.0))
    result = _correct(scene, tmp_path / "out.tif", *[str(dem) if a == "DEM" else a for a in extra])
    assert result.exit_code == 2
    assert len(result.stderr.strip().splitlines()) == 1
    assert re.search(message, result.stderr), result.stderr
    assert not (tmp_path / "out.tif").exists()


def test_uncertainty_output_is_the_propagated_sigma(scene, tmp_path):
    # Class 1 carries a fit: block (t0 and t1 uncertain, correlated); the others none (NaN).
    table = example_table()
    entry = table[1].model_dump(exclude_none=True)
    covariance = [[4e-6, -1e-6], [-1e-6, 1e-4]]
    entry["fit"] = {"source": "test", "parameters": ["t0", "t1"], "covariance": covariance, "n": 500,
                    "chi2_dof": 1.0, "r2": 0.9, "errors": {"t0": 2e-3, "t1": 1e-2}}
    table = table.with_class(entry)
    params = table.save(tmp_path / "scene" / "fitted.yaml")
    output, sigma_path = tmp_path / "out.tif", tmp_path / "sigma.tif"
    args = ["correct", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"], "--params",
            params, "-o", output, "--uncertainty", sigma_path, "--ref-sza", "35", "--no-progress"]
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    # The classes without errors are named: their pixels are NaN in the uncertainty output.
    bare = [entry.label for entry in table.classes if entry.id != 1 and entry.material is None]
    assert bare and all(label in result.stderr for label in bare) and "have no fit: block" in result.stderr

    data = scene["data"]
    expected = correction_uncertainty(
        data["reflectance"], data["classes"].rio.write_nodata(255), {a: data[a] for a in ("sza", "saa", "vza", "vaa")},
        ParameterTable.load(params), {"sza": 35.0},
    )
    sigma = _read(sigma_path)
    np.testing.assert_allclose(sigma, expected.values, rtol=2e-6, equal_nan=True)
    roof = data["classes"].values == 1
    assert np.isfinite(sigma[:, roof]).all() and (sigma[:, roof] > 0).all()
    assert np.isnan(sigma[:, ~roof]).all()
    with rasterio.open(sigma_path) as dataset, rasterio.open(output) as corrected:
        assert dataset.descriptions == corrected.descriptions
        assert dataset.transform == corrected.transform and dataset.crs == corrected.crs


def test_uncertainty_output_may_not_be_an_input(scene, tmp_path):
    result = _correct(scene, tmp_path / "out.tif", "--uncertainty", scene["image"])
    assert result.exit_code == 2
    assert "uncertainty output" in result.stderr and "image" in result.stderr
