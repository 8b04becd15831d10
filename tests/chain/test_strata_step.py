"""NDVI strata as a chain step (issue 38): ``steps.strata`` derives each scene's class map and
``steps.strata.ndvi_interpolation`` gives the run's table the strata's ``ndvi_interpolation:``
block. The chain's class map, fitted table and corrected image are those of the commands run by
hand (``classes ndvi``, ``fit-classes``, the block added in Python, ``correct``); a resumed run
skips the scene until a strata setting changes; bad keys are refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from click.testing import CliRunner

from brdfcorr.chain.demo import demo_scene, write_demo_scene
from brdfcorr.cli import main
from brdfcorr.params import ParameterTable

#: Edges that split the demo line's NDVI (concrete 0.02, roof tiles 0.1, bare soil 0.15,
#: vegetation 0.8) into three strata; stratum 1 (concrete and part of the roofs) is no kernel-model
#: surface: the fit leaves it uncorrected (its R^2 ~ 0), so the interpolation is over strata 2 and 3.
EDGES = [0.1, 0.5]


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> tuple[Path, dict[str, Path]]:
    root = tmp_path_factory.mktemp("strata_step")
    return root, write_demo_scene(root / "scenes", demo_scene(rows=60, pixel=12.0))


def _chain(root: Path, name: str, strata: dict | None = None, **changes) -> Path:
    document = {
        "inputs": {"images": ["scenes/*_image.tif"], "scene_regex": "(?P<scene>.+)_image",
                   "angles": {"kind": "geotiff", "path": "{dir}/{scene}_angles.tif"}},
        "steps": {"strata": {"edges": EDGES, "ndvi_interpolation": True} if strata is None else strata,
                  "fit": {"source": "imagery", "allow_uncorrected": True}, "correct": {}},
        "outputs": {"directory": f"out_{name}"},
        "engine": {"scheduler": "synchronous", "chunk": 64},
    }
    for key, value in changes.items():  # dotted keys, as --set
        section, _, leaf = key.rpartition(".")
        node = document
        for part in section.split("."):
            node = node.setdefault(part, {})
        node[leaf] = value
    path = root / f"{name}.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


def _run(*args):
    return CliRunner().invoke(main, [str(arg) for arg in args])


def _read(path: Path) -> np.ndarray:
    with rasterio.open(path) as dataset:
        return dataset.read()


@pytest.fixture(scope="module")
def by_hand(demo) -> dict[str, Path]:
    """The commands a user runs without the step: the strata map, the fit on it, the table with
    the interpolation block (written in Python), the correction."""
    root, scene = demo
    hand = root / "hand"
    hand.mkdir()
    # The chain's file name: the tables' fit sources name the class map.
    files = {"strata": hand / "line01_strata.tif", "fitted": hand / "fitted.yaml", "table": hand / "table.yaml",
             "corrected": hand / "corrected.tif"}
    assert _run("classes", "ndvi", scene["image"], "-o", files["strata"], "--edges", ",".join(map(str, EDGES)),
                "--no-progress").exit_code == 0
    result = _run("fit-classes", scene["image"], "--angles", scene["angles"], "--classes", files["strata"],
                  "-o", files["fitted"])
    assert result.exit_code == 0, result.output
    fitted = ParameterTable.load(files["fitted"])
    assert fitted.class_ids == (2, 3)  # stratum 1 failed the guard rails
    fitted.with_ndvi_interpolation({"classes": [2, 3]}).save(files["table"])
    result = _run("correct", scene["image"], "--angles", scene["angles"], "--classes", files["strata"],
                  "--params", files["table"], "-o", files["corrected"], "--chunk", 64, "--no-progress")
    assert result.exit_code == 0, result.output
    return files


@pytest.fixture(scope="module")
def console(demo) -> str:
    """The console of the chain's run."""
    root, _ = demo
    result = _run("run", _chain(root, "strata", **{"steps.assess": {}}), "--no-progress")
    assert result.exit_code == 0, result.output
    assert "1 ok, 0 skipped, 0 failed" in result.stdout
    return result.stdout


@pytest.fixture(scope="module")
def chained(demo, console) -> Path:
    return demo[0] / "out_strata"


def test_the_console_has_a_fit_line_and_an_assessment_line_per_class(chained, console):
    report = json.loads((chained / "run_report.json").read_text())
    lines = console.splitlines()
    fit = lines[lines.index("fit:") + 3:]
    for entry in report["fit"]["classes"]:  # 1 uncorrected (its reason), 2 and 3 fitted
        row = fit[entry["class_id"] - 1].split()
        assert row[:5] == [str(entry["class_id"]), entry["name"], entry["model"], entry["status"],
                           str(entry["n_samples"])], row
    heading = "assessment (median |relative slope| over bands, %/10 deg):"
    assessed = lines[lines.index(heading) + 3:]
    for number, entry in enumerate(report["scenes"][0]["assess"]):
        slopes = entry["median_abs_relative_slope_percent_per_10deg"]
        assert assessed[number].split() == ["line01", str(entry["id"]), f"({entry['name']})", str(entry["pixels"]),
                                            f"{slopes['before']:.3g}", f"{slopes['after']:.3g}"]


def test_the_chain_derives_the_class_map_of_classes_ndvi(chained, by_hand):
    np.testing.assert_array_equal(_read(chained / "line01_strata.tif"), _read(by_hand["strata"]))
    with rasterio.open(chained / "line01_strata.tif") as dataset:
        assert dataset.tags()["class_names"] == "1:ndvi_-inf_0.10,2:ndvi_0.10_0.50,3:ndvi_0.50_inf"


def test_the_chain_fits_and_corrects_as_the_commands_by_hand(chained, by_hand):
    fitted = ParameterTable.load(chained / "fitted_params.yaml")
    assert fitted.to_dict()["classes"] == ParameterTable.load(by_hand["fitted"]).to_dict()["classes"]
    report = json.loads((chained / "run_report.json").read_text())
    table = report["parameters"]["table"]
    assert table["ndvi_interpolation"]["classes"] == [2, 3]
    assert table == json.loads(json.dumps(ParameterTable.load(by_hand["table"]).to_dict()))
    corrected, expected = _read(chained / "line01_brdf.tif"), _read(by_hand["corrected"])
    np.testing.assert_array_equal(corrected, expected)


def test_without_interpolation_the_strata_keep_their_own_coefficients(demo, chained):
    root, _ = demo
    result = _run("run", _chain(root, "steps", {"edges": EDGES}), "--no-progress")
    assert result.exit_code == 0, result.output
    table = json.loads((root / "out_steps" / "run_report.json").read_text())["parameters"]["table"]
    assert table.get("ndvi_interpolation") is None
    stepwise, continuous = _read(root / "out_steps" / "line01_brdf.tif"), _read(chained / "line01_brdf.tif")
    strata = _read(chained / "line01_strata.tif")[0]
    # Same fit (same strata, same samples): the strata in the block are corrected otherwise, the
    # others (stratum 1, left uncorrected; no class) alike.
    assert not np.allclose(stepwise[:, strata == 3], continuous[:, strata == 3])
    outside = ~np.isin(strata, (2, 3))
    np.testing.assert_array_equal(stepwise[:, outside], continuous[:, outside])


def test_a_resumed_run_skips_the_scene_until_a_strata_setting_changes(demo, chained):
    root, _ = demo
    chain = _chain(root, "strata", **{"steps.assess": {}})  # the chain the console fixture ran
    result = _run("run", chain, "--resume", "--no-progress")
    assert result.exit_code == 0 and "0 ok, 1 skipped, 0 failed" in result.stdout, result.output
    result = _run("run", chain, "--dry-run", "--set", "steps.strata.edges=[0.1, 0.6]")
    assert result.exit_code == 0, result.output
    # The class maps change, so does the fit on them: fitted again, and the scene redone with it.
    assert "the fit step makes a new parameter table" in result.stdout and "reused" not in result.stdout


@pytest.mark.parametrize(("changes", "strata", "expected"), [
    ({}, {"edge": [0.3]}, "steps.strata.edge: unknown key; allowed keys: edges, ndvi_interpolation, percentiles, shadow_id, "
                                 "water_id"),
    ({}, {"edges": [0.5, 0.3]}, "steps.strata.edges: [0.5, 0.3] must be finite and strictly increasing"),
    ({}, {"edges": [0.3], "percentiles": [50]}, "give edges or percentiles, not both"),
    ({}, {"edges": [0.3], "water_id": 2}, "water_id 2 is the id of a stratum (1 to 2): give 0 or an id above"),
    ({}, {"percentiles": [0, 50]}, "steps.strata.percentiles[0]: Input should be greater than 0 (got 0)"),
    ({}, {"ndvi_interpolation": "yes please"}, "steps.strata.ndvi_interpolation: Input should be a valid boolean"),
    ({"inputs.classes": "{dir}/{scene}_classes.tif"}, None,
     "steps.strata derives each scene's class map: leave out inputs.classes"),
    ({"steps.strata": None}, None, "inputs.classes is missing: give the class maps' name pattern, set steps.strata"),
])
def test_bad_strata_keys_are_refused_in_one_line(demo, changes, strata, expected):
    root, _ = demo
    result = _run("validate", _chain(root, "bad", strata, **changes))
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and expected in lines[0], result.stderr


def test_a_scene_whose_strata_cannot_be_made_fails_alone(demo, tmp_path):
    # line02: the demo line's blue-green bands only (no red, no NIR): no NDVI, no strata.
    root, scene = demo
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    for role in ("image", "angles"):
        (scenes / f"line01_{role}.tif").symlink_to(scene[role])
    (scenes / "line02_angles.tif").symlink_to(scene["angles"])
    with rasterio.open(scene["image"]) as source:
        profile = {**source.profile, "count": 3}
        with rasterio.open(scenes / "line02_image.tif", "w", **profile) as target:
            target.write(source.read([1, 2, 3]))
            for band in (1, 2, 3):
                target.set_band_description(band, source.descriptions[band - 1])
    result = _run("run", _chain(tmp_path, "two"), "--no-progress")
    assert result.exit_code == 3, result.output
    assert "1 ok, 0 skipped, 1 failed" in result.stdout
    report = json.loads((tmp_path / "out_two" / "run_report.json").read_text())
    line01, line02 = report["scenes"]
    assert line01["status"] == "ok" and line02["status"] == "failed"
    assert line02["error"].startswith("steps.strata: ") and "red" in line02["error"], line02["error"]
    assert not (tmp_path / "out_two" / "line02_strata.tif").exists()
    assert report["fit"]["scenes_left_out"][0]["scene"] == "line02"  # the fit pooled line01 alone
