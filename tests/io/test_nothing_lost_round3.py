"""Nothing lost, round 3, the write side (issue 26): full disks, sidecar files, two runs at once.

Each case ends either in a correct result or in exit code 2 with exactly one stderr line
``brdfcorr: error: ...`` naming the file and the cause, no file at the target (not even a
temporary one) and the inputs byte-identical:

1. a full disk, stood in for by the file size limit (``RLIMIT_FSIZE`` in a subprocess, SIGXFSZ
   ignored so that writes fail with EFBIG, as they fail with ENOSPC on a full device): GeoTIFF and
   ENVI outputs, ``materials -o``, ``fit-classes -o``/``--report`` and the run report. GDAL reported
   such failures only in its log and rasterio raised nothing at close: files that read as NaN were
   reported as written, and libtiff printed its own lines on stderr;
2. the sidecars GDAL reads beside an input (an ENVI header in both namings, ``.aux.xml``) are inputs;
3. ``materials -o`` follows the overwrite rule of every output and keeps a symbolic link a link;
4. two runs of one chain exclude each other (a lock file with the holder's pid);
5. an ENVI output has one commit point: a process killed after its sidecars were renamed leaves
   no data file beside them, and the resumed chain redoes the scene;
9. an ENVI header cannot say "sheared" or "no CRS": refused, not written wrong;
11. the ENVI ``description`` names the output, not its temporary file, and a folder name with ``}``
    and a line break cannot add header fields;
and ``--chunk 100000``'s real cause: a GeoTIFF tile of 100 000 pixels square (160 GB to allocate for
4 bands of float32), now no larger than the raster.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine
from click.testing import CliRunner

from brdfcorr.chain import run as chain_module
from brdfcorr.chain.config import load_config
from brdfcorr.chain.plan import plan_run
from brdfcorr.chain.run import LOCK_NAME, run_lock
from brdfcorr.cli import main
from brdfcorr.errors import OutputError
from brdfcorr.io import commit
from brdfcorr.io.paths import InputOverwriteError, check_outputs
from brdfcorr.io.writer import GeoTiffOutput, write_rasters
from brdfcorr.params import ParameterTable
from brdfcorr.testing import file_digests, georeference

# The scene: a copy of the 32 x 32 template of tests/conftest.py, 4 bands of float32: 16 384 bytes of data.


def _correct_args(scene, output, *extra) -> list[str]:
    return ["correct", str(scene["image"]), "--angles", str(scene["angles"]), "--classes", str(scene["classes"]),
            "--params", str(scene["params"]), "-o", str(output), "--chunk", "16", "--no-progress", *map(str, extra)]


def _limited(limit: int):
    def preexec():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG
    return preexec


def _run(args, limit: int | None = None, cwd=None) -> subprocess.CompletedProcess:
    """``brdfcorr ARGS`` in a subprocess, under a file size limit [bytes] if given."""
    return subprocess.run([sys.executable, "-c", "from brdfcorr.cli import main; main()", *map(str, args)],
                          capture_output=True, text=True, timeout=120, cwd=cwd,
                          preexec_fn=None if limit is None else _limited(limit))


def _one_line(stderr: str, pattern: str) -> str:
    """stderr is exactly one ``brdfcorr: error:`` line (no libtiff or GDAL line) matching ``pattern``,
    after brdfcorr's own warnings (a fit's guard rails) if any."""
    lines = [line for line in stderr.splitlines() if not line.startswith("brdfcorr: warning: ")]
    assert len(lines) == 1, stderr
    assert lines[0].startswith("brdfcorr: error: ") and re.search(pattern, lines[0]), lines[0]
    return lines[0]


# ------------------------------------------------------------------------------ 1. full disks
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
    """The report's write fails with ENOSPC (the table before it is written): exit 2, one line."""
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
    _one_line(result.stderr, rf"cannot write {re.escape(str(report))}: No space left on device")
    assert sorted(p.name for p in scene["out"].iterdir()) == ["fitted.yaml"]


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


# --------------------------------------------------------------------- 2. sidecars are inputs
def _envi_input(scene, header_name: str) -> Path:
    """The scene's image as an ENVI file ``in.img`` with its header at ``header_name``."""
    image = scene["dir"] / "in.img"
    rasterio.shutil.copy(scene["image"], image, driver="ENVI")
    if header_name != "in.hdr":
        (scene["dir"] / "in.hdr").rename(scene["dir"] / header_name)
    return image


@pytest.mark.parametrize("header, output", [("in.img.hdr", "in.img.bsq"), ("in.hdr", "in.bsq")])
def test_envi_output_header_never_replaces_an_input_header(scene, header, output):
    """GDAL finds an ENVI header as NAME.hdr or NAME.ext.hdr; the output in.img.bsq writes in.img.hdr."""
    image = _envi_input(scene, header)
    with rasterio.open(image) as dataset:  # GDAL reads the header of either naming
        assert dataset.driver == "ENVI" and dataset.count == 4
    before = file_digests(scene["dir"])
    args = _correct_args({**scene, "image": image}, scene["dir"] / output, "--format", "ENVI")
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, rf"output header \S*{re.escape(header)} is also an input")
    assert file_digests(scene["dir"]) == before
    assert not (scene["dir"] / output).exists()


def test_report_on_an_input_aux_xml_is_refused(scene):
    aux = Path(f"{scene['image']}.aux.xml")
    aux.write_text('<PAMDataset><Metadata><MDI key="a">1</MDI></Metadata></PAMDataset>\n')
    before = file_digests(scene["dir"])
    args = ["fit-classes", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"],
            "-o", scene["out"] / "t.yaml", "--report", aux]
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, r"--report \S*image\.tif\.aux\.xml is also an input")
    assert file_digests(scene["dir"]) == before and list(scene["out"].iterdir()) == []


@pytest.mark.parametrize("suffix", [".hdr", ".aux.xml", ".ovr", ".msk"])
def test_guard_knows_every_sidecar(tmp_path, suffix):
    image = tmp_path / "image.img"
    image.write_bytes(b"\0")
    sidecar = Path(f"{image}{suffix}")
    sidecar.write_text("x")
    with pytest.raises(InputOverwriteError):
        check_outputs({"report": sidecar}, {"image": image})
    sidecar.unlink()  # absent: nothing to protect
    check_outputs({"report": sidecar}, {"image": image})


# ----------------------------------------------------------------------------- 3. materials -o
def test_materials_output_follows_the_overwrite_rule(tmp_path):
    table = tmp_path / "table.yaml"
    table.write_text("# my notes\nclasses:\n  - {id: 1, name: tiles, material: roof_tile}\n")
    before = table.read_bytes()
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(table)])
    assert result.exit_code == 2
    _one_line(result.stderr, rf"output {re.escape(str(table))} exists; give --overwrite")
    assert table.read_bytes() == before
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(table), "--overwrite"])
    assert result.exit_code == 0, result.output
    assert ParameterTable.load(table).class_ids == (1, 2)


def test_materials_output_keeps_a_symbolic_link_a_link(tmp_path):
    real = tmp_path / "tables" / "real.yaml"
    real.parent.mkdir()
    ParameterTable().with_class({"id": 1, "material": "roof_tile"}).save(real)
    link = tmp_path / "table.yaml"
    link.symlink_to(real)
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(link), "--overwrite"])
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and link.resolve() == real.resolve()
    assert ParameterTable.load(real).class_ids == (1, 2)
    dangling = tmp_path / "nothing.yaml"
    dangling.symlink_to(tmp_path / "missing.yaml")
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(dangling)])
    assert result.exit_code == 2
    _one_line(result.stderr, "is a symbolic link to no file")
    assert dangling.is_symlink() and not (tmp_path / "missing.yaml").exists()


# ------------------------------------------------------------------------ 4. one run at a time
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


# ---------------------------------------------------------------- 5. one commit point for ENVI
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


# ----------------------------------------------------------------------- 9, 11. ENVI headers
def _regrid(scene, transform: Affine, crs) -> None:
    """Rewrite the scene's image, angles and class map with another geotransform and CRS."""
    for key in ("image", "angles", "classes"):
        with rasterio.open(scene[key]) as source:
            profile, values, descriptions = source.profile, source.read(), source.descriptions
        profile.update(transform=transform, crs=crs)
        scene[key].unlink()
        with rasterio.open(scene[key], "w", **profile) as target:
            target.write(values)
            target.descriptions = descriptions


@pytest.mark.parametrize("transform, crs, pattern", [
    (Affine(10.0, 3.0, 500_000.0, 0.0, -10.0, 5_400_000.0), "EPSG:32632", "the image's geotransform is sheared"),
    (Affine(10.0, 0.0, 500_000.0, 0.0, -10.0, 5_400_000.0), None, "the image has no CRS"),
])
def test_envi_refuses_what_its_header_cannot_say(scene, transform, crs, pattern):
    _regrid(scene, transform, crs)
    output = scene["out"] / "c.img"
    before = file_digests(scene["dir"])
    result = CliRunner().invoke(main, _correct_args(scene, output, "--format", "ENVI"))
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, rf"ENVI output {re.escape(str(output))}: {pattern}")
    assert list(scene["out"].iterdir()) == [] and file_digests(scene["dir"]) == before
    # A GeoTIFF holds both as they are.
    result = CliRunner().invoke(main, _correct_args(scene, scene["out"] / "c.tif"))
    assert result.exit_code == 0, result.output
    with rasterio.open(scene["out"] / "c.tif") as written:
        assert written.transform == transform and written.crs == (crs and rasterio.crs.CRS.from_string(crs))


def _header_fields(path: Path) -> dict[str, str]:
    """An ENVI header's fields (``key = value``, a ``{...}`` value may span lines)."""
    text = path.read_text()
    assert text.startswith("ENVI\n")
    return {key.strip(): value.strip() for key, value in
            re.findall(r"^([^=\n{}]+?)\s*=\s*(\{[^}]*\}|[^\n]*)$", text[5:], flags=re.M)}


def test_envi_header_names_the_output_and_no_folder_adds_fields(scene):
    folder = scene["out"] / "x}\ndata gain values = {2, 2, 2, 2}"
    folder.mkdir()
    output = folder / "c.img"
    result = CliRunner().invoke(main, _correct_args(scene, output, "--format", "ENVI"))
    assert result.exit_code == 0, result.output
    fields = _header_fields(folder / "c.hdr")
    assert "data gain values" not in fields
    assert fields["description"] == "{\nbrdfcorr output c.img}" and "partial" not in fields["description"]
    assert fields["bands"] == "4" and fields["band names"] == "{\n480 nm,\n560 nm,\n660 nm,\n830 nm}"
    with rasterio.open(output) as envi, rasterio.open(scene["image"]) as image:
        assert envi.count == image.count == 4  # not doubled


# ------------------------------------------------------------------------------- --chunk 100000
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
