"""A process killed mid-write, or a disk that fills, never leaves an output that looks complete.

Outputs are written to a temporary name beside the target (``.NAME.XXXX.partial``) and renamed
when complete (:func:`brdfcorr.io.files.atomic_path`). A SIGKILL cannot run any clean-up, so the
temporary file may stay; nothing may appear under the output's own name, and a rerun succeeds. A
failed write (disk full, file size limit) is an exit code 2 with one message naming the file, and
nothing is left at all.
"""

from __future__ import annotations

import errno
import os
import re
import signal
import time
from pathlib import Path

import _forked
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr import normalize
from brdfcorr.cli import main
from brdfcorr.testing import example_table, synthetic_scene

NY = NX = 512  # 512 x 512 x 4 bands: a few seconds to correct in chunks of 32 pixels
CHUNK = 32
PARTIAL = re.compile(r"^\.corrected\.tif\.[^/]+\.partial$")


@pytest.fixture(scope="module")
def big(tmp_path_factory, write_example_scene) -> dict:
    scene = synthetic_scene(ny=NY, nx=NX)
    return {"scene": scene, **write_example_scene(tmp_path_factory.mktemp("big") / "scene", scene, blocksize=64)}


def _arguments(big, output: Path, *extra, chunk: int = CHUNK) -> list[str]:
    return ["correct", str(big["image"]), "--angles", str(big["angles"]), "--classes", str(big["classes"]),
            "--params", str(big["params"]), "-o", str(output), "--chunk", str(chunk), "--no-progress",
            *map(str, extra)]


def test_sigkill_mid_write_leaves_only_a_partial_file_and_a_rerun_succeeds(big, tmp_path):
    output_dir = tmp_path / "out"
    output_dir.mkdir()
    output = output_dir / "corrected.tif"
    # A process of its own, forked from one that has imported the package (tests/_forked.py).
    process = _forked.start(["brdfcorr", *_arguments(big, output)])
    try:
        for _ in range(30_000):  # a hang guard of at most 300 s of polling, not a measurement
            if any(PARTIAL.match(p.name) for p in output_dir.iterdir()):
                break
            assert process.poll() is None, f"finished before writing began: {process.communicate()}"
            time.sleep(0.01)
        else:
            raise AssertionError("no temporary output appeared")
        time.sleep(0.3)  # into the chunked write (which takes several seconds here)
        assert process.poll() is None, "the write finished before the kill: make the scene larger"
        process.send_signal(signal.SIGKILL)
        assert process.wait(timeout=30) == -signal.SIGKILL
    finally:
        if process.poll() is None:
            process.kill()
        process.communicate()

    left = sorted(p.name for p in output_dir.iterdir())
    assert not output.exists()
    assert left and all(PARTIAL.match(name) for name in left), left  # only the temporary file

    # The rerun need not be a process of its own, nor slow: in this process, in larger chunks.
    rerun = CliRunner().invoke(main, _arguments(big, output, chunk=4 * CHUNK))
    assert rerun.exit_code == 0, rerun.output
    assert output.exists()
    # The rerun's output is complete: the same numbers as the in-memory (numpy) normalization.
    scene = big["scene"]
    expected, _ = normalize(scene["reflectance"], scene["classes"].rio.write_nodata(255),
                            {name: scene[name] for name in ("sza", "saa", "vza", "vaa")}, example_table())
    with rasterio.open(output) as dataset:
        np.testing.assert_array_equal(dataset.read(), expected.values)


def test_file_size_limit_mid_write_exits_2_and_leaves_nothing(big, tmp_path):
    """RLIMIT_FSIZE stands in for a full disk: the kernel refuses writes past the limit."""
    output_dir = tmp_path / "out"
    output_dir.mkdir()
    output = output_dir / "corrected.tif"
    # A process of its own under the limit, forked from one that has imported the package (tests/_forked.py).
    result = _forked.run(["brdfcorr", *_arguments(big, output, "--compress", "none", "--qa", output_dir / "qa.tif",
                                                  chunk=128)], timeout=120, file_size_limit=256 * 1024)
    assert result.returncode == 2, result.stderr
    # GDAL's TIFF writer prints its own lines too (C stderr, in any order with ours): brdfcorr's
    # message is its one line among them.
    ours = [line for line in result.stderr.splitlines() if line.startswith("brdfcorr:")]
    assert len(ours) == 1, result.stderr
    last = ours[0]
    assert re.match(rf"brdfcorr: error: cannot write {re.escape(str(output))}, \S*qa\.tif: .*nothing was "
                    r"written \(check the free space, file size limit and permissions of ", last), last
    assert "Traceback" not in result.stderr
    assert list(output_dir.iterdir()) == []


@pytest.fixture
def small(tmp_path, write_example_scene) -> dict:
    (tmp_path / "out").mkdir()
    return write_example_scene(tmp_path / "scene", synthetic_scene(ny=64, nx=64))


@pytest.mark.parametrize("cog", [False, True])
def test_disk_full_mid_write_exits_2_and_leaves_nothing(small, tmp_path, monkeypatch, cog):
    """GDAL's block writes raise ENOSPC after two blocks, as a full disk would (rasterio's
    DatasetWriter.write: the path of every writer, local or on a cluster)."""
    original, calls = rasterio.io.DatasetWriter.write, []

    def fills_up(self, *args, **kwargs):
        calls.append(args)
        if len(calls) > 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(rasterio.io.DatasetWriter, "write", fills_up)
    output = tmp_path / "out" / "corrected.tif"
    args = ["correct", small["image"], "--angles", small["angles"], "--classes", small["classes"],
            "--params", small["params"], "-o", output, "--chunk", 16, "--qa", tmp_path / "out" / "qa.tif"]
    result = CliRunner().invoke(main, [str(a) for a in args] + (["--cog"] if cog else []))
    assert len(calls) > 2, "the simulated disk never filled"
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [result.stderr.strip()]
    assert re.match(r"brdfcorr: error: cannot write \S*corrected\.tif, \S*qa\.tif: No space left on device",
                    result.stderr), result.stderr
    assert list((tmp_path / "out").iterdir()) == []
