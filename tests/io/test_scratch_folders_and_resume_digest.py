"""What a stopped run leaves and what a resumed run sees (issue 39): SIGTERM removes ``nbar``'s
scratch folder and the file being written (exit 143, one line); a rerun removes the scratch folders
of dead processes only; the content digest that decides whether a scene is redone sees an edit in
a large file's header, end and samples.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import _forked
import numpy as np
from _cli_lines import _nbar

from brdfcorr.testing import write_sentinel2_safe

#: Seconds a command may take before it counts as hung (a FIFO blocks forever).
HANG_GUARD = 60



# ------------------------------------------------------------------------- resume: content digest
def test_content_digest_of_a_large_file_sees_its_header_end_and_samples(tmp_path, monkeypatch):
    """Above FULL_HASH_BYTES the digest reads the first and last EDGE_BYTES and SAMPLES pieces
    between: an edit there changes it, the file's size and time alike."""
    from brdfcorr.io import files

    monkeypatch.setattr(files, "FULL_HASH_BYTES", 1000)
    monkeypatch.setattr(files, "EDGE_BYTES", 100)
    monkeypatch.setattr(files, "SAMPLES", 4)
    monkeypatch.setattr(files, "SAMPLE_BYTES", 10)
    path = tmp_path / "big.bin"
    data = bytearray(np.random.default_rng(0).integers(0, 256, 10_000, dtype="uint8").tobytes())
    path.write_bytes(data)
    original = files.content_digest(path)
    for offset in (0, 99, 100, 100 + 2450, 9_999):  # header, header end, first and second sample, end
        edited = bytearray(data)
        edited[offset] ^= 0xFF
        path.write_bytes(edited)
        assert files.content_digest(path) != original, offset
    edited = bytearray(data)
    edited[200] ^= 0xFF  # between samples: not read (a large file is sampled)
    path.write_bytes(edited)
    assert files.content_digest(path) == original


# ------------------------------------------------------------------- scratch folders, SIGTERM
def test_sigterm_removes_the_scratch_folder_and_what_was_being_written(tmp_path):
    """SIGTERM ended the process where it stood: ``.nbar-XXXX`` scratch folders stayed and reruns
    never removed them (issue 39). It now stops as Ctrl-C does, exit 143 and one line."""
    folder = write_sentinel2_safe(tmp_path / "in", size=64)
    out = tmp_path / "out"
    out.mkdir()
    # A process of its own, forked from one that has imported the package (tests/_forked.py).
    process = _forked.start(["brdfcorr", "nbar", folder, "-o", out / "nbar.tif", "--view-band", "each",
                             "--no-progress"])
    for _ in range(30_000):  # a hang guard of at most 300 s of polling, not a measurement
        if any(out.glob(".nbar-*/*")) or process.poll() is not None:
            break
        time.sleep(0.01)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=HANG_GUARD)
    if process.returncode == 0:  # finished before the signal arrived: nothing to check
        return
    assert process.returncode == 143, stderr
    assert stderr.splitlines()[-1] == "brdfcorr: terminated"
    assert list(out.iterdir()) == [], "no scratch folder, no partial output"


def test_a_rerun_removes_the_scratch_folders_of_dead_processes_only(safe, invoke):
    """A SIGKILL leaves its scratch folder (no cleanup can run): the next nbar beside it removes
    it, and leaves the folder of a process that still runs."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()  # a process id that no longer runs
    dead = safe["out"] / f".nbar-{child.pid}-abcd1234"
    (dead / "bands").mkdir(parents=True)
    (dead / "stack.vrt").write_text("<VRTDataset/>")
    running = safe["out"] / f".nbar-{os.getpid()}-efgh5678"
    running.mkdir()
    code, stderr = invoke(_nbar(safe))
    assert code == 0, stderr
    assert not dead.exists() and running.is_dir()
    assert sorted(path.name for path in safe["out"].iterdir()) == [running.name, "nbar.tif"]
