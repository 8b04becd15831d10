"""``brdfcorr assess --clusters``: the slopes' 1-sigma over a cluster layer's ids (issue 40)."""

from __future__ import annotations

import json

import numpy as np
import rioxarray
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.io.scene import SceneSources
from brdfcorr.tasks.assess import assess_files
from brdfcorr.tasks.correct import correct_files
from brdfcorr.tasks.request import CorrectionRequest, OutputFiles
from brdfcorr.testing import example_table, synthetic_scene, write_scene


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def _layer(paths, directory, values, name):
    """A raster of ``values`` (y, x) on the scene image's grid."""
    like = rioxarray.open_rasterio(paths["image"]).isel(band=0, drop=True)
    layer = like.copy(data=values)
    layer.attrs = {}
    layer = layer.rio.write_nodata(-1)
    path = directory / name
    layer.rio.to_raster(path)
    return path


def test_assess_takes_a_cluster_layer_and_reports_what_its_errors_are_over(tmp_path):
    paths = write_scene(tmp_path, synthetic_scene(ny=32, nx=40))
    after = tmp_path / "corrected.tif"
    correct_files(CorrectionRequest(SceneSources(paths["image"], paths["classes"], paths["angles"]), example_table(),
                                    OutputFiles(after), reference={"sza": "observed", "vza": 0.0}))
    days = np.where(np.arange(40)[None, :] % 3 == 0, 153, 160) * np.ones((32, 1), np.int16)
    days[0, :] = -1  # nodata: a row left out
    layer = _layer(paths, tmp_path, days.astype(np.int16), "days.tif")
    report_path = tmp_path / "report.json"
    result = _invoke("assess", paths["image"], after, "--classes", paths["classes"], "--angles", paths["angles"],
                     "--clusters", layer, "-o", report_path)
    assert result.exit_code == 0, result.output
    report = json.loads(report_path.read_text())
    assert "cluster layer" in report["view_angles"]["errors"]["clusters"]
    assert all(entry["blocks"] <= 2 for entry in report["view_angles"]["classes"])  # two days
    expected = assess_files(SceneSources(paths["image"], paths["classes"], paths["angles"]), after,
                            clusters=(layer, 1)).report()
    assert report["view_angles"] == json.loads(json.dumps(expected["view_angles"]))
    pixels = sum(entry["pixels"] for entry in report["view_angles"]["classes"])
    assert pixels == 31 * 40  # the nodata row is left out


def test_a_float_cluster_layer_is_refused_in_one_line(tmp_path):
    paths = write_scene(tmp_path, synthetic_scene(ny=16, nx=16))
    layer = _layer(paths, tmp_path, np.ones((16, 16), np.float32), "float.tif")
    result = CliRunner().invoke(main, [str(a) for a in ("assess", paths["image"], paths["image"], "--classes",
                                                         paths["classes"], "--angles", paths["angles"], "--clusters",
                                                         layer, "-o", tmp_path / "r.json")])
    assert result.exit_code == 2
    assert "needs integer ids" in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "r.json").exists()


def test_a_cluster_layer_of_one_id_gives_no_sigma_and_says_so(tmp_path):
    """Every pixel in one cluster: the slopes' 1-sigma is NaN (one cluster estimates no spread),
    and the console said nothing: "0 of 0 bands within 2 sigma" read as a result."""
    import pytest

    from brdfcorr.errors import BrdfcorrWarning

    paths = write_scene(tmp_path, synthetic_scene(ny=32, nx=40))
    after = tmp_path / "corrected.tif"
    correct_files(CorrectionRequest(SceneSources(paths["image"], paths["classes"], paths["angles"]), example_table(),
                                    OutputFiles(after), reference={"sza": "observed", "vza": 0.0}))
    layer = _layer(paths, tmp_path, np.full((32, 40), 153, np.int16), "one_day.tif")
    with pytest.warns(BrdfcorrWarning, match=r"^no 1-sigma for the slopes of class 1, class 2, class 3, class 4: the "
                                             r"pixels of each lie in a single one of the cluster layer.s ids"):
        assessment = assess_files(SceneSources(paths["image"], paths["classes"], paths["angles"]), after,
                                  clusters=(layer, 1))
    classes = assessment.report()["view_angles"]["classes"]
    assert all(entry["blocks"] == 1 for entry in classes)
