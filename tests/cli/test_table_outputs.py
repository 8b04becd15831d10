"""One overwrite rule for every command that writes a parameter table (issue 26, item 3):
`fit -o`, `materials -o` and `coefficients -o` (one class) and `fit-classes -o` (a whole table)
write a new table, refuse an existing one without `--overwrite` (exit 2, one line, the file
untouched), write it with `--overwrite`, and keep a symbolic link a link (the file it points to is
rewritten)."""

import hashlib
import re

import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.fit.measurements import write_measurements
from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
from brdfcorr.models import load_material
from brdfcorr.params import ParameterTable

#: A hand-written table: its comment is what a silent rewrite would lose.
HAND_WRITTEN = "# measured on site, 2026-06-15\nclasses:\n  - {id: 1, name: tiles, material: roof_tile}\n"


@pytest.fixture(scope="module")
def measurements(tmp_path_factory):
    """Goniometer measurements of roof_tile (paper 003, Table 1), 1 % noise."""
    tile = load_material("roof_tile")
    path = tmp_path_factory.mktemp("gonio") / "tile.csv"
    write_measurements(path, synthesize_measurements(tile.model, tile.params, *goniometer_angles(),
                                                     relative_noise=0.01, seed=3))
    return path


def _command(kind: str, measurements, table) -> list[str]:
    """The command writing class 2 to ``table``."""
    return {
        "fit": ["fit", str(measurements), "--fix", "k=0.25", "--min-phi", "90", "-o", str(table), "--class-id", "2"],
        "materials": ["materials", "red_concrete", "-o", str(table), "--class-id", "2"],
        "coefficients": ["coefficients", "roy2016", "-o", str(table), "--class-id", "2"],
    }[kind]


COMMANDS = ["fit", "materials", "coefficients"]
#: The model each command writes as class 2.
MODELS = {"fit": "torrance_sparrow", "materials": "torrance_sparrow", "coefficients": "ross_thick_li_sparse"}


@pytest.mark.parametrize("kind", COMMANDS)
def test_an_existing_table_is_refused_without_overwrite_and_added_to_with_it(kind, measurements, tmp_path):
    table = tmp_path / "table.yaml"
    table.write_text(HAND_WRITTEN)
    before = hashlib.sha256(table.read_bytes()).hexdigest()
    refused = CliRunner().invoke(main, _command(kind, measurements, table))
    assert refused.exit_code == 2
    lines = refused.stderr.splitlines()
    assert lines == [f"brdfcorr: error: output {table} exists; give --overwrite to replace it"]
    assert hashlib.sha256(table.read_bytes()).hexdigest() == before
    assert "wrote" not in refused.stdout  # refused before any work was shown as done
    added = CliRunner().invoke(main, [*_command(kind, measurements, table), "--overwrite"])
    assert added.exit_code == 0, added.output
    result = ParameterTable.load(table)
    assert result.class_ids == (1, 2)
    assert result[1].name == "tiles" and result[1].params == load_material("roof_tile").params  # class 1 kept
    assert result[2].model == MODELS[kind]
    assert list(tmp_path.iterdir()) == [table]  # no temporary file left


@pytest.mark.parametrize("kind", COMMANDS)
def test_a_new_table_needs_no_overwrite(kind, measurements, tmp_path):
    table = tmp_path / "new.yaml"
    result = CliRunner().invoke(main, _command(kind, measurements, table))
    assert result.exit_code == 0, result.output
    assert ParameterTable.load(table).class_ids == (2,)


@pytest.mark.parametrize("kind", ["fit", "coefficients"])
def test_a_symbolic_link_stays_a_link_and_a_dangling_one_is_refused(kind, measurements, tmp_path):
    real = tmp_path / "tables" / "real.yaml"
    real.parent.mkdir()
    real.write_text(HAND_WRITTEN)
    link = tmp_path / "table.yaml"
    link.symlink_to(real)
    result = CliRunner().invoke(main, [*_command(kind, measurements, link), "--overwrite"])
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and link.resolve() == real.resolve()
    assert ParameterTable.load(real).class_ids == (1, 2)
    dangling = tmp_path / "nothing.yaml"
    dangling.symlink_to(tmp_path / "missing.yaml")
    result = CliRunner().invoke(main, [*_command(kind, measurements, dangling), "--overwrite"])
    assert result.exit_code == 2
    assert re.fullmatch(r"brdfcorr: error: -o \S+nothing\.yaml is a symbolic link to no file; give the file's own "
                        r"path", result.stderr.strip())
    assert dangling.is_symlink() and not (tmp_path / "missing.yaml").exists()


def test_the_measurements_are_never_the_table_even_with_overwrite(measurements):
    before = measurements.read_bytes()
    result = CliRunner().invoke(main, ["fit", str(measurements), "-o", str(measurements), "--overwrite"])
    assert result.exit_code == 2 and "inputs are never overwritten" in result.stderr
    assert measurements.read_bytes() == before


@pytest.mark.parametrize("kind", COMMANDS)
def test_help_says_the_rule(kind):
    text = " ".join(CliRunner().invoke(main, [kind, "--help"]).output.split())
    assert "an existing table needs --overwrite" in text


def test_fit_classes_refuses_an_existing_table_or_report_before_fitting(tmp_path):
    # fit-classes writes a whole table (not one class): an existing one is replaced only with
    # --overwrite, and the refusal comes before the fit's work.
    from brdfcorr.testing import synthetic_scene, write_scene

    paths = write_scene(tmp_path, synthetic_scene(ny=32, nx=48))
    base = ["fit-classes", str(paths["image"]), "--angles", str(paths["angles"]), "--classes", str(paths["classes"]),
            "--model", "lambertian", "--min-vza-spread", "0"]
    for existing in ("table.yaml", "report.json"):
        (tmp_path / existing).write_text(HAND_WRITTEN)
        before = hashlib.sha256((tmp_path / existing).read_bytes()).hexdigest()
        refused = CliRunner().invoke(main, [*base, "-o", str(tmp_path / "table.yaml"),
                                            "--report", str(tmp_path / "report.json")])
        assert refused.exit_code == 2 and "give --overwrite" in refused.output
        assert hashlib.sha256((tmp_path / existing).read_bytes()).hexdigest() == before
        (tmp_path / existing).unlink()
    (tmp_path / "table.yaml").write_text(HAND_WRITTEN)
    replaced = CliRunner().invoke(main, [*base, "-o", str(tmp_path / "table.yaml"), "--overwrite"])
    assert replaced.exit_code == 0, replaced.output
    fitted = ParameterTable.load(tmp_path / "table.yaml")
    assert {entry.model for entry in fitted.classes} == {"lambertian"}  # the fit, not the hand-written table
