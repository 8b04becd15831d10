"""Angles as MODIS and VIIRS products give them (issue 24): solar zenith, view zenith and the
relative azimuth raa = vaa - saa only. The correction of a flat surface depends on the azimuths only
through |saa - vaa|, so such a source corrects exactly as the four angles do; what needs the
absolute azimuths (a tilted surface, signing by the flight track) is refused in one line."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.testing import synthetic_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory, write_example_scene):
    directory = tmp_path_factory.mktemp("relative_azimuth")
    files = write_example_scene(directory, synthetic_scene(ny=24, nx=32))
    with rasterio.open(files["angles"]) as angles:
        profile = {**angles.profile, "count": 1}
        sza, saa, vza, vaa = angles.read()
    raa = vaa - saa  # MODIS/VIIRS: SensorAzimuth - SolarAzimuth, both from the pixel
    for name, layers, descriptions in (("relative", (vza, raa, sza), ("view zenith", "relative azimuth", "sza")),
                                       ("sza_only", (sza,), None), ("vza_only", (vza,), None),
                                       ("raa_only", (raa,), None)):
        path = directory / f"{name}.tif"
        with rasterio.open(path, "w", **{**profile, "count": len(layers)}) as target:
            target.write(np.stack(layers))
            if descriptions:
                target.descriptions = descriptions
        files[name] = path
    return files


def _correct(scene, output, *angles):
    return CliRunner().invoke(main, [str(a) for a in (
        "correct", scene["image"], *angles, "--classes", scene["classes"], "--params", scene["params"],
        "-o", output, "--ref-sza", 35, "--no-progress")])


def _read(path):
    with rasterio.open(path) as dataset:
        return dataset.read()


def test_sza_vza_raa_correct_as_the_four_angles(scene, tmp_path):
    four = _correct(scene, tmp_path / "four.tif", "--angles", scene["angles"])
    stacked = _correct(scene, tmp_path / "stacked.tif", "--angles", scene["relative"])  # bands named, any order
    separate = _correct(scene, tmp_path / "separate.tif", "--sza", scene["sza_only"], "--vza", scene["vza_only"],
                        "--raa", scene["raa_only"])
    for result in (four, stacked, separate):
        assert result.exit_code == 0, result.output
    reference = _read(tmp_path / "four.tif")
    assert np.isfinite(reference).all()
    for name in ("stacked", "separate"):  # float32 angles: |saa - vaa| rounds alike to 1e-6
        np.testing.assert_allclose(_read(tmp_path / f"{name}.tif"), reference, rtol=1e-5)


def test_what_needs_absolute_azimuths_is_refused(scene, tmp_path):
    slope_aspect = tmp_path / "slope_aspect.tif"
    with rasterio.open(scene["angles"]) as angles:
        with rasterio.open(slope_aspect, "w", **{**angles.profile, "count": 2}) as target:
            target.write(np.stack([np.full(angles.shape, 10.0, "float32"), np.full(angles.shape, 90.0, "float32")]))
    output = tmp_path / "out.tif"
    result = _correct(scene, output, "--angles", scene["relative"], "--slope-aspect", slope_aspect)
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "only their relative azimuth (raa)" in lines[0] and not output.exists()
    result = CliRunner().invoke(main, [str(a) for a in (
        "assess", scene["image"], scene["image"], "--classes", scene["classes"], "--angles", scene["relative"],
        "--sign-by", "track", "--heading", 0, "-o", tmp_path / "assess.json")])
    assert result.exit_code == 2, result.output
    assert "gives only the relative azimuth (raa): sign by the sun" in result.stderr.splitlines()[-1]
    # assess-lines as well (it signed by sin(heading - raa) and reported the slopes), before any fit.
    output, second = tmp_path / "lines.json", shutil.copy(scene["image"], tmp_path / "line2.tif")
    result = CliRunner().invoke(main, [str(a) for a in (
        "assess-lines", scene["image"], second, "--classes", scene["classes"], "--classes", scene["classes"],
        "--angles", scene["relative"], "--angles", scene["relative"], "--model", "ross_thick_li_sparse",
        "--sign-by", "track", "--heading", 0, "-o", output)])
    assert result.exit_code == 2, result.output
    assert "gives only the relative azimuth (raa): sign by the sun" in result.stderr.splitlines()[-1]
    assert not output.exists()


def test_an_incomplete_set_of_files_is_one_error(scene, tmp_path):
    result = _correct(scene, tmp_path / "out.tif", "--sza", scene["sza_only"], "--raa", scene["raa_only"])
    assert result.exit_code == 2
    assert "missing angle file(s): vza" in result.stderr.splitlines()[-1]


@pytest.mark.parametrize("stacked", [False, True])
def test_relative_azimuth_in_radians_is_refused(scene, tmp_path, stacked):
    """A --raa file or the 3-band raster's raa in radians was taken as degrees near the hotspot
    (up to 119 % off, exit 0) while the zeniths were degrees: issue 39."""
    with rasterio.open(scene["relative"]) as relative:
        profile, layers, descriptions = relative.profile, relative.read(), relative.descriptions
    layers[1] = np.radians(layers[1])
    path = tmp_path / ("relative_radians.tif" if stacked else "raa_radians.tif")
    with rasterio.open(path, "w", **{**profile, "count": 3 if stacked else 1}) as target:
        target.write(layers if stacked else layers[1:2])
        if stacked:
            target.descriptions = descriptions
    angles = ("--angles", path) if stacked else ("--sza", scene["sza_only"], "--vza", scene["vza_only"], "--raa", path)
    output = tmp_path / "out.tif"
    result = _correct(scene, output, *angles)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and not output.exists(), result.stderr
    assert re.search(rf"{path.name}\)?: the relative azimuth \(raa\) \S+ looks like radians; brdfcorr needs degrees",
                     lines[0]), lines[0]
