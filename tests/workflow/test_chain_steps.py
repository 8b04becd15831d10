"""Chain steps and outputs wired to the library: steps.assess, outputs.uncertainty, terrain inputs
(steps.correct.terrain), outputs.interleave for ENVI, chunk progress; each against a closed form,
an independent computation or the library call the chain makes."""

import dataclasses
import json
import os

import numpy as np
import pytest
import rasterio
import xarray as xr

from brdfcorr.chain.config import load_config
from brdfcorr.chain.run import plan_run, run_chain
from brdfcorr.io.scene import SceneSources
from brdfcorr.params import ParameterTable
from brdfcorr.tasks.correct import Terrain, correct_files
from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles
from brdfcorr.tasks.results import CorrectionResult, TopographicSummary
from brdfcorr.testing import PIXEL, example_table, georeference

NY, NX = 32, 48  # the scenes of make_scenes (tests/conftest.py)


# make_scenes, write_chain, read and chain_reference: tests/conftest.py.
def direct(paths, output, table, reference, uncertainty=None, **options):
    """The call of correct_files the chain's correct step makes for a scene of write_chain (its
    ``reference``: chain_reference)."""
    return correct_files(CorrectionRequest(
        SceneSources(paths["image"], paths["classes"], paths["angles"]), table,
        OutputFiles(output, uncertainty=uncertainty), reference=reference, limits=None, engine=Engine(chunks=16),
        **options))


# ------------------------------------------------------------------------------------- assess
def test_assess_step_writes_report_figure_and_summary(tmp_path, make_scenes, write_chain):
    scene, paths = make_scenes(tmp_path, count=1)["line0"]
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}, "assess": {"bin_width": 5.0}})
    report = run_chain(load_config(chain))
    assert report.ok, report.scenes
    result = report.scenes[0]
    # named by the scene: "image", the stem of scenes/line0/image.tif (one image, no scene_regex)
    assessed = json.loads((tmp_path / "out" / "image_assess.json").read_text())
    assert result["outputs"]["assess"] == str(tmp_path / "out" / "image_assess.json")
    assert (tmp_path / "out" / "image_assess_profiles.png").read_bytes()[:4] == b"\x89PNG"
    assert set(result["seconds"]) == {"correct", "assess", "total"}

    # Independent: the least-squares slope of one class and band against the signed view zenith
    # (sign by the sun: + where cos(saa - vaa) < 0), relative to its mean, in %/10 deg.
    classes = scene["classes"].values
    signed = scene["vza"].values * np.sign(-np.cos(np.radians(scene["saa"].values - scene["vaa"].values)))
    entries = {entry["id"]: entry for entry in assessed["view_angles"]["classes"]}
    for class_id in (1, 2):
        inside = classes == class_id
        values = scene["reflectance"].values[0][inside].astype(float)
        slope = np.polyfit(signed[inside], values, 1)[0]
        assert entries[class_id]["before"]["relative_slope"][0] == pytest.approx(1000 * slope / values.mean(),
                                                                                 rel=1e-5)
    assert {entry["id"]: entry["name"] for entry in entries.values()} == {
        entry.id: entry.name for entry in example_table().classes}  # names from the parameter table

    # The report entry: per class the median over bands of |relative slope|, before and after.
    for row in result["assess"]:
        entry = entries[row["id"]]
        for stage in ("before", "after"):
            expected = np.median(np.abs([v for v in entry[stage]["relative_slope"] if v is not None]))
            assert row["median_abs_relative_slope_percent_per_10deg"][stage] == pytest.approx(expected)
            # and the bands whose slope lies within 2 sigma of 0, counted from the report's lists
            slopes, errors = (np.array(entry[stage][key], dtype=float) for key in ("relative_slope",
                                                                                  "relative_slope_error"))
            assert row["bands_within_2_sigma"][stage] == int(np.sum(np.abs(slopes) <= 2 * errors))
    assert assessed["view_angles"]["classes"][0]["profile"]["vza_bin_edges_deg"][0][1] - \
        assessed["view_angles"]["classes"][0]["profile"]["vza_bin_edges_deg"][0][0] == pytest.approx(5.0)

    # Resumed: the scene is skipped and its entry keeps what the assessment found.
    again = run_chain(load_config(chain))
    assert again.scenes[0]["status"] == "skipped" and again.scenes[0]["assess"] == result["assess"]


# -------------------------------------------------------------------------------- uncertainty
def table_with_fits() -> ParameterTable:
    """The example table with a fit: block (covariance) for class 1 (Torrance-Sparrow) and 4
    (Lambertian); classes 2 and 3 have none."""
    document = example_table().to_dict()
    fits = {  # errors: sqrt(diag(covariance))
        1: {"parameters": ["t0", "t1", "w"], "covariance": [[1e-6, -1e-6, 0.0], [-1e-6, 1e-4, 2e-6], [0.0, 2e-6, 4e-6]],
            "errors": {"t0": 1e-3, "t1": 1e-2, "w": 2e-3}},
        4: {"parameters": ["t0"], "covariance": [[1e-4]], "errors": {"t0": 1e-2}},
    }
    for entry in document["classes"]:
        if entry["id"] in fits:
            entry["fit"] = {"source": "test", "n": 400, "chi2_dof": 1.0, "r2": 0.9, **fits[entry["id"]]}
    return ParameterTable.from_dict(document)


def test_uncertainty_output(tmp_path, make_scenes, write_chain, read, chain_reference):
    scene, paths = make_scenes(tmp_path, count=1)["line0"]
    table = table_with_fits()
    chain = write_chain(tmp_path, table=table, outputs__uncertainty=True)
    report = run_chain(load_config(chain))
    assert report.ok, report.scenes
    sigma, _ = read(tmp_path / "out" / "line0_sigma.tif")
    classes = scene["classes"].values
    # Lambertian: F = f(ref) / f(obs) = t0 / t0 = 1 whatever t0, so dF/dt0 = 0 and sigma = 0 exactly.
    assert (sigma[:, classes == 4] == 0).all()
    assert np.isfinite(sigma[:, classes == 1]).all() and (sigma[:, classes == 1] > 0).all()
    assert np.isnan(sigma[:, (classes == 2) | (classes == 3)]).all()  # no fit: block, nothing known
    # The chain writes what the library call writes.
    direct(paths, tmp_path / "direct.tif", table, chain_reference, uncertainty=tmp_path / "direct_sigma.tif")
    np.testing.assert_array_equal(sigma, read(tmp_path / "direct_sigma.tif")[0])
    # The plan says beforehand which classes will be NaN.
    assert plan_run(load_config(chain)).warnings == (
        "outputs.uncertainty: class 2 (grass), class 3 (paving) have no fit: block (covariance) in the "
        "parameter table; their pixels are NaN in the uncertainty raster",)


def test_uncertainty_output_counts_for_resume(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path, table=table_with_fits())
    assert run_chain(load_config(chain)).ok
    with_sigma = load_config(chain, {"outputs.uncertainty": True})
    assert plan_run(with_sigma).scenes[0].action == "run"  # the uncertainty raster is missing
    assert run_chain(with_sigma).ok
    plan = plan_run(with_sigma)
    assert plan.scenes[0].action == "skip" and "uncertainty" in plan.scenes[0].outputs
    assert tmp_path / "out" / "line0_sigma.tif" in plan.files_written()


# ------------------------------------------------------------------------------------ terrain
def write_slope_aspect(path, slope, aspect):
    layers = xr.DataArray(np.stack([np.broadcast_to(slope, (NY, NX)), np.broadcast_to(aspect, (NY, NX))]),
                          dims=("band", "y", "x"), coords={"band": [1, 2]}).astype(np.float32)
    layers = georeference(layers)
    layers.attrs["long_name"] = ("slope", "aspect")
    layers.rio.to_raster(path)
    return path


def terrain_chain(write_chain, tmp_path, **terrain):
    return write_chain(tmp_path, inputs__slope_aspect="{dir}/slope_aspect.tif",
                       steps={"correct": {"limits": None, "terrain": terrain}})


def test_flat_terrain_gives_the_flat_correction(tmp_path, make_scenes, write_chain, read):
    # A zero slope is a horizontal surface: cos i = cos(sza) (cosine factor 1) and the surface frame
    # is the horizontal one, so the terrain correction must equal the plain one.
    make_scenes(tmp_path, count=1)
    write_slope_aspect(tmp_path / "scenes" / "line0" / "slope_aspect.tif", 0.0, 0.0)
    flat = run_chain(load_config(write_chain(tmp_path), {"outputs.directory": "flat"}))
    tilted = run_chain(load_config(terrain_chain(write_chain, tmp_path)))
    assert flat.ok and tilted.ok, tilted.scenes
    np.testing.assert_allclose(read(tmp_path / "out" / "line0_brdf.tif")[0], read(tmp_path / "flat" / "line0_brdf.tif")[0],
                               rtol=1e-5)
    assert tilted.scenes[0]["topographic"]["method"] == "cosine"


def test_terrain_inputs_reach_correct_files_and_the_fingerprint(tmp_path, make_scenes, write_chain, read,
                                                               chain_reference):
    _, paths = make_scenes(tmp_path, count=1)["line0"]
    slope_file = write_slope_aspect(tmp_path / "scenes" / "line0" / "slope_aspect.tif",
                                    np.linspace(0.0, 20.0, NX), 150.0)  # facets towards the sun (saa 150)
    chain = terrain_chain(write_chain, tmp_path, topographic="scs", brdf_frame="horizontal")
    config = load_config(chain)
    scene = plan_run(config).scenes[0]
    assert ("slope/aspect", slope_file) in scene.inputs()
    assert run_chain(config).ok
    direct(paths, tmp_path / "direct.tif", example_table(), chain_reference,
           terrain=Terrain(slope_aspect=slope_file, topographic="scs", brdf_frame="horizontal"))
    np.testing.assert_array_equal(read(tmp_path / "out" / "line0_brdf.tif")[0], read(tmp_path / "direct.tif")[0])

    # Resume: the terrain settings and the terrain file are part of the fingerprint.
    assert plan_run(config).scenes[0].action == "skip"
    changed = plan_run(load_config(chain, {"steps.correct.terrain": {"topographic": "cosine",
                                                                      "brdf_frame": "horizontal"}})).scenes[0]
    assert changed.action == "run" and "steps.correct.terrain changed" in changed.reason
    os.utime(slope_file, ns=(0, 0))
    touched = plan_run(config).scenes[0]
    assert touched.action == "run" and str(slope_file) in touched.reason

    # A missing terrain file fails the scene before anything runs; so does an output named like it.
    slope_file.unlink()
    missing = plan_run(config).scenes[0]
    assert missing.action == "fail" and missing.reason == f"missing input: slope/aspect {slope_file}"


def test_dem_pattern(tmp_path, make_scenes, write_chain, read, chain_reference):
    # A plane z = 0.1 x rises 1 m per 10 m pixel eastwards: slope atan(0.1) = 5.71 deg facing west
    # (aspect 270). Chain with the DEM == library call with the same DEM.
    _, paths = make_scenes(tmp_path, count=1)["line0"]
    heights = np.broadcast_to(0.1 * PIXEL * np.arange(NX, dtype=np.float32), (NY, NX))
    dem = georeference(xr.DataArray(heights, dims=("y", "x")))
    dem_file = tmp_path / "scenes" / "line0" / "dem.tif"
    dem.rio.to_raster(dem_file)
    chain = write_chain(tmp_path, inputs__dem="{dir}/dem.tif", steps={"correct": {"limits": None, "terrain": {}}})
    report = run_chain(load_config(chain))
    assert report.ok, report.scenes
    result = direct(paths, tmp_path / "direct.tif", example_table(), chain_reference, terrain=Terrain(dem=dem_file))
    np.testing.assert_array_equal(read(tmp_path / "out" / "line0_brdf.tif")[0], read(tmp_path / "direct.tif")[0])
    assert json.loads(report.path.read_text())["inputs"][0]["dem"] == str(dem_file)
    # The result is a frozen record; the chain's report holds its fields as the library call gives them.
    assert isinstance(result, CorrectionResult) and isinstance(result.topographic, TopographicSummary)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.counts = {}  # type: ignore[misc]
    found = report.scenes[0]
    assert found["qa"] == dict(result.counts) and found["reference"] == result.reference.describe()
    assert found["topographic"] == result.topographic.as_dict() and result.topographic.method == "cosine"
    assert result.topographic.c == () and result.topographic.rejected == 0  # cosine fits no C
    assert result.notes == () and "notes" not in found  # most pixels corrected: nothing to say
    # Every pixel of the scene is counted once among corrected, no class, unknown class and nodata, or more.
    assert sum(result.counts[key] for key in ("corrected", "no_class", "unknown_class", "nodata")) >= NY * NX


# --------------------------------------------------------------------------------- interleave
def test_envi_interleave(tmp_path, make_scenes, write_chain, read):
    make_scenes(tmp_path, count=1)
    plain = run_chain(load_config(write_chain(tmp_path), {"outputs.directory": "tif"}))
    chain = write_chain(tmp_path, outputs__format="ENVI", outputs__interleave="bil",
                        outputs__naming="{parent}_brdf.bil")
    envi = run_chain(load_config(chain))
    assert plain.ok and envi.ok, envi.scenes
    output = tmp_path / "out" / "line0_brdf.bil"
    header = output.with_suffix(".hdr").read_text()
    assert "interleave = bil" in header
    with rasterio.open(output) as dataset:
        assert dataset.driver == "ENVI"
        np.testing.assert_array_equal(dataset.read(), read(tmp_path / "tif" / "line0_brdf.tif")[0])
    # BIL on disk: the first line holds band 1's NX values, then band 2's (float32, the header's
    # byte order): an independent read of the raw file.
    with rasterio.open(tmp_path / "tif" / "line0_brdf.tif") as dataset:
        first_line = dataset.read(window=((0, 1), (0, NX)))[:, 0, :]
    order = "<" if "byte order = 0" in header else ">"
    raw = np.fromfile(output, dtype=f"{order}f4", count=first_line.size).reshape(first_line.shape)
    np.testing.assert_array_equal(raw, first_line)
    # The interleave is part of the output's fingerprint: bsq redoes the scene.
    changed = plan_run(load_config(chain, {"outputs.interleave": "bsq"})).scenes[0]
    assert changed.action == "run" and "output format changed" in changed.reason


# ----------------------------------------------------------------------------------- progress
def test_chunk_events_only_inline(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    events = []
    run_chain(load_config(chain, {"engine.scheduler": "synchronous"}),
              progress=lambda event, info: events.append((event, dict(info))))
    chunks = [info for event, info in events if event == "chunks"]
    assert chunks and chunks[-1]["done"] == chunks[-1]["total"] > 0 and chunks[-1]["scene"] == "image"
    events.clear()
    run_chain(load_config(chain, {"engine.scheduler": "processes", "engine.workers": 1, "outputs.existing": "overwrite"}),
              progress=lambda event, info: events.append((event, dict(info))))
    assert [event for event, _ in events] == ["plan", "scene"]  # scene-level progress from worker processes


def test_a_class_given_by_two_parameter_sources_is_named_with_the_entry_used(tmp_path, make_scenes, write_chain):
    # The table file's class 1 replaced the inline class 1 (and the material) without a word.
    make_scenes(tmp_path, count=1)
    inline = [{"id": 1, "name": "flat", "model": "lambertian", "params": {"t0": 0.1}}]
    chain = write_chain(tmp_path, parameters__materials={1: "roof_tile", 3: "red_concrete"}, parameters__classes=inline)
    plan = plan_run(load_config(chain))
    assert [w for w in plan.warnings if w.startswith("class ")] == [
        "class 1 is given in parameters.materials and parameters.classes and parameters.table: "
        "parameters.table's entry is used",
        "class 3 is given in parameters.materials and parameters.table: parameters.table's entry is used"]
    alone = write_chain(tmp_path)
    assert not [w for w in plan_run(load_config(alone)).warnings if w.startswith("class ")]
