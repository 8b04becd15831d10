"""The output guard: no command writes over a file it reads, two outputs on one file, or a device;
chains keep the user's paths; a resume redoes what is stale and only that.

Every refused case checks, as :mod:`test_bad_input` does: exit code 2, one stderr line
``brdfcorr: error: ...`` naming the output and the input, every file byte-identical afterwards
(SHA-256 of every file) and no new file (not even a temporary one). Chains run on the demo (the
measured cases of issue 14) and on the scenes of :mod:`test_pipeline`.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import stat
import tempfile
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdfcorr.chain.config import load_config
from brdfcorr.chain.demo import run_demo
from brdfcorr.chain.plan import plan_run
from brdfcorr.chain.run import run_chain
from brdfcorr.cli import main
from brdfcorr.errors import InputError, OutputError
from brdfcorr.io.paths import InputOverwriteError, SameOutputError, check_outputs, remove_partials


# ------------------------------------------------------------------------------------- helpers
def _digests(directory: Path) -> dict[str, str]:
    """SHA-256 of every file under ``directory`` (links followed), by relative path."""
    return {str(path.relative_to(directory)): hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(directory.rglob("*")) if path.is_file()}


def _listing(directory: Path) -> list[str]:
    """Every name under ``directory``, files, links and folders (a temporary file shows here)."""
    return sorted(str(path.relative_to(directory)) for path in directory.rglob("*"))


def _one_error_line(result) -> str:
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("brdfcorr: error: "), lines[0]
    assert "Traceback" not in result.output
    return lines[0]


def _refused(root: Path, args: list, pattern: str) -> str:
    """Run the command line; it must be refused (exit 2, one line matching ``pattern``) and leave
    every file under ``root`` as it was."""
    before, names = _digests(root), _listing(root)
    result = CliRunner().invoke(main, [str(arg) for arg in args])
    line = _one_error_line(result)
    assert re.search(pattern, line), line
    assert _digests(root) == before, "no file may change"
    assert _listing(root) == names, "nothing may be written, not even a temporary file"
    return line


# ------------------------------------------------------------------------- chains: the demo
def _demo(directory: Path) -> Path:
    """A small demo output: demo.yaml, scene/line01_{image,angles,classes}.tif, corrected/ (made
    here, not copied: the outputs' fingerprints hold the inputs' paths)."""
    assert run_demo(directory, rows=40, pixel=16.0, materials_figure=False).report.ok
    return directory


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> Path:
    """The demo output, made once for the tests that only read it or are refused: a refusal
    changes and writes nothing (``_refused`` checks every file and name under it)."""
    return _demo(tmp_path_factory.mktemp("shared") / "demo")


@pytest.fixture
def own_demo(tmp_path) -> Path:
    """A demo output of the test's own, for a test that adds a file to it."""
    return _demo(tmp_path / "demo")


def test_demo_reruns_skip_everything(demo):
    """The setting of the measured cases: a rerun of the demo chain skips its one scene."""
    plan = plan_run(load_config(demo / "demo.yaml"))
    assert [scene.action for scene in plan.scenes] == ["skip"], plan.scenes


DEMO_CASES = {
    "report is the angle raster": (
        ["--set", "outputs.report=../scene/line01_angles.tif"],
        r"demo\.yaml: outputs\.report \S*corrected/\.\./scene/line01_angles\.tif would overwrite an input "
        r"\(the same file as the angles of scene line01 \S*scene/line01_angles\.tif\)$"),
    "report is the chain config (every scene skipped)": (
        ["--set", "outputs.report=../demo.yaml"],
        r"demo\.yaml: outputs\.report \S*corrected/\.\./demo\.yaml would overwrite an input "
        r"\(the same file as the chain config \S*demo\.yaml\)$"),
    "report is the corrected image": (
        ["--set", "outputs.report=line01_brdf.tif"],
        r"demo\.yaml: outputs: corrected output \S*corrected/line01_brdf\.tif of scene line01 and "
        r"outputs\.report \S*corrected/line01_brdf\.tif are the same file"),
    "fitted table is the class map": (
        ["--set", "steps.fit.source=imagery", "--set", "steps.fit.output=../scene/line01_classes.tif"],
        r"demo\.yaml: steps\.fit\.output \S*line01_classes\.tif would overwrite an input \(the same file as "
        r"the class map of scene line01 \S*scene/line01_classes\.tif\)$"),
    "report is the image, by an absolute path": (
        ["--set", "outputs.report={demo}/scene/line01_image.tif"],
        r"outputs\.report \S*scene/line01_image\.tif would overwrite an input \(the same file as the image "
        r"of scene line01"),
    # An output folder the run has not made yet, left again by "..": the path names the input
    # as soon as the folder exists (issue 39: the image became the run report, exit 0).
    "report through an output folder not made yet is the image": (
        ["--set", "outputs.directory=new/deeper", "--set", "outputs.report=../../scene/line01_image.tif"],
        r"demo\.yaml: outputs\.report \S*new/deeper/\.\./\.\./scene/line01_image\.tif would overwrite an "
        r"input \(the same file as the image of scene line01 \S*scene/line01_image\.tif\)$"),
    "report through an output folder not made yet is the chain config": (
        ["--set", "outputs.directory=new/deeper", "--set", "outputs.report=../../demo.yaml"],
        r"demo\.yaml: outputs\.report \S*new/deeper/\.\./\.\./demo\.yaml would overwrite an input "
        r"\(the same file as the chain config \S*demo\.yaml\)$"),
    "fitted table through an output folder not made yet is the class map": (
        ["--set", "outputs.directory=new/deeper", "--set", "steps.fit.source=imagery",
         "--set", "steps.fit.output=../../scene/line01_classes.tif", "--overwrite"],
        r"demo\.yaml: steps\.fit\.output \S*line01_classes\.tif would overwrite an input \(the same file as "
        r"the class map of scene line01 \S*scene/line01_classes\.tif\)$"),
    # An ENVI output's header is an output too: the report written over it left the image headerless.
    "report is the ENVI header of the corrected image": (
        ["--set", "outputs.format=ENVI", "--set", "outputs.naming='{scene}_brdf.img'", "--set",
         "outputs.report=line01_brdf.hdr"],
        r"demo\.yaml: outputs: corrected output's sidecar \S*corrected/line01_brdf\.hdr of scene line01 and "
        r"outputs\.report \S*corrected/line01_brdf\.hdr are the same file"),
    "QA naming equal to the corrected naming": (
        ["--set", "outputs.qa_naming='{scene}_brdf.tif'"],
        r"demo\.yaml: outputs: corrected output \S*corrected/line01_brdf\.tif of scene line01 and outputs: qa "
        r"output \S*corrected/line01_brdf\.tif of scene line01 are the same file"),
}


@pytest.mark.parametrize("case", list(DEMO_CASES))
@pytest.mark.parametrize("dry_run", [False, True])
def test_chain_outputs_never_replace_an_input_or_each_other(demo, case, dry_run):
    options, pattern = DEMO_CASES[case]
    options = [option.replace("{demo}", str(demo)) for option in options]
    _refused(demo, ["run", demo / "demo.yaml", "--no-progress", *options, *(["--dry-run"] if dry_run else [])],
             pattern)


def test_chain_report_on_a_hard_link_of_an_input(own_demo):
    demo = own_demo
    os.link(demo / "scene" / "line01_angles.tif", demo / "corrected" / "linked.json")
    _refused(demo, ["run", demo / "demo.yaml", "--set", "outputs.report=linked.json"],
             r"outputs\.report \S*corrected/linked\.json would overwrite an input \(the same file as the angles "
             r"of scene line01 \S*scene/line01_angles\.tif\)$")


def test_chain_output_on_a_symbolic_link_to_the_parameter_table(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "run_report.json").symlink_to(tmp_path / "params.yaml")
    _refused(tmp_path, ["run", chain], r"outputs\.report \S*out/run_report\.json would overwrite an input "
                                       r"\(the same file as parameters\.table \S*params\.yaml\)$")


def test_chain_output_that_is_a_directory(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    (tmp_path / "out" / "run_report.json").mkdir(parents=True)
    _refused(tmp_path, ["run", chain], r"chain\.yaml: outputs\.report \S*run_report\.json is a directory, "
                                       r"not a regular file")


# ------------------------------------------------------------------------ brdfcorr correct
@pytest.fixture
def scene(scene) -> dict[str, Path]:
    """The copy of the 32 x 32 template scene (tests/conftest.py) with a class lookup table beside it,
    and the folder holding both the scene and the output folder as ``root``."""
    lookup = scene["dir"] / "lookup.yaml"
    lookup.write_text("1: 1\n2: 2\n3: 3\n4: 4\n")
    return {**scene, "lookup": lookup, "root": scene["dir"].parent}


def _correct(scene, output, *extra) -> list:
    return ["correct", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"],
            "--params", scene["params"], "-o", output, "--chunk", 16, *extra]


def test_correct_output_is_the_parameter_table(scene):
    _refused(scene["root"], _correct(scene, scene["params"], "--overwrite"),
             r"output \S*params\.yaml is also an input; inputs are never overwritten "
             r"\(the same file as --params \S*params\.yaml\)$")


def test_correct_output_is_the_class_lookup_table(scene):
    _refused(scene["root"], _correct(scene, scene["lookup"], "--overwrite", "--class-lookup", scene["lookup"]),
             r"output \S*lookup\.yaml is also an input; .*\(the same file as --class-lookup \S*lookup\.yaml\)$")


def test_correct_output_and_qa_on_one_file(scene):
    target = scene["out"] / "both.tif"
    _refused(scene["root"], _correct(scene, target, "--qa", target),
             r"output \S*out/both\.tif and QA output \S*out/both\.tif are the same file")


def test_correct_output_and_qa_on_one_file_through_a_link(scene):
    target = scene["out"] / "both.tif"
    (scene["out"] / "qa.tif").symlink_to(target)
    _refused(scene["root"], _correct(scene, target, "--qa", scene["out"] / "qa.tif"),
             r"output \S*out/both\.tif and QA output \S*out/qa\.tif are the same file")


def test_correct_output_is_a_hard_link_of_the_image(scene):
    os.link(scene["image"], scene["out"] / "linked.tif")
    _refused(scene["root"], _correct(scene, scene["out"] / "linked.tif", "--overwrite"),
             r"output \S*out/linked\.tif is also an input; inputs are never overwritten "
             r"\(the same file as image \S*scene/image\.tif\)$")


def test_qa_output_is_a_link_to_the_class_map(scene):
    (scene["out"] / "qa.tif").symlink_to(scene["classes"])
    _refused(scene["root"], _correct(scene, scene["out"] / "c.tif", "--overwrite", "--qa", scene["out"] / "qa.tif"),
             r"QA output \S*out/qa\.tif is also an input; .*\(the same file as class map \S*scene/classes\.tif\)$")


def test_correct_output_is_a_character_device(scene):
    """As root, a device node given as output would be replaced by a file: refused (a node made
    here, never one of /dev)."""
    device = scene["out"] / "device"
    try:
        os.mknod(device, stat.S_IFCHR | 0o600, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("making a device node needs root")
    _refused(scene["root"], _correct(scene, device, "--overwrite"),
             r"output \S*out/device is a character device, not a regular file")
    assert stat.S_ISCHR(os.stat(device).st_mode)


def test_correct_output_is_no_regular_file(scene):
    os.mkfifo(scene["out"] / "fifo")
    _refused(scene["root"], _correct(scene, scene["out"] / "fifo", "--overwrite"),
             r"output \S*out/fifo is a FIFO, not a regular file")
    (scene["out"] / "folder").mkdir()  # refused by the option itself
    _refused(scene["root"], _correct(scene, scene["out"] / "folder", "--overwrite"), r"out/folder' is a directory")


# ------------------------------------------------------------------- fit, fit-classes, classes
def test_fit_classes_table_and_report_on_one_file(scene):
    target = scene["out"] / "fit.yaml"
    _refused(scene["root"], ["fit-classes", scene["image"], "--angles", scene["angles"], "--classes",
                             scene["classes"], "-o", target, "--report", target],
             r"-o \S*out/fit\.yaml and --report \S*out/fit\.yaml are the same file")


def test_fit_classes_report_is_the_class_lookup(scene):
    _refused(scene["root"], ["fit-classes", scene["image"], "--angles", scene["angles"], "--classes",
                             scene["classes"], "--class-lookup", scene["lookup"], "-o", scene["out"] / "fit.yaml",
                             "--report", scene["lookup"]],
             r"--report \S*lookup\.yaml is also an input; .*\(the same file as --class-lookup \S*lookup\.yaml\)$")


def test_fit_table_is_one_of_its_figures(scene):
    from brdfcorr.fit.measurements import write_measurements
    from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
    from brdfcorr.models.materials import load_material

    tile = load_material("roof_tile")
    measurements = scene["root"] / "scene" / "tile.csv"
    write_measurements(measurements, synthesize_measurements(tile.model, tile.params, *goniometer_angles(),
                                                             relative_noise=0.01, seed=1))
    figures = scene["out"] / "figures"
    _refused(scene["root"], ["fit", measurements, "--fix", "k=0.25", "--plot-dir", figures,
                             "-o", figures / "tile_azimuth.png"],
             r"-o \S*figures/tile_azimuth\.png and --plot-dir file \S*figures/tile_azimuth\.png are the same file")


def test_classes_ndvi_output_is_a_hard_link_of_the_image(scene):
    os.link(scene["image"], scene["out"] / "classes.tif")
    _refused(scene["root"], ["classes", "ndvi", scene["image"], "-o", scene["out"] / "classes.tif", "--overwrite"],
             r"output \S*out/classes\.tif is also an input; .*\(the same file as image \S*scene/image\.tif\)$")


def test_classes_align_output_is_the_lookup(scene):
    _refused(scene["root"], ["classes", "align", scene["classes"], "--like", scene["image"], "--lookup",
                             scene["lookup"], "-o", scene["lookup"], "--overwrite"],
             r"output \S*lookup\.yaml is also an input; .*\(the same file as --lookup \S*lookup\.yaml\)$")


# ---------------------------------------------------------------------- the guard, property
@st.composite
def aliasing(draw):
    """3 inputs and 2 outputs, each output a new file, an unrelated existing file, or an input
    (the same path, another spelling, a symbolic or a hard link); the second output possibly the
    first (the same path or a link to it). Inputs 1 and 2 may be links of input 0."""
    inputs = [draw(st.sampled_from(["file", "symlink", "hardlink"])) if index else "file" for index in range(3)]
    kinds = ["new", "existing", "same", "spelled", "symlink", "hardlink"]
    first = (draw(st.sampled_from(kinds)), draw(st.integers(0, 2)))
    second = (draw(st.sampled_from([*kinds, "first", "link to first"])), draw(st.integers(0, 2)))
    return inputs, [first, second]


def _build(root: Path, inputs, outputs):
    """The paths, and what file each is (an index of an input's file, or an output's own)."""
    (root / "sub").mkdir()
    paths, files = [], []
    for index, kind in enumerate(inputs):
        path = root / f"input{index}.dat"
        if kind == "file":
            path.write_text(f"input {index}")
        elif kind == "symlink":
            path.symlink_to(paths[0])
        else:
            os.link(paths[0], path)
        paths.append(path)
        files.append(files[0] if kind != "file" else ("input", index))
    targets, owners = [], []
    for index, (kind, which) in enumerate(outputs):
        path = root / f"output{index}.dat"
        owner = ("input", which) if kind in ("same", "spelled", "symlink", "hardlink") else ("output", index)
        if kind in ("same", "spelled", "symlink", "hardlink"):
            owner = files[which]
        if kind == "existing":
            path.write_text("an earlier result")
        elif kind == "same":
            path = paths[which]
        elif kind == "spelled":
            path = root / "sub" / ".." / paths[which].name
        elif kind == "symlink":
            path.symlink_to(paths[which])
        elif kind == "hardlink":
            os.link(paths[which], path)
        elif kind == "first":
            path, owner = targets[0], owners[0]
        elif kind == "link to first":
            path.symlink_to(targets[0])
            owner = owners[0]
        targets.append(path)
        owners.append(owner)
    return paths, files, targets, owners


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(aliasing())
def test_guard_refuses_exactly_when_an_output_is_an_input_or_the_other_output(case):
    inputs, outputs = case
    with tempfile.TemporaryDirectory() as directory:
        paths, files, targets, owners = _build(Path(directory), inputs, outputs)
        overwrites_input = any(owner in files for owner in owners)
        expected = InputOverwriteError if overwrites_input else SameOutputError if owners[0] == owners[1] else None
        contents = {path: path.read_bytes() for path in paths}
        named = {"first": targets[0], "second": targets[1]}
        if expected is None:
            check_outputs(named, paths)
        else:
            with pytest.raises(expected):
                check_outputs(named, paths)
        assert {path: path.read_bytes() for path in paths} == contents


def test_guard_on_devices_and_missing_paths(tmp_path):
    with pytest.raises(OutputError, match="/dev/null is a character device"):
        check_outputs({"output": "/dev/null"}, [])
    with pytest.raises(SameOutputError, match="are the same file"):  # neither exists: the resolved paths
        check_outputs([("a", tmp_path / "x.tif"), ("b", tmp_path / "sub" / ".." / "x.tif")])
    check_outputs([("a", tmp_path / "x.tif")], [tmp_path / "y.tif", None])
    with pytest.raises(InputError, match=r"output \S*x\.tif is also an input"):
        check_outputs({"output": tmp_path / "x.tif"}, [tmp_path / "x.tif"])


def test_guard_follows_dot_dot_through_folders_not_made_yet(tmp_path):
    """An output whose path runs through a folder that does not exist yet and leaves it by ``..``
    is the file it names once the folder is made: an input, another output, or a directory."""
    image = tmp_path / "in" / "image.tif"
    image.parent.mkdir()
    image.write_bytes(b"input")
    (tmp_path / "link").symlink_to(tmp_path / "in", target_is_directory=True)
    through = tmp_path / "out" / "new" / ".." / ".." / "in" / "image.tif"
    with pytest.raises(InputOverwriteError, match=r"report \S*out/new/\.\./\.\./in/image\.tif is also an input"):
        check_outputs({"report": through}, {"image": image})
    with pytest.raises(InputOverwriteError):  # a link on the way, then a folder not made yet
        check_outputs({"report": tmp_path / "link" / "new" / ".." / "image.tif"}, {"image": image})
    with pytest.raises(OutputError, match="is a directory"):
        check_outputs({"report": tmp_path / "out" / "new" / ".." / ".." / "in"}, [])
    check_outputs({"report": tmp_path / "out" / "new" / ".." / "report.json"}, {"image": image})
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- paths as given
def test_scene_given_as_a_link_reads_the_files_beside_the_link(tmp_path, make_scenes, write_chain, read):
    """``{dir}`` of an image given as a symbolic link is the link's directory: its class map and
    angles are the ones beside the link, and the messages show the link's path."""
    scenes = make_scenes(tmp_path, count=1)
    source = scenes["line0"][1]
    links = tmp_path / "links" / "line0"
    links.mkdir(parents=True)
    (links / "image.tif").symlink_to(source["image"])
    shutil.copy(source["angles"], links / "angles.tif")
    with rasterio.open(source["classes"]) as dataset:
        profile, classes = dataset.profile, dataset.read()
    with rasterio.open(links / "classes.tif", "w", **profile) as dataset:
        dataset.write(np.zeros_like(classes))  # no class anywhere: the image is left as it is
    # no pixel corrected is expected here: said with min_corrected_share 0 (else the scene fails)
    chain = write_chain(tmp_path, inputs={"images": ["links/*/image.tif"], "classes": "{dir}/classes.tif",
                                          "angles": {"kind": "geotiff", "path": "{dir}/angles.tif"}},
                        steps={"correct": {"limits": None, "min_corrected_share": 0}})
    plan = plan_run(load_config(chain))
    (planned,) = plan.scenes
    assert planned.image == links / "image.tif" and planned.classes == links / "classes.tif"
    assert planned.angles == str(links / "angles.tif")
    result = CliRunner().invoke(main, ["run", str(chain), "--dry-run"])
    assert str(links / "image.tif") in result.output and str(source["image"]) not in result.output
    report = run_chain(load_config(chain))
    assert report.ok and report.scenes[0]["qa"]["no_class"] == 32 * 48
    np.testing.assert_array_equal(read(tmp_path / "out" / "line0_brdf.tif")[0], read(source["image"])[0])


# ---------------------------------------------------------------------------------- resume
def _actions(chain, *options) -> tuple[dict[str, str], dict[str, str], str]:
    """What ``brdfcorr run --dry-run`` shows, then what the run does: ({scene: action},
    {scene: status}, dry-run output)."""
    dry = CliRunner().invoke(main, ["run", str(chain), "--dry-run", *options])
    assert dry.exit_code == 0, dry.output
    planned = {line.split()[0]: line.split()[1] for line in dry.output.splitlines() if line.startswith("line")}
    done = CliRunner().invoke(main, ["run", str(chain), "--no-progress", *options])
    assert done.exit_code == 0, done.output
    status = {line.split()[0]: line.split()[1] for line in done.output.splitlines() if line.startswith("line")}
    assert {name: {"run": "ok", "skip": "skipped"}[action] for name, action in planned.items()} == status
    return planned, status, dry.output


def test_resume_redoes_what_changed_and_skips_the_rest(tmp_path, make_scenes, write_chain, read):
    scenes = make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    out = tmp_path / "out"
    assert run_chain(load_config(chain)).ok
    stamps = {name: (out / f"{name}_brdf.tif").stat().st_mtime_ns for name in scenes}

    planned, _, _ = _actions(chain)  # nothing changed: both skip, nothing is rewritten
    assert planned == {"line0_image": "skip", "line1_image": "skip"}
    assert {name: (out / f"{name}_brdf.tif").stat().st_mtime_ns for name in scenes} == stamps

    # Another reference geometry: every scene is redone, and says why.
    planned, _, output = _actions(chain, "--set", "reference.sza=40")
    assert planned == {"line0_image": "run", "line1_image": "run"} and "reference geometry changed" in output
    assert read(out / "line0_brdf.tif")[1]["brdf_reference"] == "sza=40 vza=0 raa=0"
    planned, _, _ = _actions(chain, "--set", "reference.sza=40")
    assert planned == {"line0_image": "skip", "line1_image": "skip"}

    # The input image of one scene touched: that scene only.
    stamps = {name: (out / f"{name}_brdf.tif").stat().st_mtime_ns for name in scenes}
    image = scenes["line0"][1]["image"]
    os.utime(image, ns=(image.stat().st_atime_ns, image.stat().st_mtime_ns + 10**9))
    planned, _, output = _actions(chain, "--set", "reference.sza=40")
    assert planned == {"line0_image": "run", "line1_image": "skip"}
    assert f"image {image} changed since it was written" in output
    assert (out / "line0_brdf.tif").stat().st_mtime_ns != stamps["line0"]
    assert (out / "line1_brdf.tif").stat().st_mtime_ns == stamps["line1"]

    # Other limits: redone, naming the setting.
    planned, _, output = _actions(chain, "--set", "reference.sza=40", "--set", "steps.correct.limits=[0.5, 2]")
    assert planned == {"line0_image": "run", "line1_image": "run"} and "steps.correct.limits changed" in output


def test_resume_redoes_a_scene_whose_assessment_settings_changed(tmp_path, make_scenes, write_chain):
    # The assessment is an output of the scene: before, a rerun with another min_vza skipped the
    # scene and kept the assessment of the old settings beside a report that recorded the new ones.
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}, "assess": {}})
    assert run_chain(load_config(chain)).ok
    planned, _, _ = _actions(chain)
    assert planned == {"line0_image": "skip", "line1_image": "skip"}
    planned, _, output = _actions(chain, "--set", "steps.assess.min_vza=20")
    assert planned == {"line0_image": "run", "line1_image": "run"}
    assert "steps.assess changed since it was written" in output
    written = json.loads((tmp_path / "out" / "line0_image_assess.json").read_text())
    assert json.dumps(written).count('"min_vza": 20.0') >= 1


def test_resume_redoes_an_input_edited_in_place_with_its_size_and_time(tmp_path, make_scenes, write_chain):
    """The fingerprint held path, size and mtime only: an edit that kept both kept a stale output
    (issue 39). It holds the content's digest too."""
    scenes = make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    image = scenes["line0"][1]["image"]
    with rasterio.open(image) as dataset:  # uncompressed: an edit of a pixel keeps the file's size
        profile, data, tags, descriptions = dataset.profile, dataset.read(), dataset.tags(), dataset.descriptions
    with rasterio.open(image, "w", **{**profile, "compress": None}) as dataset:
        dataset.write(data)
        dataset.update_tags(**tags)
        dataset.descriptions = descriptions
    assert run_chain(load_config(chain)).ok
    status = image.stat()
    with rasterio.open(image, "r+") as dataset:  # one pixel of the first band, in place
        band = dataset.read(1)
        band[3, 3] += 0.01
        dataset.write(band, 1)
    os.utime(image, ns=(status.st_atime_ns, status.st_mtime_ns))
    assert (image.stat().st_size, image.stat().st_mtime_ns) == (status.st_size, status.st_mtime_ns)
    planned, _, output = _actions(chain)
    assert planned == {"line0_image": "run", "line1_image": "skip"}
    assert f"image {image} changed since it was written" in output


@pytest.mark.parametrize("role", ["brdf", "qa"])
def test_resume_redoes_an_output_cut_short(tmp_path, make_scenes, write_chain, role):
    """An output cut to half its size after the run was "skipped, complete outputs exist" with exit
    0, and unreadable (issue 39): a skipped output is reopened and checked as a fresh write is."""
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    assert run_chain(load_config(chain)).ok
    damaged = tmp_path / "out" / f"line0_{role}.tif"
    os.truncate(damaged, damaged.stat().st_size // 2)
    planned, _, output = _actions(chain)
    assert planned == {"line0_image": "run", "line1_image": "skip"}
    assert re.search(rf"line0_{role}\.tif is damaged \(tile \(\d+, \d+\) of band \d+ ends beyond the file", output), output
    with rasterio.open(damaged) as dataset:  # whole again
        assert np.isfinite(dataset.read()).any()


def test_fingerprint_is_recorded_with_its_digest(tmp_path, make_scenes, write_chain, read):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    plan = plan_run(load_config(chain))
    assert run_chain(load_config(chain), plan=plan).ok
    tags = read(tmp_path / "out" / "line0_brdf.tif")[1]
    assert tags["brdf_fingerprint_content"] == plan.scenes[0].fingerprint
    assert tags["brdf_fingerprint"] == hashlib.sha256(plan.scenes[0].fingerprint.encode()).hexdigest()
    # Only in the output renamed last (issue 26): a QA file committed before it never vouches for it.
    assert "brdf_fingerprint" not in read(tmp_path / "out" / "line0_qa.tif")[1]


def test_resume_removes_partial_files_of_its_outputs_only(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    stale = [out / ".line0_brdf.tif.k3j_x9q2.partial", out / ".run_report.json.abcd1234.partial",
             out / ".line0_qa.tif.zz00zz00.partial.gtiff"]
    kept = [out / ".line0_brdf.tif.notes", out / ".other.tif.abcd1234.partial", out / "line0_brdf.tif.partial"]
    for path in stale + kept:
        path.write_text("left by an interrupted run")
    assert run_chain(load_config(chain)).ok
    assert not any(path.exists() for path in stale) and all(path.exists() for path in kept)
    assert remove_partials(out / "line0_brdf.tif") == []


def test_resume_skips_only_what_the_earlier_report_vouches_for(tmp_path, make_scenes, write_chain, read):
    """A skipped scene reports the QA counts of the run that wrote its outputs, and is judged by
    them; the report records each scene's fingerprint and outputs, and a scene whose earlier
    report does not describe its outputs is redone. Before: a scene failed for its share of
    corrected pixels kept its uncorrected output and passed once the report was gone; a QA
    raster of other limits stayed beside a corrected image of new ones; a run killed after
    rewriting a scene left the counts of the run before it."""
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path, steps={"correct": {"limits": [0.2, 5.0]}})
    out, report = tmp_path / "out", tmp_path / "out" / "run_report.json"
    assert run_chain(load_config(chain)).ok
    recorded = {scene["scene"]: scene["fingerprint"] for scene in json.loads(report.read_text())["scenes"]}
    assert recorded["line0_image"] == read(out / "line0_brdf.tif")[1]["brdf_fingerprint"]

    # The report gone: no run vouches for the outputs, so they are made again.
    report.unlink()
    planned, _, output = _actions(chain)
    assert planned == {"line0_image": "run", "line1_image": "run"}
    assert "no earlier run report vouches for its outputs: redone" in output

    # A run without QA rewrites the corrected images with new limits and leaves the old QA rasters.
    narrow = ("--set", "steps.correct.limits=[0.999, 1.001]")
    planned, _, _ = _actions(chain, *narrow, "--set", "steps.correct.qa=false")
    assert planned == {"line0_image": "run", "line1_image": "run"}
    assert read(out / "line0_qa.tif")[1]["brdf_limits"] == "0.2,5"
    planned, _, output = _actions(chain, *narrow)
    assert planned == {"line0_image": "run", "line1_image": "run"}
    assert "the earlier run did not write its qa output: redone" in output
    assert read(out / "line0_qa.tif")[1]["brdf_limits"] == "0.999,1.001"

    # A run killed after rewriting its scenes: their outputs are new, the report is the run's before.
    kept = report.read_text()
    wide = ("--set", "steps.correct.limits=[0.5, 2]")
    assert CliRunner().invoke(main, ["run", str(chain), "--no-progress", *wide]).exit_code == 0
    report.write_text(kept)
    planned, _, output = _actions(chain, *wide)
    assert planned == {"line0_image": "run", "line1_image": "run"}
    assert "its outputs are not those the earlier run report describes: redone" in output
