"""`fit-classes` as a scientist expects it (issue 29, "Names and defaults"): one option spelling
(`--class-name`, the old `--name` a hidden alias that warns), a kernel-driven default model and the
class names of an NDVI strata map (its tags say what it is), the condition-number guard rail as
an option, and `brdfcorr models` within 100 columns."""

import re

import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.params import ParameterTable


@pytest.fixture(scope="module")
def files(tmp_path_factory, write_strata_scene):
    """The scene rendered from STRATA_TRUTH (soil and grass) with its NDVI strata map (tests/conftest.py)."""
    root = tmp_path_factory.mktemp("names")
    return {**write_strata_scene(root), "root": root}


def _fit(files, classes, *options, output="table.yaml"):
    result = CliRunner().invoke(main, [
        "fit-classes", str(files["image"]), "--angles", str(files["angles"]), "--classes", str(classes),
        "--min-samples", "50", "-o", str(files["root"] / output), *map(str, options)])
    return result, files["root"] / output


def test_a_strata_map_gets_a_kernel_model_and_its_own_class_names_and_says_so(files):
    result, output = _fit(files, files["strata"])
    assert result.exit_code == 0, result.output
    table = ParameterTable.load(output)
    assert {entry.model for entry in table.classes} == {"ross_thick_li_sparse"}
    # The names `classes ndvi` wrote in the map's class_names tag, not class_1, class_2.
    assert [entry.name for entry in table.classes] == ["ndvi_-inf_0.30", "ndvi_0.30_inf"]
    assert "model ross_thick_li_sparse for every class: the class map is NDVI strata" in result.output
    assert "class names from the class map's tags: 1=ndvi_-inf_0.30, 2=ndvi_0.30_inf" in result.output


def test_explicit_model_and_class_name_win_over_the_map(files):
    result, output = _fit(files, files["strata"], "--model", "ross_thin_li_sparse", "--class-name", "2=grass",
                          output="explicit.yaml")
    assert result.exit_code == 0, result.output
    table = ParameterTable.load(output)
    assert {entry.model for entry in table.classes} == {"ross_thin_li_sparse"}
    assert (table[1].name, table[2].name) == ("ndvi_-inf_0.30", "grass")
    assert "for every class: the class map is NDVI strata" not in result.output
    assert result.stderr == ""


def test_a_plain_class_map_keeps_the_torrance_sparrow_default(files):
    from brdfcorr.fit.classes import ClassModels, GuardRails
    from brdfcorr.tasks.fit import SceneFiles, fit_class_files

    fit = fit_class_files([SceneFiles(files["image"], files["classes"], files["angles"])], ClassModels(None),
                          guard=GuardRails(min_samples=50))
    assert {class_fit.model for class_fit in fit.result.fits} == {"torrance_sparrow"}
    assert [class_fit.name for class_fit in fit.result.fits] == ["class_1", "class_2"]  # no names in its tags
    assert fit.notes == []


def test_the_old_name_option_still_works_hidden_and_warns(files):
    result, output = _fit(files, files["strata"], "--name", "1=soil", output="old.yaml")
    assert result.exit_code == 0, result.output
    assert ParameterTable.load(output)[1].name == "soil"
    assert result.stderr.splitlines()[0] == "brdfcorr: warning: --name is deprecated; use --class-name ID=NAME"
    for command in (["fit-classes"], ["fit"], ["assess"]):
        text = CliRunner().invoke(main, [*command, "--help"]).output
        assert not re.search(r"(?<![\w-])--name\b", text), command
        assert "--class-name" in text, command


def test_the_condition_limit_is_an_option(files):
    strict, output = _fit(files, files["strata"], "--max-condition", "1", output="strict.yaml")
    # A condition number is >= 1 and the kernels' columns are not orthogonal: every class fails.
    assert strict.exit_code == 2 and not output.exists()
    assert "ill-conditioned (condition" in strict.output and "> 1)" in strict.output
    assert "--max-condition" in CliRunner().invoke(main, ["fit-classes", "--help"]).output


def test_models_fits_100_columns_and_details_one_model():
    listing = CliRunner().invoke(main, ["models"])
    assert listing.exit_code == 0
    lines = listing.output.splitlines()
    assert max(map(len, lines)) <= 100 and not any(line != line.rstrip() for line in lines)
    assert any(line.startswith("ross_thick_li_sparse  ") for line in lines)
    one = CliRunner().invoke(main, ["models", "ross_thick_li_sparse"])
    assert one.exit_code == 0
    assert "Lucht, Schaaf & Strahler (2000)" in one.output and "volume-scattering weight" in one.output
    assert max(map(len, one.output.splitlines())) <= 100
    unknown = CliRunner().invoke(main, ["models", "lambert"])
    assert unknown.exit_code == 2 and "unknown BRDF model 'lambert'" in unknown.output


def test_assess_names_the_strata_as_fit_classes_does(files):
    # The names of the map's tags in the report (and the legends), a --class-name still winning.
    import json

    result, table = _fit(files, files["strata"], output="assess_table.yaml")
    assert result.exit_code == 0, result.output
    corrected, report = files["root"] / "assess_corrected.tif", files["root"] / "assess.json"
    common = ["--angles", str(files["angles"]), "--classes", str(files["strata"])]
    assert CliRunner().invoke(main, ["correct", str(files["image"]), *common, "--params", str(table),
                                     "-o", str(corrected)]).exit_code == 0
    result = CliRunner().invoke(main, ["assess", str(files["image"]), str(corrected), *common, "--class-name",
                                       "2=grass", "-o", str(report)])
    assert result.exit_code == 0, result.output
    classes = json.loads(report.read_text())["view_angles"]["classes"]
    assert [entry["name"] for entry in classes] == ["ndvi_-inf_0.30", "grass"]


@pytest.mark.parametrize("size, blocks", [(64, 1), (32, 4)])
def test_the_block_size_is_an_option(files, size, blocks):
    # The 48 x 64 scene in squares of `size` pixels: the errors of each class (both span the scene)
    # come from that many blocks, too few, which the report says (one block gives no errors at all).
    import json

    report = files["root"] / f"blocks_{size}.json"
    result, _ = _fit(files, files["strata"], "--block-size", size, "--report", report, output=f"blocks_{size}.yaml")
    assert result.exit_code == 0, result.output
    reasons = [entry["errors_reason"] for entry in json.loads(report.read_text())["classes"]]
    said = f"errors from {blocks} spatial blocks" if blocks > 1 else "all samples in one spatial block"
    assert all(said in reason and "--block-size" in reason for reason in reasons)


def test_class_settings_for_a_class_no_map_holds_are_named(files):
    """--class-model 9=rpv --class-name 9=foo where the map holds classes 1 and 2 (9 meant 7, or
    1): the fit goes on and says which settings it did not use, instead of nothing."""
    result, output = _fit(files, files["strata"], "--class-model", "9=rpv", "--class-name", "9=foo",
                          "--class-name", "2=grass", output="typo.yaml")
    assert result.exit_code == 0, result.output
    assert ("brdfcorr: warning: the class settings name class 9 that no class map holds (class_models 9; names 9): "
            "not used") in result.stderr.splitlines()
    assert ParameterTable.load(output)[2].name == "grass"
