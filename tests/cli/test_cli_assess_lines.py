"""Tests of ``brdfcorr assess-lines`` and :func:`brdfcorr.tasks.assess.leave_one_line_out_files`:
three overlapping lines rendered with a known kernel model (``make_lines`` of tests/conftest.py),
written as GeoTIFFs; the CLI's JSON equals the library's numbers, the held-out slopes fall."""

from __future__ import annotations

import json
import shutil
import warnings

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.analysis.assess import HoldoutFit, ViewAngleOptions, leave_one_line_out, leave_one_line_out_report
from brdfcorr.cli import main
from brdfcorr.errors import InputError
from brdfcorr.io.scene import SceneSources
from brdfcorr.tasks.assess import leave_one_line_out_files
from brdfcorr.testing import write_scene

NAMES = {1: "grass", 2: "soil"}
REFERENCE = {"sza": 35.0, "vza": 0.0}


@pytest.fixture(scope="module")
def lines(make_lines):
    return make_lines()


@pytest.fixture(scope="module")
def files(lines, tmp_path_factory):
    """Each line as image, class map and 4-band angle GeoTIFFs; the images named line1.tif ..."""
    directory = tmp_path_factory.mktemp("lines")
    paths = {"images": [], "classes": [], "angles": []}
    for line in lines:
        scene = {"reflectance": line.reflectance, "classes": line.classes, **line.angles}
        written = write_scene(directory / line.name, scene)
        image = written["image"].rename(directory / f"{line.name}.tif")
        paths["images"].append(image)
        paths["classes"].append(written["classes"])
        paths["angles"].append(written["angles"])
    return paths


@pytest.fixture(scope="module")
def library_report(files):
    assessment = leave_one_line_out_files(_scenes(files), HoldoutFit("ross_thick_li_sparse", reference=REFERENCE),
                                          view_options=ViewAngleOptions(class_names=NAMES))
    return assessment.report()


@pytest.fixture(scope="module")
def plain(lines):
    """The lines' leave-one-line-out in memory (never written), without a prior: read-only."""
    return leave_one_line_out(lines, HoldoutFit("ross_thick_li_sparse", reference=REFERENCE),
                              view_options=ViewAngleOptions(class_names=NAMES))


def _scenes(files, count=None, images=None):
    """The lines' SceneSources: image, class map and angle source of each, in order."""
    images = files["images"][:count] if images is None else images
    return [SceneSources(image, classes, angles) for image, classes, angles in
            zip(images, files["classes"], files["angles"])]


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def _arguments(files, images=None, classes=None, angles=None):
    arguments = [*(files["images"] if images is None else images)]
    for option, paths in (("--classes", files["classes"] if classes is None else classes),
                          ("--angles", files["angles"] if angles is None else angles)):
        for path in paths:
            arguments += [option, path]
    return arguments


def test_files_give_the_numbers_of_the_lines_in_memory(plain, library_report):
    # Independent computation: the same lines, never written, through leave_one_line_out. The files
    # hold the same float64 values, so every number agrees to rounding.
    memory = leave_one_line_out_report(plain)
    assert [line["held_out"] for line in library_report["lines"]] == ["line1", "line2", "line3"]
    for from_files, in_memory in zip(library_report["lines"], memory["lines"]):
        for stage in ("before", "after"):
            for got, expected in zip(from_files["view_angles"]["classes"], in_memory["view_angles"]["classes"]):
                np.testing.assert_allclose(got[stage]["relative_slope"], expected[stage]["relative_slope"],
                                           rtol=1e-6)
            for name, overlap in in_memory["overlaps"].items():
                np.testing.assert_allclose(from_files["overlaps"][name][stage]["rmse"], overlap[stage]["rmse"],
                                           rtol=1e-6)


def test_held_out_slopes_and_overlap_differences_fall(library_report):
    for line in library_report["lines"]:
        slope = line["view_angles"]["summary"]["abs_relative_slope_percent_per_10deg"]
        # property: parameters fitted on the other lines take most of the view-angle signal out
        assert slope["after"]["max"] < 0.2 * slope["before"]["max"], line["held_out"]
        assert line["overlaps"], line["held_out"]  # every line overlaps a neighbour
        for overlap in line["overlaps"].values():
            assert np.all(np.array(overlap["after"]["rmse"]) < 0.2 * np.array(overlap["before"]["rmse"]))


def test_cli_report_equals_the_library_report(files, library_report, tmp_path):
    output = tmp_path / "lines.json"
    result = _invoke("assess-lines", *_arguments(files), "--model", "ross_thick_li_sparse",
                     "--class-name", "1=grass", "--class-name", "2=soil", "--ref-sza", "35", "-o", output)
    assert result.exit_code == 0, result.output
    report = json.loads(output.read_text())
    assert report["kind"] == "leave-one-line-out"
    assert [entry["name"] for entry in report["inputs"]] == ["line1", "line2", "line3"]
    assert report == library_report  # the command is one call of the library function
    # the printed table: per held-out line, the largest |relative slope| before and after
    line = report["lines"][1]
    assert "line2 (parameters fitted on line1, line3)" in result.output
    slope = line["view_angles"]["summary"]["abs_relative_slope_percent_per_10deg"]
    assert f"{slope['before']['max']:.2f}" in result.output and f"{slope['after']['max']:.2f}" in result.output
    assert "overlap with line1" in result.output and "overlap with line3" in result.output
    # the reference every line and its overlaps were corrected to, in the report and printed
    assert line["reference"] == {"sza": 35.0, "vza": 0.0, "sza_from": "fixed"}
    assert "corrected to sun zenith 35 deg (fixed), view zenith 0 deg" in result.output
    # an existing report is replaced only with --overwrite
    again = _invoke("assess-lines", *_arguments(files), "--model", "ross_thick_li_sparse", "-o", output)
    assert again.exit_code == 2


def test_bad_input_is_one_line_and_exit_2(files, tmp_path):
    output = tmp_path / "r.json"
    mismatched = _invoke("assess-lines", *_arguments(files, classes=files["classes"][:2]), "-o", output)
    assert mismatched.exit_code == 2
    assert mismatched.output.strip().count("\n") == 0
    assert "3 image(s), 2 class map(s) and 3 angle source(s)" in mismatched.output
    missing = _invoke("assess-lines", *_arguments(files, images=[*files["images"][:2], tmp_path / "nope.tif"]),
                      "-o", output)
    assert missing.exit_code == 2
    assert missing.output.strip().count("\n") == 0 and "nope.tif" in missing.output
    assert not output.exists()
    with pytest.raises(InputError, match="at least 2 lines"):
        leave_one_line_out_files(_scenes(files, count=1))
    with pytest.raises(InputError, match="given twice"):
        leave_one_line_out_files(_scenes(files, images=files["images"][:1] * 2))


def test_a_prior_reaches_every_held_out_fit(lines, plain, files, tmp_path, tables_close):
    # --prior as for fit-classes: each held-out line is corrected with the posterior of the fit on
    # the other lines (brdfcorr.fit.prior), and the CLI is the library call.
    from brdfcorr.fit.prior import ShapePrior, with_shape_prior

    options = {"view_options": ViewAngleOptions(class_names=NAMES)}
    prior = leave_one_line_out(lines, HoldoutFit("ross_thick_li_sparse", reference=REFERENCE,
                                                 prior=ShapePrior("roy2016", 0.1)), **options)
    for without, with_prior in zip(plain, prior):
        tables_close(with_prior.table, with_shape_prior(without.table, ShapePrior("roy2016", 0.1)))
    arguments = ["--model", "ross_thick_li_sparse", "--class-name", "1=grass", "--class-name", "2=soil",
                 "--ref-sza", "35", "--prior", "roy2016", "--prior-spread", "0.1", "-o", tmp_path / "prior.json"]
    # The files' bands have no wavelengths: the prior cannot be placed, and says so (exit 2).
    result = _invoke("assess-lines", *_arguments(files), *arguments)
    assert result.exit_code == 2 and "needs the bands' wavelengths" in result.output
    # With their band centres in the band descriptions, the CLI is the library call.
    images = []
    for line, image in zip(lines, files["images"]):
        images.append(shutil.copy(image, tmp_path / image.name))
        with rasterio.open(images[-1], "r+") as dataset:
            dataset.descriptions = tuple(f"{value:g} nm" for value in line.reflectance["wavelength"].values)
    result = _invoke("assess-lines", *_arguments(files, images=images), *arguments)
    assert result.exit_code == 0, result.output
    library = leave_one_line_out_files(_scenes(files, images=images), HoldoutFit(
        "ross_thick_li_sparse", reference=REFERENCE, prior=ShapePrior("roy2016", 0.1)), **options)
    assert json.loads((tmp_path / "prior.json").read_text()) == library.report()


def test_each_line_takes_its_cluster_layer(files, tmp_path):
    """``--clusters`` once per line (issue 40): each held-out line's slopes' 1-sigma is over its
    layer's ids (stripes of 4 columns here); a count that is not one per line is refused in one line."""
    import rioxarray

    layers = []
    for image in files["images"]:
        like = rioxarray.open_rasterio(image).isel(band=0, drop=True)
        stripes = like.copy(data=(np.arange(like.sizes["x"]) // 4 * np.ones((like.sizes["y"], 1))).astype(np.int16))
        stripes.attrs = {}
        layers.append(tmp_path / f"stripes_{image.stem}.tif")
        stripes.rio.to_raster(layers[-1])
    output = tmp_path / "lines.json"
    clusters = [argument for layer in layers for argument in ("--clusters", layer)]
    result = _invoke("assess-lines", *_arguments(files), "--model", "ross_thick_li_sparse", *clusters, "-o", output)
    assert result.exit_code == 0, result.output
    report = json.loads(output.read_text())
    assert [entry["clusters"] for entry in report["inputs"]] == [f"{layer} band 1" for layer in layers]
    for line in report["lines"]:
        assert "cluster layer" in line["view_angles"]["errors"]["clusters"]
        assert line["reference"]["sza_from"] == "mean of the lines"  # the default reference sun
    assert "corrected to sun zenith 35 deg (the mean of the lines)" in result.output  # every line's sun: 35 deg
    refused = CliRunner().invoke(main, [str(a) for a in ("assess-lines", *_arguments(files), *clusters[:4], "-o",
                                                         tmp_path / "two.json")])
    assert refused.exit_code == 2 and "give one per line" in refused.output
    assert len(refused.output.strip().splitlines()) == 1


def test_view_azimuths_stored_from_the_sensor_are_flipped_in_the_fits_too(lines, plain, tables_close):
    # The same lines with each view azimuth stored as seen from the sensor (vaa + 180) and
    # --flip-view-azimuth: every held-out fit, correction and assessment is that of the lines
    # stored the usual way (the fits read the azimuths as the corrections do).
    turned = [line._replace(angles={**line.angles, "vaa": (line.angles["vaa"] + 180.0) % 360.0}) for line in lines]
    fit = HoldoutFit("ross_thick_li_sparse", reference=REFERENCE)
    flipped = leave_one_line_out(turned, fit, view_options=ViewAngleOptions(class_names=NAMES,
                                                                            flip_view_azimuth=True))
    for ours, theirs in zip(flipped, plain):
        tables_close(ours.table, theirs.table, rtol=1e-6)
        assert ours.table.classes  # fitted, not left uncorrected
        np.testing.assert_allclose(ours.view["relative_slope"].values, theirs.view["relative_slope"].values, atol=1e-6)


def test_tagged_class_names_are_not_warned_about_but_given_ones_are(files, tmp_path):
    # The class maps' class_names tag names a class 7 that no line holds (what a map may hold, as
    # fit-classes reads it: ClassModels.default_names): no fold warns of it. A name the user gives
    # for a class no training line holds (9) is still warned about, once per fold.
    from brdfcorr.fit.classes import ClassFitWarning

    tagged = []
    for path in files["classes"]:
        tagged.append(shutil.copy(path, tmp_path / f"{path.parent.name}_{path.name}"))
        with rasterio.open(tagged[-1], "r+") as dataset:
            dataset.update_tags(class_names="1:grass,2:soil,7:water")
    scenes = [SceneSources(image, classes, angles)
              for image, classes, angles in zip(files["images"], tagged, files["angles"])]
    fit = HoldoutFit("ross_thick_li_sparse", reference=REFERENCE, max_samples=2000)

    def unused_warnings(view_options):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assessment = leave_one_line_out_files(scenes, fit, view_options=view_options, overlap=False)
        return assessment, [str(w.message) for w in caught
                            if issubclass(w.category, ClassFitWarning) and "not used" in str(w.message)]

    assessment, unused = unused_warnings(ViewAngleOptions())
    assert unused == []
    # the tag's names still name the fitted and the assessed classes
    for line in assessment.report()["lines"]:
        assert [entry["name"] for entry in line["fit"]] == ["grass", "soil"]
        assert [entry["name"] for entry in line["view_angles"]["classes"]] == ["grass", "soil"]
    _, unused = unused_warnings(ViewAngleOptions(class_names={9: "roof"}))
    assert len(unused) == 3  # one per held-out line's fit
    assert all("names 9" in message and "7" not in message for message in unused)
