"""A correction that does nothing is never silent (issue 24): a table without classes is exit 2
wherever a table is used, a run that leaves most pixels uncorrected says so, and the README's
example table improves every class of the demo scene it is run on."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from click.testing import CliRunner

from brdfcorr.chain.demo import demo_scene, write_demo_scene
from brdfcorr.chain.report import assessment_summary
from brdfcorr.cli import main
from brdfcorr.io.scene import SceneSources
from brdfcorr.tasks.assess import assess_files

ROOT = Path(__file__).parents[2]


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> dict[str, Path]:
    """A smaller demo line (60 rows, the demo's classes and geometry)."""
    return write_demo_scene(tmp_path_factory.mktemp("demo"), demo_scene(rows=60, pixel=12.0))


def _correct(demo, params: Path, output: Path, *extra):
    return CliRunner().invoke(main, [str(a) for a in (
        "correct", demo["image"], "--angles", demo["angles"], "--classes", demo["classes"], "--params", params,
        "-o", output, "--no-progress", *extra)])


def _one_error_line(result) -> str:
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("brdfcorr: error: "), lines[0]
    return lines[0]


def test_the_readme_example_table_improves_every_class_of_the_demo_scene(demo, tmp_path):
    output = tmp_path / "corrected.tif"
    result = _correct(demo, ROOT / "configs" / "params_example.yaml", output)
    assert result.exit_code == 0, result.output
    summary = assessment_summary(assess_files(SceneSources(demo["image"], demo["classes"], demo["angles"]),
                                              output).report())
    assert {row["id"] for row in summary} == {1, 2, 3, 4, 5}
    for row in summary:
        slopes = row["median_abs_relative_slope_percent_per_10deg"]
        # Before: several %/10 deg (docs/assess.md); after: the view-angle signal taken out.
        assert slopes["after"] < 0.2 * slopes["before"], row


def test_a_table_without_classes_is_exit_2_for_correct_and_validate(demo, tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text(yaml.safe_dump({"classes": []}))
    output = tmp_path / "out.tif"
    result = _correct(demo, empty, output)
    assert result.exit_code == 2
    assert _one_error_line(result).endswith("empty.yaml: the parameter table has no classes: nothing would be "
                                            "corrected")
    assert not output.exists() and list(tmp_path.iterdir()) == [empty]
    result = CliRunner().invoke(main, ["validate", str(empty)])
    assert result.exit_code == 2
    assert "empty.yaml: the parameter table has no classes" in _one_error_line(result)


def test_fit_classes_that_fit_no_class_writes_nothing(demo, tmp_path):
    # A guard no class can pass (a view-zenith spread of 89 deg): no table is written, exit 2.
    output = tmp_path / "fitted.yaml"
    result = CliRunner().invoke(main, [str(a) for a in (
        "fit-classes", demo["image"], "--angles", demo["angles"], "--classes", demo["classes"],
        "--min-vza-spread", 89, "-o", output)])
    assert result.exit_code == 2, result.output
    assert "no class passed the guard rails" in result.stderr.splitlines()[-1]
    assert not output.exists()


def test_a_correction_that_leaves_most_pixels_uncorrected_says_so(demo, tmp_path):
    # Only the roof tiles (class 1) are in this table: most of the demo's pixels keep their values.
    table = yaml.safe_load((ROOT / "configs" / "params_example.yaml").read_text())
    table["classes"] = [entry for entry in table["classes"] if entry["id"] == 1]
    params = tmp_path / "roofs_only.yaml"
    params.write_text(yaml.safe_dump(table))
    result = _correct(demo, params, tmp_path / "out.tif")
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.stderr.splitlines() if line.startswith("brdfcorr: warning: ")]
    assert len(warnings) == 1, result.stderr
    # The numbers of the class map itself: roof pixels corrected, 0/255 no class, ids 2-5 unknown.
    with rasterio.open(demo["classes"]) as dataset:
        classes = dataset.read(1)
    roofs, no_class = int((classes == 1).sum()), int(np.isin(classes, (0, 255)).sum())
    unknown = classes.size - roofs - no_class
    assert warnings[0] == (
        f"brdfcorr: warning: only {100 * roofs / classes.size:.0f} % of the {classes.size} valid pixels were "
        f"corrected: {no_class} have no class and {unknown} a class the parameter table does not have; check the "
        "class map against the table's class ids")
    assert roofs < classes.size / 2
