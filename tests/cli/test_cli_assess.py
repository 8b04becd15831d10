"""Tests of ``brdfcorr assess``: exit codes, the JSON report and figures reopened, the same numbers
as the library."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from brdfcorr.analysis.assess import ViewAngleOptions
from brdfcorr.cli import main
from brdfcorr.io.scene import SceneSources
from brdfcorr.tasks.assess import assess_files
from brdfcorr.tasks.correct import correct_files
from brdfcorr.tasks.request import CorrectionRequest, OutputFiles
from brdfcorr.testing import example_table, render, synthetic_scene, write_scene


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    directory = tmp_path_factory.mktemp("assess")
    scene = synthetic_scene(ny=40, nx=48)
    paths = write_scene(directory, scene)
    paths["scene"] = scene
    paths["after"] = directory / "corrected.tif"
    correct_files(CorrectionRequest(SceneSources(paths["image"], paths["classes"], paths["angles"]), example_table(),
                                    OutputFiles(paths["after"]), reference={"sza": "observed", "vza": 0.0}))
    return paths


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def _common(files):
    return [files["image"], files["after"], "--classes", files["classes"], "--angles", files["angles"]]


def test_assess_writes_the_library_report_and_figures(files, tmp_path):
    report_path, figures = tmp_path / "report.json", tmp_path / "figures"
    twin = tmp_path / "twin.tif"  # another line, identical to this one (the line itself is refused)
    twin.write_bytes(Path(files["image"]).read_bytes())
    result = _invoke("assess", *_common(files), "--class-name", "1=roof_tile", "--overlap", twin,
                     files["after"], "-o", report_path, "--figures", figures)
    assert result.exit_code == 0, result.output
    assert "roof_tile" in result.output and f"wrote {report_path}" in result.output
    report = json.loads(report_path.read_text())
    expected = assess_files(SceneSources(files["image"], files["classes"], files["angles"]), files["after"],
                            view_options=ViewAngleOptions(class_names={1: "roof_tile"}),
                            overlap=(twin, files["after"])).report()
    assert report["view_angles"] == json.loads(json.dumps(expected["view_angles"]))
    classes = {entry["id"]: entry for entry in report["view_angles"]["classes"]}
    assert classes[1]["name"] == "roof_tile" and classes[2]["name"] == "class 2"
    # The scene is rendered from the table it is corrected with, so the corrected image is the
    # scene rendered at nadir view: its slope is that of the albedo texture alone, computed here
    # independently (numpy polyfit of the nadir rendering against the signed view zenith).
    scene = files["scene"]
    angles = {name: scene[name].values for name in ("sza", "saa", "vza", "vaa")}
    nadir = render(example_table(), scene["classes"].values, angles["sza"], angles["saa"], 0 * angles["vza"],
                   angles["vaa"], wavelengths=list(scene["reflectance"]["wavelength"].values),
                   brightness=scene["brightness"].values)
    signed = np.where(angles["vaa"] == 270, 1.0, -1.0) * angles["vza"]  # sun at saa 150: vaa 270 is forward
    for class_id in (1, 2, 3, 4):
        mask = scene["classes"].values == class_id
        for band in range(4):
            slope = np.polyfit(signed[mask], nadir[band][mask], 1)[0]
            expected = 1000 * slope / nadir[band][mask].mean()
            assert classes[class_id]["after"]["relative_slope"][band] == pytest.approx(expected, rel=1e-3, abs=1e-4)
    # a line compared with its twin: the overlap differs by exactly 0
    assert report["inputs"]["overlap_before"] == str(twin)
    assert report["overlap"]["before"]["rmse"] == [0.0] * 4 and report["overlap"]["pixels"] > 0
    assert sorted(p.name for p in figures.iterdir()) == ["assess_overlap.png", "assess_profiles.png"]


def test_existing_outputs_inputs_and_bad_options_are_exit_2(files, tmp_path):
    report_path = tmp_path / "report.json"
    report_path.write_text("{}")
    result = _invoke("assess", *_common(files), "-o", report_path)
    assert result.exit_code == 2 and "exists; give --overwrite" in result.output
    assert report_path.read_text() == "{}"
    result = _invoke("assess", *_common(files), "-o", files["after"], "--overwrite")
    assert result.exit_code == 2 and "inputs are never overwritten" in result.output
    result = _invoke("assess", *_common(files), "-o", tmp_path / "r.json", "--sign-by", "track")
    assert result.exit_code == 2 and "--heading" in result.output
    result = _invoke("assess", files["image"], tmp_path / "missing.tif", "--classes", files["classes"],
                     "--angles", files["angles"], "-o", tmp_path / "r.json")
    assert result.exit_code == 2 and "missing.tif" in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "r.json").exists()


def test_sign_by_track_mirrors_sun_for_this_scene(files, tmp_path):
    # brdfcorr.testing's sun is at saa 150 (south-east): the pixels with vaa 270 see the sensor
    # opposite the sun (forward, + by sun) and lie right of a northbound track (+ by track).
    paths = [tmp_path / "sun.json", tmp_path / "track.json"]
    assert _invoke("assess", *_common(files), "-o", paths[0]).exit_code == 0
    assert _invoke("assess", *_common(files), "-o", paths[1], "--sign-by", "track", "--heading", "0").exit_code == 0
    sun, track = (json.loads(p.read_text())["view_angles"]["classes"] for p in paths)
    assert [c["before"]["slope"] for c in sun] == [c["before"]["slope"] for c in track]


@pytest.mark.parametrize("option, value", [("--block-size", str(2**63)), ("--block-size", str(2**20 + 1)),
                                           ("--bin-width", "1e-9")])
def test_sizes_that_would_overflow_or_exhaust_memory_are_one_line(files, tmp_path, option, value):
    """--block-size 2^63 overflowed a C long, --bin-width 1e-9 asked for 1.3 TiB of bin edges: both
    internal errors (issue 39). The library refuses them too."""
    output = tmp_path / "r.json"
    result = _invoke("assess", *_common(files), "-o", output, option, value)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("brdfcorr: error: ") and option in lines[0], result.stderr
    assert not output.exists()


@pytest.mark.parametrize("options, pattern", [({"block_size": 2**63}, "block size .* from 1 to 1048576"),
                                              ({"bin_width": 1e-9}, r"bin width 1e-09 deg must be in \[0\.01, 90\]")])
def test_the_library_refuses_the_same_sizes(files, options, pattern):
    from brdfcorr.analysis.view_angles import assess_view_angles
    from brdfcorr.errors import InputError

    scene = files["scene"]
    with pytest.raises(InputError, match=pattern):
        assess_view_angles(scene["reflectance"], scene["reflectance"], scene["classes"], scene["vza"], scene["vaa"],
                           scene["saa"], options=ViewAngleOptions(**options))


def test_an_after_image_of_nodata_only_is_one_line_not_an_empty_report(files, tmp_path):
    """An all-NaN AFTER gave an assessment of 0 pixels everywhere with exit 0 (issue 39)."""
    import rasterio

    after = tmp_path / "nan_after.tif"
    with rasterio.open(files["after"]) as dataset:
        profile, shape = dataset.profile, (dataset.count, dataset.height, dataset.width)
    with rasterio.open(after, "w", **profile) as dataset:
        dataset.write(np.full(shape, np.nan, dtype=profile["dtype"]))
    output = tmp_path / "r.json"
    result = _invoke("assess", files["image"], after, "--classes", files["classes"], "--angles", files["angles"],
                     "-o", output)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "nan_after.tif: nothing to assess" in lines[0] and not output.exists(), result.stderr


def test_a_figure_that_fails_leaves_no_report(files, tmp_path, monkeypatch):
    """The JSON report was written before the figures: a figure that failed left it behind, looking
    complete (issue 39). The report is now written last."""
    import brdfcorr.plot.assess
    from brdfcorr.errors import OutputError

    def failing(*args, **kwargs):
        raise OutputError("cannot write figure assess_profiles.png: No space left on device")

    monkeypatch.setattr(brdfcorr.plot.assess, "write_assessment_figures", failing)
    output = tmp_path / "r.json"
    result = _invoke("assess", *_common(files), "-o", output, "--figures", tmp_path / "figures")
    assert result.exit_code == 2, result.output
    assert "cannot write figure" in result.stderr and not output.exists()


def test_an_overlap_with_other_bands_is_refused_before_the_view_angle_pass(files, tmp_path, monkeypatch):
    # The other line's band count was found by the overlap, after the whole view-angle pass.
    import rasterio

    three = tmp_path / "three_bands.tif"
    with rasterio.open(files["image"]) as source:
        with rasterio.open(three, "w", **{**source.profile, "count": 3}) as target:
            target.write(source.read([1, 2, 3]))
    passes = []
    monkeypatch.setattr("brdfcorr.tasks.assess.assess_view_angles", lambda *a, **k: passes.append(1))
    output = tmp_path / "r.json"
    result = CliRunner().invoke(main, [str(a) for a in ("assess", *_common(files), "--overlap", three, files["after"],
                                                        "-o", output)])
    assert result.exit_code == 2, result.output
    assert f"{three} has 3 bands, {files['image']} has 4" in result.stderr.splitlines()[-1]
    assert passes == [] and not output.exists()
    # The line itself as the other line (a typo): its overlap would agree to 0.00 %.
    result = CliRunner().invoke(main, [str(a) for a in ("assess", *_common(files), "--overlap", files["image"],
                                                        files["after"], "-o", output)])
    assert result.exit_code == 2, result.output
    assert "is the assessed image itself" in result.stderr.splitlines()[-1]
    assert passes == [] and not output.exists()


def _reordered(source_path, target_path, order, *, tag: bool):
    """A copy of a raster with its bands (and their descriptions) in ``order`` (1-based), its
    ``wavelength`` tag rewritten to match with ``tag``, else copied as it was (as gdal_translate
    -b ... copies a dataset's tags)."""
    import rasterio

    with rasterio.open(source_path) as source:
        profile, tags, descriptions = source.profile, source.tags(), source.descriptions
        values = source.read(order)
    if tag and "wavelength" in tags:
        centres = tags["wavelength"].split(",")
        tags["wavelength"] = ",".join(centres[index - 1] for index in order)
    with rasterio.open(target_path, "w", **profile) as target:
        target.write(values)
        target.update_tags(**tags)
        target.descriptions = tuple(descriptions[index - 1] for index in order)
    return target_path


def test_a_corrected_image_with_its_bands_in_another_order_is_read_by_wavelength(files, tmp_path):
    """The corrected image's bands were paired with the input's by position: a file whose bands
    are stored in another order compared each band of the input with another band."""
    canonical, reordered = tmp_path / "canonical.json", tmp_path / "reordered.json"
    assert _invoke("assess", *_common(files), "-o", canonical).exit_code == 0
    shuffled = _reordered(files["after"], tmp_path / "shuffled.tif", [3, 1, 4, 2], tag=True)
    arguments = [files["image"], shuffled, "--classes", files["classes"], "--angles", files["angles"]]
    assert _invoke("assess", *arguments, "-o", reordered).exit_code == 0
    expected, found = (json.loads(path.read_text()) for path in (canonical, reordered))
    expected.pop("inputs"), found.pop("inputs")
    assert found == expected
    # The bands reordered, the tag copied as it was: the file contradicts itself.
    stale = _reordered(files["after"], tmp_path / "stale.tif", [3, 1, 4, 2], tag=False)
    result = CliRunner().invoke(main, [str(a) for a in ("assess", files["image"], stale, *_common(files)[2:], "-o",
                                                        tmp_path / "stale.json")])
    assert result.exit_code == 2, result.output
    assert "tag 'wavelength' says 480, 560, 660, 830 nm and the band descriptions 660, 480, 830, 560 nm" in \
        result.stderr.splitlines()[-1]
