"""Several outputs renamed together (:func:`brdfcorr.io.files.atomic_paths`: ``fit-classes``'
table, report and figures) lose no old output when a rename fails: files already at the targets
(replaced with ``--overwrite``) are moved aside first and put back, with their old content, where
any rename fails; no temporary or backup file is left either way. Before, a rename that failed
after the first removed the first target, and with it the old output it had replaced.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from brdfcorr.errors import OutputError
from brdfcorr.io.files import atomic_paths

NAMES = ("table.yaml", "report.json", "class_1.png")


def _write_all(targets: list[Path]) -> None:
    with atomic_paths(targets) as temporaries:
        for target, temporary in temporaries.items():
            temporary.write_text(f"new {target.name}")


@pytest.mark.parametrize("step", ["rename of the second new file", "moving the second old file aside"])
def test_a_failed_rename_keeps_every_old_output(tmp_path, monkeypatch, step):
    targets = [tmp_path / name for name in NAMES]
    for target in targets:
        target.write_text(f"old {target.name}")
    replace = os.replace

    def failing(source, destination):
        source, destination = Path(source), Path(destination)
        moving_aside = source == targets[1]
        renaming = destination == targets[1] and source.name.endswith(".partial")
        if moving_aside if step.startswith("moving") else renaming:
            raise OSError(5, "Input/output error")
        replace(source, destination)

    monkeypatch.setattr(os, "replace", failing)
    with pytest.raises(OutputError, match="Input/output error"):
        _write_all(targets)
    assert {target.name: target.read_text() for target in targets} == {name: f"old {name}" for name in NAMES}
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted(NAMES)  # no .partial, no .backup


def test_a_failed_rename_leaves_new_targets_absent(tmp_path, monkeypatch):
    # Only the second target existed: it keeps its old content, the others stay absent.
    targets = [tmp_path / name for name in NAMES]
    targets[1].write_text("old")
    replace = os.replace

    def failing(source, destination):
        if Path(destination) == targets[2] and Path(source).name.endswith(".partial"):
            raise OSError(5, "Input/output error")
        replace(source, destination)

    monkeypatch.setattr(os, "replace", failing)
    with pytest.raises(OutputError):
        _write_all(targets)
    assert [path.name for path in tmp_path.iterdir()] == [NAMES[1]] and targets[1].read_text() == "old"


def test_renames_that_succeed_replace_every_old_output(tmp_path):
    targets = [tmp_path / name for name in NAMES]
    targets[0].write_text("old")
    _write_all(targets)
    assert {target.name: target.read_text() for target in targets} == {name: f"new {name}" for name in NAMES}
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted(NAMES)
