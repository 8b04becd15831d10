"""The command line's input checks of issue 38: angle bands in another order (recognised from
their values where no band descriptions say which is which), an ENVI obs file read as a GeoTIFF,
a land-cover map on another grid, a reference sun zenith in radians. Each is one line, exit 2,
naming the fix."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main

#: The documented order and the one of the issue (view angles first), as band indices of angles.tif.
DOCUMENTED = ("sza", "saa", "vza", "vaa")


def _angles(scene: dict, order: tuple[str, ...], descriptions: bool, count: int | None = None) -> Path:
    """The scene's angles rewritten with their bands in ``order`` (with or without descriptions),
    padded with copies of the last band to ``count`` bands."""
    with rasterio.open(scene["angles"]) as source:
        layers = dict(zip(DOCUMENTED, source.read()))
        profile = source.profile
    data = np.stack([layers[name] for name in order])
    if count is not None:
        data = np.concatenate([data, np.repeat(data[-1:], count - len(order), axis=0)])
    target = scene["dir"] / "reordered.tif"
    with rasterio.open(target, "w", **{**profile, "count": data.shape[0]}) as dataset:
        dataset.write(data)
        dataset.descriptions = tuple(order) if descriptions else (None,) * data.shape[0]
    return target


def _correct(scene: dict, angles: Path, *extra: str):
    return CliRunner().invoke(main, ["correct", str(scene["image"]), "--angles", str(angles), "--classes",
                                     str(scene["classes"]), "--params", str(scene["params"]), "-o",
                                     str(scene["output"]), "--no-progress", "--ref-sza", "mean", *extra])


def _one_line(result, pattern: str) -> str:
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("brdfcorr: error: "), result.stderr
    assert re.search(pattern, lines[0]), lines[0]
    return lines[0]


def test_view_angles_first_without_descriptions_are_refused_naming_the_order(scene):
    result = _correct(scene, _angles(scene, ("vza", "vaa", "sza", "saa"), descriptions=False))
    _one_line(result, r"taken as sza, saa, vza, vaa, but bands 1-2 vary far more than bands 3-4.*"
                      r"is the order vza, vaa, sza, saa\? Describe the bands")
    assert not scene["output"].exists()


def test_view_angles_first_with_descriptions_are_read_by_them(scene):
    reordered = _correct(scene, _angles(scene, ("vza", "vaa", "sza", "saa"), descriptions=True))
    assert reordered.exit_code == 0, reordered.output
    with rasterio.open(scene["output"]) as dataset:
        by_descriptions = dataset.read()
    scene["output"].unlink()
    documented = _correct(scene, scene["angles"])
    assert documented.exit_code == 0, documented.output
    with rasterio.open(scene["output"]) as dataset:
        np.testing.assert_array_equal(dataset.read(), by_descriptions)


def test_azimuths_and_zeniths_interleaved_get_a_word_about_the_band_order(scene):
    result = _correct(scene, _angles(scene, ("sza", "vza", "saa", "vaa"), descriptions=False))
    _one_line(result, r"no vza value in \[0, 90\).*the bands have no descriptions, so they were taken as "
                      r"sza, saa, vza, vaa: if they are in another order, describe them")


def test_an_obs_file_read_as_a_geotiff_names_envi_obs(scene):
    result = _correct(scene, _angles(scene, DOCUMENTED, descriptions=False, count=11))
    _one_line(result, r"has 11 bands; it needs 4 .*an ENVI obs/obs_ort file\? Read it with --angles-kind envi_obs$")


def test_a_class_map_on_another_grid_names_align_classes(scene):
    with rasterio.open(scene["classes"]) as source:
        data, profile = source.read(), source.profile
    coarse = scene["dir"] / "coarse_classes.tif"
    with rasterio.open(coarse, "w", **{**profile, "width": profile["width"] // 2, "height": profile["height"] // 2,
                                       "transform": profile["transform"] * rasterio.Affine.scale(2)}) as dataset:
        dataset.write(data[:, ::2, ::2])
    result = CliRunner().invoke(main, ["correct", str(scene["image"]), "--angles", str(scene["angles"]),
                                       "--classes", str(coarse), "--params", str(scene["params"]), "-o",
                                       str(scene["output"]), "--no-progress"])
    _one_line(result, r"classes \(.*coarse_classes.tif\) is not on the grid of image .*brought onto the image's "
                      r"with --align-classes$")


def test_a_reference_sun_zenith_in_radians_is_refused(scene):
    result = _correct(scene, scene["angles"], "--ref-sza", "0.78")
    _one_line(result, r"reference sza = 0.78 looks like radians \(44.69 deg\); the reference angles are degrees")
    assert not scene["output"].exists()
