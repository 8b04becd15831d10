"""A write that fails leaves nothing (issue 26): exit code 2 with exactly one stderr line
``brdfcorr: error: ...`` naming the file and the cause, no file at the target (not even a temporary
one) and the inputs byte-identical; a write that fits gives the same numbers.

1. a full disk, stood in for by the file size limit (``RLIMIT_FSIZE`` in a subprocess, SIGXFSZ
   ignored so that writes fail with EFBIG, as they fail with ENOSPC on a full device): GeoTIFF and
   ENVI outputs, ``materials -o``, ``fit-classes -o``/``--report`` and the run report. GDAL reported
   such failures only in its log and rasterio raised nothing at close: files that read as NaN were
   reported as written, and libtiff printed its own lines on stderr;
2. ``--chunk 100000``'s real cause: a GeoTIFF tile of 100 000 pixels square (160 GB to allocate for
   4 bands of float32), now no larger than the raster; an allocation failure GDAL only logs is named
   as such, not blamed on the disk.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import shutil
import subprocess
from pathlib import Path

import _forked
import dask
import numpy as np
import pytest
import rasterio
import xarray as xr
from _cli_lines import _correct_args, _one_line
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import OutputError
from brdfcorr.io.writer import GeoTiffOutput, write_rasters
from brdfcorr.testing import file_digests, georeference

# The scene: a copy of the 32 x 32 template of tests/conftest.py, 4 bands of float32: 16 384 bytes of data.


def _run(args, limit: int | None = None, cwd=None) -> subprocess.CompletedProcess:
    """``brdfcorr ARGS`` in a process of its own, under a file size limit [bytes] if given."""
    return _forked.run(["brdfcorr", *args], cwd=cwd, timeout=120, file_size_limit=limit)


# --------------------------------------------------------------------------------- full disks
@pytest.mark.parametrize("fmt, name", [("GTiff", "corrected.tif"), ("ENVI", "corrected.img")])
def test_file_size_limit_below_the_output_is_exit_2_and_leaves_nothing(scene, fmt, name):
    """The limit is 1 byte below the output's size (measured without a limit): the write cannot
    complete, so exit 0 would be a corrupt file reported as written."""
    reference = scene["out"].parent / "reference"
    reference.mkdir()
    extra = ["--format", fmt, "--qa", reference / "qa.tif"]
    result = CliRunner().invoke(main, _correct_args(scene, reference / name, *extra))
    assert result.exit_code == 0, result.output
    size = (reference / name).stat().st_size
    before = file_digests(scene["dir"])
    output = scene["out"] / name
    limit = size - 1
    run = _run(_correct_args(scene, output, "--format", fmt, "--qa", scene["out"] / "qa.tif"), limit)
    assert run.returncode == 2, run.stderr
    _one_line(run.stderr, rf"cannot write {re.escape(str(output))}.*File too large: the file size limit "
                          rf"\(ulimit -f\) of {limit} bytes was reached.*; nothing was written")
    assert list(scene["out"].iterdir()) == [], "no output, no temporary file"
    assert file_digests(scene["dir"]) == before


def test_file_size_limit_above_the_outputs_gives_the_same_numbers(scene):
    """A limit the outputs fit under: exit 0 and the numbers of the run without a limit."""
    reference = scene["out"].parent / "reference"
    reference.mkdir()
    assert CliRunner().invoke(main, _correct_args(scene, reference / "c.tif")).exit_code == 0
    before = file_digests(scene["dir"])
    run = _run(_correct_args(scene, scene["out"] / "c.tif"), (reference / "c.tif").stat().st_size + 4096)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert file_digests(scene["dir"]) == before and [p.name for p in scene["out"].iterdir()] == ["c.tif"]
    with rasterio.open(reference / "c.tif") as expected, rasterio.open(scene["out"] / "c.tif") as written:
        np.testing.assert_array_equal(written.read(), expected.read())


def test_materials_output_on_a_full_disk(tmp_path):
    table = tmp_path / "table.yaml"
    run = _run(["materials", "roof_tile", "-o", table], limit=100)  # the table is ~400 bytes
    assert run.returncode == 2, run.stderr
    _one_line(run.stderr, rf"cannot write {re.escape(str(table))}: File too large: .*; nothing was written")
    assert list(tmp_path.iterdir()) == []


def test_fit_classes_table_on_a_full_disk(scene):
    table = scene["out"] / "fitted.yaml"
    before = file_digests(scene["dir"])
    run = _run(["fit-classes", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"],
                "--min-samples", 10, "--min-vza-spread", 1, "-o", table], limit=200)  # the table is > 1 kB
    assert run.returncode == 2, run.stderr
    _one_line(run.stderr, rf"cannot write {re.escape(str(table))}: File too large")
    assert list(scene["out"].iterdir()) == [] and file_digests(scene["dir"]) == before


def test_fit_classes_report_on_a_full_disk(scene, monkeypatch):
    """The report's write fails with ENOSPC: exit 2, one line, and the table written with it is not
    left behind either (the outputs of fit-classes are renamed into place together)."""
    table, report = scene["out"] / "fitted.yaml", scene["out"] / "report.json"
    write_text = Path.write_text

    def full_for_the_report(self, *args, **kwargs):
        if self.name.startswith(f".{report.name}."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
        return write_text(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", full_for_the_report)
    args = ["fit-classes", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"],
            "--min-samples", 10, "--min-vza-spread", 1, "-o", table, "--report", report]
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, rf"cannot write .*{re.escape(str(report))}: No space left on device")
    assert list(scene["out"].iterdir()) == []


def test_run_report_on_a_full_disk(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2, ny=8, nx=8)
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}})
    assert CliRunner().invoke(main, ["run", str(chain), "--no-progress"]).exit_code == 0
    sizes = {path.name: path.stat().st_size for path in (tmp_path / "out").iterdir()}
    shutil.rmtree(tmp_path / "out")
    largest = max(size for name, size in sizes.items() if name.endswith(".tif"))
    assert sizes["run_report.json"] > largest + 200, sizes  # a limit between the rasters and the report
    before = file_digests(tmp_path / "scenes")
    run = _run(["run", chain, "--no-progress"], limit=largest + 100, cwd=tmp_path)
    assert run.returncode == 2, run.stderr
    _one_line(run.stderr, r"cannot write \S*run_report\.json: File too large")
    left = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert left == sorted(name for name in sizes if name.endswith(".tif")), left  # no report, lock, temporary
    assert file_digests(tmp_path / "scenes") == before


# ------------------------------------------------------------------ tile size (--chunk 100000)
def test_tile_size_is_no_larger_than_the_raster(tmp_path):
    """--chunk 100000 failed as "check the free space": GDAL allocates whole tiles, and one tile of
    100 000 x 100 000 pixels of 4 float32 bands is 1.6e11 bytes. The tile is now the raster's size
    rounded up to 16 (here 48 x 32 for a 40 x 20 raster)."""
    array = georeference(xr.DataArray(np.arange(4 * 20 * 40, dtype="float32").reshape(4, 20, 40),
                                      dims=("band", "y", "x")))
    target = tmp_path / "big_tiles.tif"
    write_rasters({target: array}, geotiff=GeoTiffOutput(blocksize=100_000))
    with rasterio.open(target) as written:
        assert written.block_shapes[0] == (32, 48)
        np.testing.assert_array_equal(written.read(), array.values)


def test_a_gdal_allocation_failure_is_not_blamed_on_the_disk(tmp_path, monkeypatch):
    """A failure GDAL only logs (rasterio raises nothing at close) fails the write, and an
    allocation failure (CPLE_OutOfMemory, 2) is named as such, not as a full disk."""
    close = rasterio.io.DatasetWriter.close

    def close_without_memory(self):
        logging.getLogger("rasterio._err").info("GDAL signalled an error: err_no=%r, msg=%r", 2,
                                                "cannot allocate 160000000000 bytes")
        return close(self)

    monkeypatch.setattr(rasterio.io.DatasetWriter, "close", close_without_memory)
    array = georeference(xr.DataArray(np.ones((1, 16, 16), "float32"), dims=("band", "y", "x")))
    with pytest.raises(OutputError) as raised:
        write_rasters({tmp_path / "t.tif": array})
    message = str(raised.value)
    assert "GDAL could not allocate memory: cannot allocate 160000000000 bytes" in message
    assert "free space" not in message and list(tmp_path.iterdir()) == []


def test_a_failure_inside_the_writing_block_leaves_nothing(tmp_path):
    """``writing`` around a caller that computes the pass itself (a correction): a failure in the
    caller's block, after the files were created, removes every temporary and writes no target."""
    from brdfcorr.io.writer import writing

    array = georeference(xr.DataArray(np.ones((2, 32, 32), np.float32), dims=("band", "y", "x")).chunk(16))
    targets = {tmp_path / "a.tif": array, tmp_path / "b.tif": array[0]}
    with pytest.raises(RuntimeError, match="the caller's computation failed"):
        with writing(targets, GeoTiffOutput(blocksize=16), scheduler="synchronous") as writes:
            assert len(writes) == 2 and list(tmp_path.iterdir())  # created under temporary names
            raise RuntimeError("the caller's computation failed")
    assert list(tmp_path.iterdir()) == []
    with writing(targets, GeoTiffOutput(blocksize=16), scheduler="synchronous") as writes:
        dask.compute(*writes, scheduler="synchronous")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["a.tif", "b.tif"]
    with rasterio.open(tmp_path / "a.tif") as written:
        assert written.count == 2 and (written.read() == 1).all()
