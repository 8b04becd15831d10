"""A scene whose correction touched under ``steps.correct.min_corrected_share`` of its valid pixels
is a failed scene (issue 38): a land-cover map aligned onto the image without a lookup holds
WorldCover codes (10, 30, 50, 60), none of them a class of the table, so nothing is corrected."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from click.testing import CliRunner

from brdfcorr.chain.demo import default_config
from brdfcorr.cli import main


def _chain(root: Path, name: str, correct: dict, **inputs) -> Path:
    demo = yaml.safe_load(default_config().read_text())  # the demo's parameter table (ids 1-5)
    document = {
        "inputs": {"images": ["scenes/*_image.tif"], "scene_regex": "(?P<scene>.+)_image",
                   "angles": {"kind": "geotiff", "path": "{dir}/{scene}_angles.tif"},
                   "classes": "landcover.tif", "align_classes": True, **inputs},
        "parameters": demo["parameters"],
        "steps": {"correct": correct},
        "outputs": {"directory": f"out_{name}"},
        "engine": {"scheduler": "synchronous", "chunk": 64},
    }
    path = root / f"{name}.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


def _valid_pixels(path: Path) -> int:
    """The pixels of the corrected image with data in every band (the QA count's 'valid')."""
    with rasterio.open(path) as dataset:
        return int(np.isfinite(dataset.read()).all(axis=0).sum())


def test_an_aligned_map_without_a_lookup_fails_the_scene_naming_share_and_key(landcover):
    result = CliRunner().invoke(main, ["run", str(_chain(landcover, "nolookup", {})), "--no-progress"])
    assert result.exit_code == 3, result.output
    assert "0 ok, 0 skipped, 1 failed" in result.stdout
    row = next(line for line in result.stdout.splitlines() if line.startswith("line01"))
    assert "failed" in row and "only 0.0 % of the" in row and "steps.correct.min_corrected_share 0.5" in row
    report = json.loads((landcover / "out_nolookup" / "run_report.json").read_text())
    scene = report["scenes"][0]
    assert scene["status"] == "failed" and scene["error_type"] == "TooFewCorrected"
    # The counts in the message are the scene's: no pixel corrected, every valid pixel of a code
    # outside the table or of no class (the map's nodata 0 and the area outside it).
    valid = _valid_pixels(landcover / "out_nolookup" / "line01_brdf.tif")
    assert scene["qa"]["corrected"] == 0
    assert scene["qa"]["unknown_class"] + scene["qa"]["no_class"] == valid
    assert f"of the {valid} valid pixels" in scene["error"]


def test_the_key_says_a_small_share_is_expected(landcover):
    chain = _chain(landcover, "expected", {"min_corrected_share": 0})
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "1 ok, 0 skipped, 0 failed" in result.stdout


def test_with_the_lookup_the_scene_is_corrected_and_ok(landcover):
    chain = _chain(landcover, "withlookup", {}, class_lookup=yaml.safe_load((landcover / "lookup.yaml").read_text()))
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 0, result.output
    report = json.loads((landcover / "out_withlookup" / "run_report.json").read_text())
    qa = report["scenes"][0]["qa"]
    assert qa["corrected"] >= 0.5 * (qa["corrected"] + qa["no_class"] + qa["unknown_class"])


@pytest.mark.parametrize("value", [-0.1, 1.5, "half"])
def test_a_bad_share_is_refused_in_one_line(landcover, value):
    chain = _chain(landcover, "bad", {"min_corrected_share": value})
    result = CliRunner().invoke(main, ["validate", str(chain)])
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "steps.correct.min_corrected_share" in lines[0], result.stderr


def test_a_resumed_run_judges_a_skipped_scene_by_its_earlier_counts(landcover):
    # The share is no part of the fingerprint (outputs stay current), so a rerun with a stricter
    # share skipped the scene and exited 0 where a fresh run fails it (exit 3).
    chain = _chain(landcover, "resumed", {"min_corrected_share": 0})
    assert CliRunner().invoke(main, ["run", str(chain), "--no-progress"]).exit_code == 0
    chain = _chain(landcover, "resumed", {})  # the default share, 0.5
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 3, result.output
    report = json.loads((landcover / "out_resumed" / "run_report.json").read_text())
    scene = report["scenes"][0]
    assert scene["status"] == "failed" and scene["error_type"] == "TooFewCorrected"
    assert scene["reason"] == "complete outputs exist"  # its outputs were kept, not written again


def test_an_image_of_nodata_only_fails_the_scene(tmp_path, make_scenes, write_chain):
    """No valid pixel: the share of corrected pixels is 0 of 0, and the scene was reported ok
    (exit 0, no warning) with an output of nodata only."""
    scenes = make_scenes(tmp_path, count=2)
    image = scenes["line1"][1]["image"]
    with rasterio.open(image, "r+") as dataset:
        dataset.write(np.full((dataset.count, dataset.height, dataset.width), np.nan, dataset.dtypes[0]))
    result = CliRunner().invoke(main, ["run", str(write_chain(tmp_path)), "--no-progress"])
    assert result.exit_code == 3, result.output
    assert "1 ok, 0 skipped, 1 failed" in result.stdout
    report = json.loads((tmp_path / "out" / "run_report.json").read_text())
    failed = next(scene for scene in report["scenes"] if scene["status"] == "failed")
    assert failed["error"].startswith(f"no pixel was corrected: all {32 * 48} pixels are nodata")
