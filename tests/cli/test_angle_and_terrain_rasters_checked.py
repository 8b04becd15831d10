"""Angle and terrain rasters are checked before they are used. Each refusal ends in exit code 2,
exactly one stderr line ``brdfcorr: error: ...`` naming the cause, no file in the output directory
and inputs unchanged:

1. an angle or slope/aspect raster cut short (GDAL opens it, a block read fails later: was a
   RasterioIOError, exit 1);
2. a DEM in a CRS whose unit is the US survey foot: its pixel size is converted to metres (slopes
   were 1.75 deg for 5.71);
3. slope/aspect layers in radians or outside any plausible range (was 100 % nodata, exit 0); plausible
   layers still correct.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import _forked
import numpy as np
import pytest
import rasterio
import rioxarray
import xarray as xr
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.correction.terrain import slope_aspect
from brdfcorr.testing import PIXEL, georeference, synthetic_scene

NY, NX = 32, 32  # the scene of the template fixture (tests/conftest.py)
#: Metres per US survey foot (EPSG:9003).
US_SURVEY_FOOT = 1200 / 3937


# ------------------------------------------------------------------------------------- helpers
# scene (a copy of the template), refused(scene, args, pattern, run=None) and correct_args(scene, ...):
# tests/conftest.py.
def _truncated(source: Path, target: Path) -> Path:
    """A copy of ``source`` cut to half its size: GDAL still opens it (the header and the tile index
    come first), and reading the tiles of its second half fails."""
    shutil.copy(source, target)
    os.truncate(target, target.stat().st_size // 2)
    return target


def _slope_aspect_raster(path: Path, slope, aspect, in_new_york: bool = False) -> Path:
    layers = np.stack([np.broadcast_to(np.asarray(v, float), (NY, NX)) for v in (slope, aspect)]).astype(np.float32)
    raster = georeference(xr.DataArray(layers, dims=("band", "y", "x")))
    raster = _new_york(raster) if in_new_york else raster
    raster.attrs["long_name"] = ("slope", "aspect")
    raster.rio.to_raster(path, tiled=True, blockxsize=16, blockysize=16, compress="deflate")
    return path


def _random_surface(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Slopes of 2-40 deg facing every way [deg]."""
    rng = np.random.default_rng(seed)
    return rng.uniform(2.0, 40.0, (NY, NX)), rng.uniform(0.0, 359.0, (NY, NX))


# --------------------------------------------------------------------------- files cut short
def _cli(args) -> tuple[int, str]:
    """The installed command in its own process: stderr is everything written to it, GDAL's own
    lines included."""
    finished = _forked.run(["brdfcorr", *args])
    return finished.returncode, finished.stderr


def test_truncated_angle_raster(scene, refused, correct_args):
    cut = _truncated(scene["angles"], scene["dir"] / "angles_cut.tif")
    line = refused(scene, correct_args(scene, angles=("--angles", cut)),
                   r"cannot read angle file \S*angles_cut\.tif: angles_cut\.tif, band \d+: ", run=_cli)
    assert "(a truncated or damaged file?)" in line


def test_truncated_single_angle_file(scene, refused, correct_args):
    with rasterio.open(scene["angles"]) as dataset:
        data, profile = dataset.read(), {**dataset.profile, "count": 1}
    files = {}
    for index, name in enumerate(("sza", "saa", "vza", "vaa")):
        files[name] = scene["dir"] / f"{name}.tif"
        with rasterio.open(files[name], "w", **profile) as target:
            target.write(data[index:index + 1])
    files["vza"] = _truncated(files["vza"], scene["dir"] / "vza_cut.tif")
    angles = tuple(item for name, path in files.items() for item in (f"--{name}", path))
    # Cut within its header (GDAL writes the georeference tags last): refused when opened, not taken
    # for a raster without a CRS; cut within its tiles: refused in the pass over the angles.
    line = refused(scene, correct_args(scene, angles=angles), r"cannot read (vza )?angle files? .*vza_cut\.tif: "
                   r".*vza_cut\.tif", run=_cli)
    assert "(a truncated or damaged file?)" in line


def test_truncated_slope_aspect_raster(scene, refused, correct_args):
    good = _slope_aspect_raster(scene["dir"] / "slope_aspect.tif", *_random_surface())
    cut = _truncated(good, scene["dir"] / "slope_aspect_cut.tif")
    refused(scene, correct_args(scene, "--slope-aspect", cut),
            r"cannot read slope/aspect file \S*slope_aspect_cut\.tif: slope_aspect_cut\.tif, band \d")


# -------------------------------------------------------------------- DEM units (US survey feet)
def _new_york(layer: xr.DataArray, crs: str = "EPSG:2263") -> xr.DataArray:
    """``layer`` on the helpers' grid moved into New York Long Island (x 1,000,000 ft, y 200,000 ft
    in EPSG:2263, whose scale is 1 there within 1e-5; at the helpers' UTM coordinates, 1600 km
    north of the zone, it is 1.033, which slope_aspect would divide out)."""
    moved = layer.assign_coords(x=layer["x"] + 500_000.0, y=layer["y"] - 5_200_000.0)
    return moved.rio.write_crs(crs).rio.write_transform(moved.rio.transform(recalc=True))


def _feet_scene() -> dict:
    """The helpers' scene on a grid of 10 US survey feet (EPSG:2263, New York Long Island)."""
    return {name: _new_york(layer) for name, layer in synthetic_scene(ny=NY, nx=NX).items()}


def test_dem_in_us_survey_feet_gives_slopes_in_metres(tmp_path, write_example_scene):
    # Elevations in metres rising 0.1 m per metre northwards (rows go south): 5.71 deg facing south,
    # where the pixel size in feet read as metres gave 1.75 deg.
    paths = write_example_scene(tmp_path / "scene", _feet_scene())
    rows = np.arange(NY)[:, None] * np.ones((1, NX))
    heights = 100.0 - 0.1 * PIXEL * US_SURVEY_FOOT * rows
    dem = _new_york(georeference(xr.DataArray(heights[None].astype(np.float64), dims=("band", "y", "x"))))
    dem.rio.to_raster(tmp_path / "scene" / "dem.tif")

    surface = slope_aspect(rioxarray.open_rasterio(tmp_path / "scene" / "dem.tif")[0])
    expected = np.degrees(np.arctan(0.1))
    np.testing.assert_allclose(surface.slope.values, expected, atol=1e-6)
    np.testing.assert_allclose(surface.aspect.values, 180.0, atol=1e-6)

    # The command corrects as with a slope/aspect raster of the true surface.
    layers = _slope_aspect_raster(tmp_path / "scene" / "true_surface.tif", expected, 180.0, in_new_york=True)
    outputs = {}
    for option, path in (("--dem", tmp_path / "scene" / "dem.tif"), ("--slope-aspect", layers)):
        outputs[option] = tmp_path / f"out{option}.tif"
        args = ["correct", paths["image"], "--angles", paths["angles"], "--classes", paths["classes"], "--params",
                paths["params"], "-o", outputs[option], "--no-progress", option, path]
        result = CliRunner().invoke(main, [str(a) for a in args])
        assert result.exit_code == 0, result.output
    with rasterio.open(outputs["--dem"]) as by_dem, rasterio.open(outputs["--slope-aspect"]) as by_layers:
        np.testing.assert_allclose(by_dem.read(), by_layers.read(), rtol=1e-5, equal_nan=True)


def test_dem_heights_in_the_vertical_unit_of_a_compound_crs(tmp_path):
    # A US LiDAR DEM: x, y and heights in US survey feet (EPSG:2263 + NAVD88 height in ftUS,
    # EPSG:6360). A plane rising tan(10 deg) per unit northwards is 10 deg whatever the unit, where
    # heights in feet read as metres gave 30 deg.
    rows = np.arange(NY)[:, None] * np.ones((1, NX))
    heights = 100.0 - np.tan(np.radians(10.0)) * PIXEL * rows  # feet, rows 10 ft apart going south
    dem = _new_york(georeference(xr.DataArray(heights[None], dims=("band", "y", "x"))), crs="EPSG:2263+6360")
    dem.rio.to_raster(tmp_path / "dem.tif")
    surface = slope_aspect(rioxarray.open_rasterio(tmp_path / "dem.tif")[0])
    np.testing.assert_allclose(surface.slope.values, 10.0, atol=1e-6)
    np.testing.assert_allclose(surface.aspect.values, 180.0, atol=1e-6)


def test_dem_pixel_size_in_metres_is_unchanged():
    dem = georeference(xr.DataArray(np.arange(NY)[:, None] * np.ones((NY, NX)), dims=("y", "x")))
    slope = slope_aspect(dem).slope.values
    np.testing.assert_allclose(slope, np.degrees(np.arctan(1.0 / PIXEL)), atol=1e-9)


# --------------------------------------------------------------------- slope/aspect plausibility
@pytest.mark.parametrize("case, transform, pattern", [
    ("radians", lambda s, a: (np.radians(s), np.radians(a)),
     r"slope/aspect file \S*radians\.tif: slope and aspect look like radians \(slope 0\.0\d+\.\.0\.6\d+, "
     r"aspect [\d.]+\.\.6\.\d+\); brdfcorr needs degrees"),
    ("slope_outside", lambda s, a: (s + 100.0, a),
     r"slope/aspect file \S*slope_outside\.tif: no slope value in \[0, 90\] deg \(found slope 1\d\d\.\d+\.\.1\d\d\.\d+, "),
    ("slope_negative", lambda s, a: (-s, a), r"no slope value in \[0, 90\] deg \(found slope -"),
    ("aspect_scaled", lambda s, a: (s, a * 100.0 + 400.0), r"no aspect value in \[-360, 360\] deg"),
])
def test_implausible_slope_aspect_raster(scene, case, transform, pattern, refused, correct_args):
    path = _slope_aspect_raster(scene["dir"] / f"{case}.tif", *transform(*_random_surface()))
    line = refused(scene, correct_args(scene, "--slope-aspect", path), pattern)
    if "no " in pattern:
        assert "every pixel would be nodata" in line.lower()


def _obs_file(scene, slope, aspect) -> Path:
    """An ENVI obs_ort file on the image grid with the bands Slope and Aspect of AVIRIS-NG."""
    with rasterio.open(scene["image"]) as dataset:
        profile = {key: dataset.profile[key] for key in ("width", "height", "crs", "transform")}
    path = scene["dir"] / "ang_obs_ort"
    with rasterio.open(path, "w", driver="ENVI", count=2, dtype="float32", **profile) as target:
        target.write(np.stack([slope, aspect]).astype(np.float32))
        target.descriptions = ("Slope (local surface slope as derived from DEM in degrees)",
                               "Aspect (local surface aspect 0 to 360 degrees clockwise from N)")
    return path


def test_obs_file_slope_aspect_in_radians(scene, refused, correct_args):
    slope, aspect = _random_surface()
    path = _obs_file(scene, np.radians(slope), np.radians(aspect))
    refused(scene, correct_args(scene, "--slope-aspect", path),
            r"obs file \S*ang_obs_ort: slope and aspect look like radians")


def test_obs_file_slope_outside_its_domain(scene, refused, correct_args):
    slope, aspect = _random_surface()
    path = _obs_file(scene, 100.0 * slope, aspect)
    refused(scene, correct_args(scene, "--slope-aspect", path), r"obs file \S*ang_obs_ort: no slope value in \[0, 90\]")


@pytest.mark.parametrize("slope, aspect", [
    (0.0, 0.0),  # flat: small numbers, but no aspects spread like radians
    (1.2, 200.0),  # gentle slopes facing one way
    (None, None),  # a real spread of slopes and aspects in degrees
])
def test_plausible_slope_aspect_rasters_still_correct(scene, slope, aspect, correct_args):
    values = _random_surface() if slope is None else (np.full((NY, NX), slope), np.full((NY, NX), aspect))
    path = _slope_aspect_raster(scene["dir"] / "surface.tif", *values)
    result = CliRunner().invoke(main, [str(a) for a in correct_args(scene, "--slope-aspect", path)])
    assert result.exit_code == 0, result.output
    assert scene["output"].is_file()


def test_a_dem_on_another_grid_or_without_a_crs_is_named_with_a_fix_the_command_line_has(scene, tmp_path, refused,
                                                                                           correct_args):
    # The DEM's own file is named (it was "slope is not on the grid of image"), and a DEM without a
    # CRS is told what to write, not a Python keyword the command line does not have.
    with rasterio.open(scene["image"]) as image:
        profile = {**image.profile, "count": 1, "dtype": "float32", "nodata": None}
        shifted = {**profile, "transform": image.transform * rasterio.Affine.translation(3, 0)}
        no_crs = {key: value for key, value in profile.items() if key != "crs"}
        heights = np.zeros((1, image.height, image.width), dtype=np.float32)
    for name, options in (("shifted.tif", shifted), ("no_crs.tif", no_crs)):
        with rasterio.open(tmp_path / name, "w", **options) as dem:
            dem.write(heights)
    refused(scene, correct_args(scene, "--dem", tmp_path / "shifted.tif"),
            r"DEM \S*shifted\.tif is not on the grid of image")
    result = refused(scene, correct_args(scene, "--dem", tmp_path / "no_crs.tif"), r"DEM file \S*no_crs\.tif: no CRS")
    assert "pixel_size=" not in result.split("write its projected CRS")[0]
