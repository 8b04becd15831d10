"""Each option of ``correct``, ``fit-classes``, ``assess`` and ``nbar`` is described once, in
:mod:`brdfcorr.tasks.options`; the click options, the chain steps' defaults and words and the
request's defaults are made from it (issue 42). The KEY=VALUE and ID=NAME options are click types
that convert each item once and refuse a bad one with click's one-line usage error.
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from brdfcorr import defaults
from brdfcorr.cli import main
from brdfcorr.cli._base import CLASS_NAME, NAME_RANGE, NAME_VALUE, READER_OPTION
from brdfcorr.tasks.options import ASSESS, ASSESS_LINES, CORRECT, FIT_CLASSES, NBAR, Settings

TABLES = {"correct": CORRECT, "fit-classes": FIT_CLASSES, "assess": ASSESS, "assess-lines": ASSESS_LINES,
          "nbar": NBAR}


def _command(name: str) -> click.Command:
    command = main.get_command(click.Context(main), name)
    assert command is not None
    return command


@pytest.mark.parametrize("name", sorted(TABLES))
def test_every_option_of_the_command_is_a_setting_of_its_table(name):
    table: Settings = TABLES[name]
    options = [param for param in _command(name).params if isinstance(param, click.Option)]
    assert [option.name for option in options] == table.names()
    for option in options:
        setting = table[option.name]
        flags = [flag for declared in setting.flags for flag in declared.split("/")]
        assert [*option.opts, *option.secondary_opts] == flags, option.name
        assert option.multiple == setting.multiple and option.required == setting.required, option.name
        assert option.hidden == setting.hidden, option.name
        if setting.kind == "choice":
            assert tuple(option.type.choices) == setting.choices, option.name  # type: ignore[attr-defined]


def test_defaults_on_the_command_line_are_the_tables():
    command = _command("correct")
    context = click.Context(command)
    defaults_shown = {param.name: param.get_default(context) for param in command.params
                      if isinstance(param, click.Option)}
    assert defaults_shown["unknown"] == "keep" == CORRECT.default("unknown")
    assert tuple(defaults_shown["limits"]) == defaults.DEFAULT_LIMITS == (0.2, 5.0)
    assert defaults_shown["factor_at"] == "pixels"
    # Given only: unset on the command line (the rule of --topographic without terrain needs it),
    # the table's default applied by the command.
    assert not isinstance(defaults_shown["topographic"], str) and CORRECT.default("topographic") == "cosine"


def test_chain_steps_take_the_tables_defaults_and_words():
    from brdfcorr.chain.config_steps import AssessStep, CorrectStep, ImageryFit, TerrainStep

    correct, terrain = CorrectStep(), TerrainStep()
    for name in ("limits", "unknown", "extrapolate", "flip_view_azimuth", "factor_at"):
        assert getattr(correct, name) == CORRECT.default(name), name
    assert (terrain.topographic, terrain.brdf_frame) == ("cosine", "surface")
    fit = ImageryFit(source="imagery")
    for name in ("max_samples", "seed", "block_size", "levels", "patch_size", "min_samples", "min_vza_spread",
                 "max_condition"):
        assert getattr(fit, name) == FIT_CLASSES.default(name), name
    assess = AssessStep()
    for name in ("sign_by", "bin_width", "min_vza", "block_size"):
        assert getattr(assess, name) == ASSESS.default(name), name
    # The words are the owners': every one of them is accepted, another refused.
    for word in CORRECT["topographic"].choices:
        TerrainStep(topographic=word, brdf_frame="horizontal")
    with pytest.raises(ValueError, match="topographic"):
        TerrainStep(topographic="minnaert")
    # Bounds are the command line's, the chain's own stricter ones over them.
    with pytest.raises(ValueError, match="min_vza"):
        AssessStep(min_vza=90)
    with pytest.raises(ValueError, match="bin_width"):
        AssessStep(bin_width=60)  # the command line allows up to 90, a chain 45


def test_the_fit_step_passes_its_error_clusters_to_the_sampling():
    from brdfcorr.chain.config_steps import ImageryFit

    assert ImageryFit(source="imagery").fit_settings()["sampling"].errors_cluster == "one-way"
    assert ImageryFit(source="imagery", errors_cluster="two-way").fit_settings()["sampling"].errors_cluster == "two-way"
    with pytest.raises(ValueError, match="errors_cluster"):
        ImageryFit(source="imagery", errors_cluster="three-way")


@pytest.mark.parametrize(("step", "table", "model"), [("correct", CORRECT, "CorrectStep"),
                                                    ("terrain", CORRECT, "TerrainStep"),
                                                    ("fit", FIT_CLASSES, "ImageryFit"),
                                                    ("assess", ASSESS, "AssessStep")])
def test_chain_keys_are_made_from_the_settings(step, table, model):
    from brdfcorr.chain import config_steps

    fields = getattr(config_steps, model).model_fields
    marked = [setting for setting in table if setting.chain == step]
    assert marked and {setting.name for setting in marked} <= set(fields)
    for setting in marked:
        assert fields[setting.name].default == setting.default, setting.name


def test_chain_inputs_keys_are_made_from_the_settings():
    # inputs.flip_view_azimuth is --flip-view-azimuth of correct and fit-classes (one Setting),
    # unset (None) by default: the correct step's key decides then.
    from brdfcorr.chain.config import InputsConfig
    from brdfcorr.tasks.options import CHAIN_INPUTS, FLIP_VIEW_AZIMUTH

    fields = InputsConfig.model_fields
    assert [setting.name for setting in CHAIN_INPUTS if setting.chain == "inputs"] == ["flip_view_azimuth"]
    assert fields["flip_view_azimuth"].default is None is CHAIN_INPUTS.default("flip_view_azimuth")
    for table in (CORRECT, FIT_CLASSES):
        assert dataclasses.replace(table["flip_view_azimuth"], chain=None) == FLIP_VIEW_AZIMUTH


def test_library_defaults_agree_with_the_tables():
    # brdfcorr.fit.settings keeps its own dataclass defaults (the library's); they must not drift.
    from brdfcorr.fit.settings import GuardRails, Sampling

    sampling, guard = Sampling(), GuardRails()
    for name in ("max_samples", "seed", "block_size", "levels", "patch_size"):
        assert getattr(sampling, name) == FIT_CLASSES.default(name), name
    for name in ("min_samples", "min_vza_spread", "max_condition"):
        assert getattr(guard, name) == FIT_CLASSES.default(name), name


def test_request_takes_the_tables_defaults():
    from brdfcorr.tasks.request import CorrectionRequest, OutputFiles, Terrain

    fields = {field.name: field.default for cls in (CorrectionRequest, OutputFiles, Terrain)
              for field in dataclasses.fields(cls)}
    assert fields["unknown"] == "keep" and fields["factor_at"] == "pixels"
    assert fields["limits"] == (0.2, 5.0) and fields["extrapolate"] is False
    assert (fields["topographic"], fields["brdf_frame"]) == ("cosine", "surface")
    assert (fields["format"], fields["interleave"], fields["data_type"], fields["compress"]) == \
        ("GTiff", "bsq", "float", "deflate")


def test_topographic_words_are_written_once():
    from brdfcorr.correction.topographic import METHODS

    assert METHODS is defaults.TOPOGRAPHIC_METHODS
    assert CORRECT["topographic"].choices == (*METHODS, "none")
    assert set(defaults.C_METHODS) < set(METHODS)


def test_request_imports_nothing_from_the_correction_task():
    # The circle tasks.correct <-> tasks.request is gone, type-only imports included.
    import brdfcorr.tasks.request as request

    tree = ast.parse(Path(request.__file__).read_text())
    imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert "brdfcorr.tasks.correct" not in imported
    from brdfcorr.tasks.correct import Terrain

    assert Terrain is request.Terrain  # still importable where it was


@pytest.mark.parametrize(
    ("kind", "text", "value"),
    [
        (NAME_VALUE, "k=0.25", ("k", 0.25)),
        (NAME_VALUE, " n = 1e-3", ("n", 0.001)),
        (NAME_RANGE, "w=0.1:0.2", ("w", (0.1, 0.2))),
        (READER_OPTION, "resolution=20", ("resolution", 20)),
        (READER_OPTION, "band=B04", ("band", "B04")),
        (READER_OPTION, "ang=[a", ("ang", "[a")),  # no YAML: the text itself
        (READER_OPTION, "x=", ("x", "")),
        (CLASS_NAME, "2=grass", (2, "grass")),
    ],
)
def test_key_value_types_convert_once(kind, text, value):
    assert kind.convert(text, None, None) == value
    assert kind.convert(value, None, None) == value  # converted already: unchanged


@pytest.mark.parametrize(
    ("kind", "text", "message"),
    [
        (NAME_VALUE, "k", "'k': expected NAME=VALUE with numbers"),
        (NAME_RANGE, "w=0.1", "'w=0.1': expected NAME=LOW:HIGH with numbers"),
        (READER_OPTION, "=20", "'=20': expected KEY=VALUE"),
        (CLASS_NAME, "grass", "'grass': expected CLASS_ID=VALUE, e.g. 2=grass"),
        (CLASS_NAME, "2=", "'2=': expected CLASS_ID=VALUE"),
    ],
)
def test_key_value_types_refuse_bad_items(kind, text, message):
    with pytest.raises(click.BadParameter, match=message):
        kind.convert(text, None, None)


def test_a_bad_item_is_one_usage_line_with_exit_2(tmp_path):
    result = CliRunner().invoke(main, ["correct", str(tmp_path / "image.tif"), "-o", str(tmp_path / "out.tif"),
                                       "--params", "roy2017", "--angle-option", "resolution"])
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert lines == ["brdfcorr: error: correct: Invalid value for '--angle-option': 'resolution': expected "
                     "KEY=VALUE (see --help of correct)"]


@pytest.mark.parametrize("command, option, first, second", [
    ("correct", "--material", "1=roof_tile", "1=red_concrete"),
    ("correct", "--angle-option", "view_from_ang=ephemeris", "view_from_ang=mean"),
    ("fit-classes", "--class-model", "2=rpv", "2=ross_li_ts"),
    ("fit-classes", "--class-name", "2=grass", "2=lawn"),
])
def test_an_id_or_key_given_twice_with_different_values_is_one_usage_line(tmp_path, command, option, first, second):
    # A dict of the pairs kept the last without a word: which one was meant? Refused as the
    # options are parsed (the files need not exist); the same pair twice is one setting.
    files = ["--angles", str(tmp_path / "angles.tif"), "--classes", str(tmp_path / "classes.tif")]
    output = ["-o", str(tmp_path / ("out.tif" if command == "correct" else "table.yaml"))]
    given = ["--params", "roy2017"] * (command == "correct")
    result = CliRunner().invoke(main, [command, str(tmp_path / "image.tif"), *files, *output, *given,
                                       option, first, option, second])
    assert result.exit_code == 2
    key = first.partition("=")[0]
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and f"'{option}': {key} is given twice, as {first} and {second}: give it once" in lines[0]
    again = CliRunner().invoke(main, [command, str(tmp_path / "image.tif"), *files, *output, *given,
                                      option, first, option, first])
    assert "given twice" not in again.output
