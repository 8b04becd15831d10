"""A chain's outputs are committed once (issue 26): two runs of one chain exclude each other (a lock
file with the holder's pid; the lock of a dead run is taken over), and an ENVI output has one commit
point: a process killed after its sidecars were renamed leaves no data file beside them, and the
resumed chain redoes the scene (as it redoes one killed before its quicklook).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from _cli_lines import _one_line
from click.testing import CliRunner

from brdfcorr.chain import run as chain_module
from brdfcorr.chain.config import load_config
from brdfcorr.chain.plan import plan_run
from brdfcorr.chain.run import LOCK_NAME, run_lock
from brdfcorr.cli import main
from brdfcorr.io import commit

# The scene: a copy of the 32 x 32 template of tests/conftest.py, 4 bands of float32: 16 384 bytes of data.


# --------------------------------------------------------------------------- one run at a time
def test_a_second_run_of_a_chain_is_refused_and_removes_nothing(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1, ny=16, nx=16)
    chain = write_chain(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    partial = out / ".line0_brdf.tif.abcd1234.partial"  # the first run's file in flight
    partial.write_bytes(b"in flight")
    with run_lock(out) as lock:  # the first run, in this process
        assert lock.read_text().strip() == str(os.getpid())
        result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
        assert result.exit_code == 2, result.output
        _one_line(result.stderr, rf"another brdfcorr run \(pid {os.getpid()}\) is writing to \S*out "
                                 rf"\(lock file \S*{re.escape(LOCK_NAME)}\)")
        assert partial.read_bytes() == b"in flight"
        assert sorted(p.name for p in out.iterdir()) == sorted([LOCK_NAME, partial.name])
    assert not (out / LOCK_NAME).exists()


def test_the_lock_of_a_dead_run_is_taken_over(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1, ny=16, nx=16)
    chain = write_chain(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (out / LOCK_NAME).write_text(dead.stdout)  # a run killed with -9 left its lock file
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 0, result.output
    assert (out / "line0_brdf.tif").exists() and not (out / LOCK_NAME).exists()


# ------------------------------------------------------------------- one commit point for ENVI
def test_envi_output_killed_between_its_sidecars_and_its_data_is_redone(tmp_path, make_scenes, write_chain,
                                                                        monkeypatch):
    make_scenes(tmp_path, count=1, ny=16, nx=16)
    outputs = {"directory": "out", "format": "ENVI", "naming": "{parent}_brdf.img", "existing": "skip"}
    chain = write_chain(tmp_path, outputs=outputs)
    assert CliRunner().invoke(main, ["run", str(chain), "--no-progress"]).exit_code == 0
    data = tmp_path / "out" / "line0_brdf.img"
    chain = write_chain(tmp_path, outputs=outputs, reference={"sza": 50.0, "vza": 0.0, "raa": 0.0})
    replace = os.replace

    def killed_at_the_data_file(source, target):
        if Path(target) == data:
            raise KeyboardInterrupt  # the process ends here (kill -9 runs no clean-up either)
        return replace(source, target)

    monkeypatch.setattr(commit.os, "replace", killed_at_the_data_file)
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 130, result.output  # interrupted
    monkeypatch.setattr(commit.os, "replace", replace)
    # The new header and tags are in place, the old data file is not: nothing looks complete.
    assert (tmp_path / "out" / "line0_brdf.hdr").exists() and not data.exists()
    plan = plan_run(load_config(chain))
    assert [scene.action for scene in plan.scenes] == ["run"]


def test_a_scene_killed_before_its_quicklook_is_redone(tmp_path, make_scenes, write_chain, monkeypatch):
    """The quicklook is made from the corrected image after that is in place: a run killed in
    between must not leave the old quicklook beside a corrected image that says "complete"."""
    make_scenes(tmp_path, count=1, ny=16, nx=16)
    steps = {"correct": {"limits": None}, "quicklook": {"bands": [3, 2, 1]}}
    chain = write_chain(tmp_path, steps=steps, outputs__existing="skip")
    assert CliRunner().invoke(main, ["run", str(chain), "--no-progress"]).exit_code == 0
    assert (tmp_path / "out" / "line0.png").exists()
    chain = write_chain(tmp_path, steps=steps, outputs__existing="skip",
                        reference={"sza": 50.0, "vza": 0.0, "raa": 0.0})

    def killed(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(chain_module, "_quicklook", killed)
    assert CliRunner().invoke(main, ["run", str(chain), "--no-progress"]).exit_code == 130
    assert (tmp_path / "out" / "line0_brdf.tif").exists() and not (tmp_path / "out" / "line0.png").exists()
    assert [scene.action for scene in plan_run(load_config(chain)).scenes] == ["run"]
