"""The outputs of `fit-classes` (table, --report, --plot-dir figures) and of `fit` (-o table,
--plot-dir figures) appear together or not at all: a table written before its report failed looked
finished, and the rerun was refused ("exists; give --overwrite")."""

from __future__ import annotations

import errno

import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib.figure import Figure

from brdfcorr.cli import main
from brdfcorr.fit.measurements import write_measurements
from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable


@pytest.fixture(scope="module")
def scene(tmp_path_factory, write_strata_scene):
    return write_strata_scene(tmp_path_factory.mktemp("together") / "scene")


@pytest.fixture(scope="module")
def csv_path(tmp_path_factory):
    truth = load_material("roof_tile")
    data = synthesize_measurements(truth.model, truth.params, *goniometer_angles(), seed=11)
    return write_measurements(tmp_path_factory.mktemp("gonio") / "roof_tile.csv", data)


def _fit_classes(scene, *options):
    return CliRunner().invoke(main, [
        "fit-classes", str(scene["image"]), "--angles", str(scene["angles"]), "--classes", str(scene["classes"]),
        "--model", "ross_thick_li_sparse", "--min-samples", "50", "--no-progress", *map(str, options)])


def _full_disk(*args, **kwargs):  # a figure's write fails as on a full disk
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_report_that_cannot_be_written_leaves_no_table(scene, tmp_path):
    (tmp_path / "afile").touch()
    table = tmp_path / "out" / "table.yaml"
    failed = _fit_classes(scene, "-o", table, "--report", tmp_path / "afile" / "report.json")
    assert failed.exit_code == 2
    assert failed.output.strip().splitlines()[-1].startswith(f"brdfcorr: error: cannot write {tmp_path}/afile/")
    assert not table.exists() and list(table.parent.iterdir()) == []  # no temporary file either
    again = _fit_classes(scene, "-o", table, "--report", tmp_path / "report.json")  # no --overwrite needed
    assert again.exit_code == 0, again.output
    assert ParameterTable.load(table).class_ids == (1, 2) and (tmp_path / "report.json").exists()


def test_figures_that_fail_leave_neither_table_nor_report(scene, tmp_path, monkeypatch):
    monkeypatch.setattr(Figure, "savefig", _full_disk)
    failed = _fit_classes(scene, "-o", tmp_path / "table.yaml", "--report", tmp_path / "report.json",
                          "--plot-dir", tmp_path / "plots")
    assert failed.exit_code == 2
    assert "No space left on device" in failed.output and "nothing was written" in failed.output
    assert sorted(path.name for path in tmp_path.rglob("*") if path.is_file()) == []


def test_fit_figures_that_fail_leave_the_table_as_it_was(csv_path, tmp_path, monkeypatch):
    table = tmp_path / "params.yaml"
    first = CliRunner().invoke(main, ["fit", str(csv_path), "--fix", "k=0.25", "-o", str(table), "--class-id", "1"])
    assert first.exit_code == 0, first.output
    before = table.read_bytes()
    monkeypatch.setattr(Figure, "savefig", _full_disk)
    failed = CliRunner().invoke(main, ["fit", str(csv_path), "--fix", "k=0.25", "-o", str(table), "--class-id", "2",
                                       "--overwrite", "--plot-dir", str(tmp_path / "plots")])
    assert failed.exit_code == 2 and "No space left on device" in failed.output
    assert table.read_bytes() == before  # class 2 not added: the figures and the table go together
    assert not any((tmp_path / "plots").iterdir())


def test_fit_table_that_cannot_be_written_leaves_no_figures(csv_path, tmp_path):
    (tmp_path / "afile").touch()
    failed = CliRunner().invoke(main, ["fit", str(csv_path), "--fix", "k=0.25", "-o", str(tmp_path / "afile" / "t.yaml"),
                                       "--plot-dir", str(tmp_path / "plots")])
    assert failed.exit_code == 2
    assert not (tmp_path / "plots").exists() or not any((tmp_path / "plots").iterdir())
    assert np.all([not path.name.endswith(".png") for path in tmp_path.rglob("*")])
