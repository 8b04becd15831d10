"""Chain runs end to end: outputs against the closed form, report, failure isolation, resume,
dry run, fit steps, the processes engine."""

import json
import os
import sys

import numpy as np
import rasterio
import rasterio.shutil
import yaml
from click.testing import CliRunner

from brdfcorr.chain.config import load_config
from brdfcorr.chain.run import build_table, plan_run, run_chain
from brdfcorr.cli import EXIT_SCENES_FAILED, main
from brdfcorr.testing import example_table, synthetic_scene, write_scene


def test_run_writes_closed_form_outputs_and_report(tmp_path, make_scenes, write_chain, expected, read):
    scenes = make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}, "quicklook": {"bands": [3, 2, 1]}})
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 0, result.output
    for name, (scene, _) in scenes.items():
        corrected, tags = read(tmp_path / "out" / f"{name}_brdf.tif")
        # float32 input: relative agreement to float32 precision
        np.testing.assert_allclose(corrected, expected(scene), rtol=2e-5)
        assert tags["brdf_reference"] == "sza=35 vza=0 raa=0"
        qa, _ = read(tmp_path / "out" / f"{name}_qa.tif")
        assert qa.max() == 0  # every pixel of the example classes corrected, none limited
        assert (tmp_path / "out" / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    report = json.loads((tmp_path / "out" / "run_report.json").read_text())
    assert report["summary"] == {"scenes": 2, "ok": 2, "skipped": 0, "failed": 0}
    assert set(report["versions"]) >= {"brdfcorr", "numpy", "xarray", "dask", "rasterio"}
    assert [entry["image"] for entry in report["inputs"]] == [
        str(tmp_path / "scenes" / name / "image.tif") for name in sorted(scenes)]
    assert [entry["id"] for entry in report["parameters"]["table"]["classes"]] == [1, 2, 3, 4]
    for entry in report["scenes"]:
        assert entry["qa"] == {"corrected": 32 * 48, "limited": 0, "unknown_class": 0, "no_class": 0, "nodata": 0}
        assert entry["seconds"]["correct"] > 0 and entry["seconds"]["quicklook"] > 0
    assert report["timings"]["total"] >= report["timings"]["scenes"]


def test_failure_isolation_and_resume(tmp_path, make_scenes, write_chain, expected, read):
    scenes = make_scenes(tmp_path, count=3)
    bad_angles = scenes["line1"][1]["angles"]
    kept = bad_angles.read_bytes()
    bad_angles.write_bytes(b"not a GeoTIFF")  # unreadable angles: this scene must fail alone
    chain = write_chain(tmp_path)
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == EXIT_SCENES_FAILED, result.output
    report = json.loads((tmp_path / "out" / "run_report.json").read_text())
    status = {entry["scene"]: entry for entry in report["scenes"]}
    assert report["summary"]["failed"] == 1 and report["summary"]["ok"] == 2
    failed = [entry for entry in report["scenes"] if entry["status"] == "failed"]
    assert str(bad_angles) in failed[0]["error"] and failed[0]["error_type"] == "InputError"
    assert not (tmp_path / "out" / "line1_brdf.tif").exists()  # nothing partial left behind
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.endswith(".partial")]
    assert len(status) == 3

    good = tmp_path / "out" / "line0_brdf.tif"
    stamp = good.stat().st_mtime_ns
    bad_angles.write_bytes(kept)  # repair, then resume: only the failed scene runs
    result = CliRunner().invoke(main, ["run", str(chain), "--resume", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert good.stat().st_mtime_ns == stamp
    report = json.loads((tmp_path / "out" / "run_report.json").read_text())
    assert report["summary"] == {"scenes": 3, "ok": 1, "skipped": 2, "failed": 0}
    skipped = [entry for entry in report["scenes"] if entry["status"] == "skipped"]
    assert all(entry["qa"]["corrected"] == 32 * 48 for entry in skipped)  # carried from the first run
    np.testing.assert_allclose(read(tmp_path / "out" / "line1_brdf.tif")[0], expected(scenes["line1"][0]), rtol=2e-5)

    # A scene with only part of its outputs (QA missing) is not complete: it is redone.
    os.unlink(tmp_path / "out" / "line2_qa.tif")
    plan = plan_run(load_config(chain))
    assert [scene.action for scene in plan.scenes] == ["skip", "skip", "run"]
    # existing: error fails complete scenes; overwrite redoes them
    plan = plan_run(load_config(chain, {"outputs.existing": "error"}))
    assert [scene.action for scene in plan.scenes] == ["fail", "fail", "run"]
    result = CliRunner().invoke(main, ["run", str(chain), "--overwrite", "--no-progress"])
    assert result.exit_code == 0 and good.stat().st_mtime_ns != stamp


def test_missing_input_and_grid_mismatch_are_per_scene_failures(tmp_path, make_scenes, write_chain):
    scenes = make_scenes(tmp_path, count=3)
    os.unlink(scenes["line0"][1]["classes"])
    small = synthetic_scene(16, 16, seed=5)
    write_scene(tmp_path / "other", small)
    os.replace(tmp_path / "other" / "classes.tif", scenes["line2"][1]["classes"])
    report = run_chain(load_config(write_chain(tmp_path)))
    by_scene = {entry["image"]: entry for entry in report.scenes}
    first = by_scene[str(scenes["line0"][1]["image"])]
    assert first["status"] == "failed" and "missing input: class map" in first["error"]
    third = by_scene[str(scenes["line2"][1]["image"])]
    assert third["status"] == "failed" and third["error_type"] == "GridMismatchError"
    assert "classes" in third["error"] and "shape" in third["error"]
    assert by_scene[str(scenes["line1"][1]["image"])]["status"] == "ok"
    assert not report.ok and report.n_failed == 2


def test_dry_run_lists_and_writes_nothing(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    result = CliRunner().invoke(main, ["run", str(chain), "--dry-run"])
    assert result.exit_code == 0, result.output
    assert "2 scenes: 2 to run, 0 to skip, 0 would fail" in result.output
    assert "line0_brdf.tif, line0_qa.tif" in result.output
    assert "parameters: table" in result.output
    assert not (tmp_path / "out").exists()


def test_one_scene_is_singular(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    result = CliRunner().invoke(main, ["run", str(chain), "--dry-run"])
    assert result.exit_code == 0, result.output
    assert "1 scene: 1 to run, 0 to skip, 0 would fail" in result.output
    result = CliRunner().invoke(main, ["validate", str(chain)])
    assert result.exit_code == 0, result.output
    assert "valid; 1 scene found," in result.output


def test_dry_run_of_no_scenes_exits_2_as_run_does(tmp_path, write_chain):
    # The images' folder is not there: run refuses the empty batch, so must its dry run.
    chain = write_chain(tmp_path)
    run = CliRunner().invoke(main, ["run", str(chain)])
    dry = CliRunner().invoke(main, ["run", str(chain), "--dry-run"])
    assert run.exit_code == dry.exit_code == 2, (run.output, dry.output)
    assert "inputs.images matches no file" in run.output
    assert dry.output == run.output and len(dry.output.strip().splitlines()) == 1
    assert "0 scenes" not in dry.output and not (tmp_path / "out").exists()


def test_bad_config_and_fatal_errors_exit_2(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path, engine={"scheduler": "threads", "workers": 0})
    result = CliRunner().invoke(main, ["run", str(chain)])
    assert result.exit_code == 2
    assert "engine.workers: Input should be greater than or equal to 1 (got 0)" in result.output
    chain = write_chain(tmp_path, inputs={"images": ["nothing/*.tif"], "angles": {"path": "a.tif"}, "classes": "c.tif"})
    result = CliRunner().invoke(main, ["run", str(chain)])
    assert result.exit_code == 2 and "inputs.images matches no file" in result.output
    chain = write_chain(tmp_path, outputs={"directory": "scenes/line0", "naming": "{stem}.tif"})
    result = CliRunner().invoke(main, ["run", str(chain)])
    assert result.exit_code == 2 and "would overwrite an input" in result.output


def test_imagery_fit_step(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2, ny=48, nx=64)
    chain = write_chain(
        tmp_path,
        parameters={"materials": {1: "roof_tile"}},
        steps={"fit": {"source": "imagery", "class_models": {2: "empirical", 3: "torrance_sparrow_simplified",
                                                             4: "lambertian"},
                       "names": {2: "grass"}, "max_samples": 3000, "min_samples": 200},
               "correct": {"limits": None}},
    )
    report = run_chain(load_config(chain))
    assert report.ok, report.scenes
    fitted = yaml.safe_load((tmp_path / "out" / "fitted_params.yaml").read_text())
    status = {fit["class_id"]: fit["status"] for fit in report.fit["classes"]}
    # Class 4 is Lambertian: no angular signal to explain (R^2 ~ 0 by construction), so the R^2
    # guard rail does not apply; it is fitted (t0 = mean BRDF) and corrected with factor 1.
    assert status == {1: "fitted", 2: "fitted", 3: "fitted", 4: "fitted"}
    assert not any("class 4" in warning for warning in report.fit["warnings"])
    assert [entry["id"] for entry in fitted["classes"]] == [1, 2, 3, 4]
    assert fitted["classes"][0]["name"] == "roof_tile" and fitted["classes"][1]["name"] == "grass"
    # The run's table is the fitted one (plus nothing else: the material of class 1 is replaced).
    table = report.to_dict()["parameters"]["table"]["classes"]
    assert [entry["params"] for entry in table] == [entry["params"] for entry in fitted["classes"]]
    assert all(entry["qa"]["unknown_class"] == 0 for entry in report.scenes)
    # Resume reuses the fitted table instead of refitting: the fit's settings and inputs are those
    # the first run recorded (its fingerprint), and so are the classes its fit reported.
    again = run_chain(load_config(chain))
    assert again.fit == {"source": "imagery", "reused": str(tmp_path / "out" / "fitted_params.yaml"),
                         "fingerprint": report.fit["fingerprint"], "classes": report.fit["classes"]}
    # Other fit settings make another fit: the table is fitted again, not reused.
    changed = run_chain(load_config(chain, overrides={"steps.fit.max_samples": 4000}))
    assert "reused" not in changed.fit and changed.fit["fingerprint"] != report.fit["fingerprint"]


def test_goniometer_fit_step(tmp_path, make_scenes, write_chain):
    from brdfcorr.fit.measurements import write_measurements
    from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
    from brdfcorr.models.materials import load_material

    make_scenes(tmp_path, count=1)
    tile = load_material("roof_tile")
    theta_i, theta_r, phi = goniometer_angles()
    write_measurements(tmp_path / "tile.csv", synthesize_measurements(
        tile.model, tile.params, theta_i, theta_r, phi, relative_noise=0.01, seed=1))
    chain = write_chain(tmp_path, steps={"fit": {"source": "goniometer", "measurements": [
        {"file": "tile.csv", "class_id": 1, "name": "tile_fit", "fixed": {"k": 0.25}, "min_phi": 90}]}})
    report = run_chain(load_config(chain))
    assert report.ok
    fit = report.fit["classes"][0]["fits"][0]
    for name in ("w", "t0"):  # paper 003 Table 1 values used to synthesize, within 4 sigma
        assert abs(fit["params"][name] - tile.params[name]) < 4 * fit["errors"][name], name
    table = report.to_dict()["parameters"]["table"]["classes"]
    assert table[0]["name"] == "tile_fit" and table[1]["name"] == "grass"  # fit replaced class 1 only
    # Other measurements in the same file: fitted again (before, the earlier table was reused and
    # the scene skipped), and the scene corrected with the new table.
    write_measurements(tmp_path / "tile.csv", synthesize_measurements(
        tile.model, {**tile.params, "w": 2 * tile.params["w"]}, theta_i, theta_r, phi, relative_noise=0.01, seed=1))
    again = run_chain(load_config(chain))
    assert "reused" not in again.fit and again.scenes[0]["status"] == "ok"
    refit = again.fit["classes"][0]["fits"][0]["params"]["w"]
    assert abs(refit - 2 * tile.params["w"]) < 4 * again.fit["classes"][0]["fits"][0]["errors"]["w"]


def test_processes_engine_matches_threads(tmp_path, make_scenes, write_chain, read):
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    threads = run_chain(load_config(chain, {"outputs.directory": "threads"}))
    processes = run_chain(load_config(chain, {"outputs.directory": "processes",
                                              "engine": {"scheduler": "processes", "workers": 2, "chunk": 16}}))
    assert threads.ok and processes.ok
    for name in ("line0", "line1"):
        a, b = (read(tmp_path / folder / f"{name}_brdf.tif")[0] for folder in ("threads", "processes"))
        np.testing.assert_array_equal(a, b)
    assert [r["qa"] for r in threads.scenes] == [r["qa"] for r in processes.scenes]


def test_a_processes_engine_fits_the_classes_in_its_workers(tmp_path, make_scenes, write_chain, monkeypatch):
    # A chain that runs its scenes in processes fits its classes in as many (brdfcorr.tasks.pool;
    # that a pool gives the same fits: tests/fit/test_classfit.py); other engines fit in the run's
    # process. The pool is recorded here and not started.
    import contextlib

    import brdfcorr.tasks.fit
    from brdfcorr.chain.config_outputs import EngineConfig
    from brdfcorr.chain.run import _fit_workers

    make_scenes(tmp_path, count=1, ny=48, nx=64)
    chain = write_chain(tmp_path, steps={"fit": {"source": "imagery", "max_samples": 1000, "min_samples": 100}})
    pools = []
    monkeypatch.setattr(brdfcorr.tasks.fit, "process_pool", lambda workers, modules: pools.append(workers) or contextlib.nullcontext())
    report = run_chain(load_config(chain, {"engine": {"scheduler": "processes", "workers": 3}}))
    assert report.ok and pools == [3] and (tmp_path / "out" / "fitted_params.yaml").is_file()
    assert [_fit_workers(EngineConfig(scheduler=kind, workers=3)) for kind in ("threads", "synchronous")] == [1, 1]


def test_resume_redoes_outputs_of_another_parameter_table(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    assert run_chain(load_config(chain)).ok
    first = tmp_path / "out" / "line0_brdf.tif"
    stamp = first.stat().st_mtime_ns
    assert run_chain(load_config(chain)).n_skipped == 2  # same table: resume skips
    table = example_table()
    changed = table.with_class({**table[1].model_dump(exclude_none=True), "params": {
        **table[1].params, "w": 0.05}})
    changed.save(tmp_path / "params.yaml")
    report = run_chain(load_config(chain))
    assert report.n_ok == 2 and report.n_skipped == 0
    assert first.stat().st_mtime_ns != stamp


def _dry_run_actions(chain):
    """The output of ``brdfcorr run --dry-run`` and the plan it shows: {image: action}."""
    result = CliRunner().invoke(main, ["run", str(chain), "--dry-run"])
    assert result.exit_code == 0, result.output
    plan = plan_run(load_config(chain), require_inputs=False)
    return {str(scene.image): scene.action for scene in plan.scenes}, result.output


def test_dry_run_and_run_agree_on_stale_scenes(tmp_path, make_scenes, write_chain):
    """The parameter table changed after a run with ``outputs.existing: skip``: the dry run says
    what the run then does with every scene (redo outputs of another table, skip the others)."""
    make_scenes(tmp_path, count=3)
    chain = write_chain(tmp_path, outputs={"directory": "out", "naming": "{parent}_brdf.tif",
                                           "qa_naming": "{parent}_qa.tif", "existing": "skip"})
    assert run_chain(load_config(chain)).ok
    table = example_table()
    table.with_class({**table[1].model_dump(exclude_none=True), "params": {**table[1].params, "w": 0.05}}).save(
        tmp_path / "params.yaml")
    # line0's outputs as if made with the new table: complete and current, to be skipped
    new_table, _ = build_table(plan_run(load_config(chain)))
    with rasterio.open(tmp_path / "out" / "line0_brdf.tif", "r+") as dataset:
        dataset.update_tags(brdf_parameter_table_content=json.dumps(new_table.to_dict(), separators=(",", ":")))

    planned, output = _dry_run_actions(chain)
    assert "3 scenes: 2 to run, 1 to skip, 0 would fail" in output
    assert "outputs were made with another parameter table" in output
    report = run_chain(load_config(chain))
    done = {result["image"]: result["status"] for result in report.scenes}
    assert {image: {"run": "ok", "skip": "skipped"}[action] for image, action in planned.items()} == done
    assert sorted(done.values()) == ["ok", "ok", "skipped"]
    assert done[str(tmp_path / "scenes" / "line0" / "image.tif")] == "skipped"
    # Now every output is current: both skip everything.
    planned, output = _dry_run_actions(chain)
    assert set(planned.values()) == {"skip"} and "3 scenes: 0 to run, 3 to skip" in output
    assert run_chain(load_config(chain)).n_skipped == 3


def test_dry_run_and_run_agree_when_the_fit_makes_a_new_table(tmp_path, make_scenes, write_chain):
    """Complete outputs, but the fitted table of the earlier run is gone: the fit runs again and
    its table is not known before the run, so the dry run and the run both redo the scenes."""
    from brdfcorr.fit.measurements import write_measurements
    from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
    from brdfcorr.models.materials import load_material

    make_scenes(tmp_path, count=2)
    tile = load_material("roof_tile")
    write_measurements(tmp_path / "tile.csv", synthesize_measurements(
        tile.model, tile.params, *goniometer_angles(), relative_noise=0.01, seed=1))
    chain = write_chain(tmp_path, steps={"fit": {"source": "goniometer", "measurements": [
        {"file": "tile.csv", "class_id": 1, "name": "tile_fit", "fixed": {"k": 0.25}, "min_phi": 90}]}})
    assert run_chain(load_config(chain)).ok
    planned, output = _dry_run_actions(chain)
    assert set(planned.values()) == {"skip"}  # the fitted table is reused: outputs are current
    assert run_chain(load_config(chain)).n_skipped == 2
    os.unlink(tmp_path / "out" / "fitted_params.yaml")
    planned, output = _dry_run_actions(chain)
    assert set(planned.values()) == {"run"} and "the fit step makes a new parameter table" in output
    report = run_chain(load_config(chain))
    assert report.n_ok == 2 and report.n_skipped == 0 and "reused" not in report.fit


def test_sensor_angle_source_solar(tmp_path, make_scenes, write_chain, read):
    """The ``solar`` kind (sun from time and coordinates, constant view) gives the same output as
    a geotiff of the same angles computed beforehand with brdfcorr.io.sensors.read_angles."""
    import xarray as xr

    from brdfcorr.io import rasters as rio_io
    from brdfcorr.io.sensors import read_angles

    scenes = make_scenes(tmp_path, count=1)
    time, view = "2026-06-15T08:00:00+00:00", {"view_zenith": 20.0, "view_azimuth": 270.0}
    inputs = {"images": ["scenes/*/image.tif"], "classes": "{dir}/classes.tif",
              "angles": {"kind": "solar", "path": time, "options": view}}
    chain = write_chain(tmp_path, inputs=inputs, outputs={"directory": "solar", "naming": "{parent}.tif"})
    plan = plan_run(load_config(chain))
    assert plan.scenes[0].action == "run" and plan.scenes[0].angles == time  # a time, not a file
    report = run_chain(load_config(chain), plan=plan)
    assert report.ok, report.scenes

    paths = scenes["line0"][1]
    angles = read_angles("solar", time, like=rio_io.open_image(paths["image"]), **view)
    stack = xr.concat([angles[name] for name in ("sza", "saa", "vza", "vaa")], dim="band")
    stack.assign_coords(band=[1, 2, 3, 4]).rio.to_raster(tmp_path / "solar_angles.tif")
    inputs["angles"] = {"kind": "geotiff", "path": str(tmp_path / "solar_angles.tif")}
    chain = write_chain(tmp_path, inputs=inputs, outputs={"directory": "geotiff", "naming": "{parent}.tif"})
    assert run_chain(load_config(chain)).ok
    solar = read(tmp_path / "solar" / "line0.tif")[0]
    np.testing.assert_array_equal(solar, read(tmp_path / "geotiff" / "line0.tif")[0])
    assert np.isfinite(solar).all() and not np.allclose(solar, read(paths["image"])[0])  # corrected

    inputs["angles"] = {"kind": "envi_obs", "path": "{dir}/obs", "options": {"view_azimuth": "to_sensor"}}
    plan = plan_run(load_config(write_chain(tmp_path, inputs=inputs)))
    assert plan.scenes[0].action == "fail" and "missing input: angles" in plan.scenes[0].reason
    assert plan.scenes[0].angles == str(tmp_path / "scenes" / "line0" / "obs")


def test_progress_bar_and_events(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    events = []
    run_chain(load_config(chain), progress=lambda event, info: events.append((event, dict(info))))
    assert [(event, info.get("status")) for event, info in events if event != "chunks"] == [
        ("plan", None), ("scene", "ok"), ("scene", "ok")]
    # Between the scene events, the chunks of each scene's correction pass (threads engine): counts
    # that only grow, and a last event with every task done, before that scene's own event.
    for name in ("line0_image", "line1_image"):  # scene names: the shared stem qualified by its directory
        chunks = [info for event, info in events if event == "chunks" and info["scene"] == name]
        assert chunks, name
        done = [info["done"] for info in chunks]
        assert done == sorted(done) and chunks[0]["done"] == 0
        assert chunks[-1]["done"] == chunks[-1]["total"] > 0
    scene_events = [index for index, (event, _) in enumerate(events) if event == "scene"]
    assert all(events[index - 1][0] == "chunks" for index in scene_events)
    result = CliRunner().invoke(main, ["run", str(chain), "--overwrite", "--progress"])
    assert result.exit_code == 0
    assert "2/2" in result.stderr  # the overall bar counts scenes
    assert "task" in result.stderr  # and the bar of the scene's tasks shows below it


def test_chain_and_correct_choose_the_tile_size_by_the_same_band_count_rule(tmp_path, write_chain):
    # 100 bands: a 256 x 256 chunk of all bands would be 26 MB, so both choose 128 (auto_chunk:
    # the largest of 512, 256, 128, 64 whose chunk of all bands holds at most 16 MB as float32).
    import rasterio
    from click.testing import CliRunner

    from brdfcorr.cli import main

    wavelengths = tuple(np.linspace(480.0, 830.0, 100))
    scene = synthetic_scene(160, 160, wavelengths=wavelengths)
    paths = write_scene(tmp_path / "scenes" / "line0", scene)
    chain = write_chain(tmp_path, engine={"scheduler": "threads", "workers": 2}, steps={"correct": {"limits": None}})
    report = run_chain(load_config(chain))
    assert report.ok, report.scenes
    result = CliRunner().invoke(main, ["correct", str(paths["image"]), "--angles", str(paths["angles"]),
                                       "--classes", str(paths["classes"]), "--params", str(tmp_path / "params.yaml"),
                                       "-o", str(tmp_path / "correct.tif")])
    assert result.exit_code == 0, result.output
    for output in (tmp_path / "out" / "line0_brdf.tif", tmp_path / "correct.tif"):
        with rasterio.open(output) as dataset:
            assert dataset.block_shapes[0] == (128, 128), output


def test_scene_workers_end_with_the_run(tmp_path):
    # A worker process of the `processes` engine (of any pool of brdfcorr.tasks.pool) ends when the
    # run's process is killed (kill -9), although its parent is the fork server, which lives on while
    # the workers do.
    import signal
    import subprocess
    import textwrap
    import time

    script = tmp_path / "parent.py"
    script.write_text(textwrap.dedent("""
        import os, time
        from brdfcorr.tasks.pool import worker_processes

        def sleep():
            time.sleep(120)

        if __name__ == "__main__":
            with worker_processes(1, ()) as pool:
                worker = pool.submit(os.getpid).result()  # it has run its initializer: no waiting on a guess
                future = pool.submit(sleep)
                print(worker, flush=True)
                future.result()
    """))
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    workers = [int(pid) for pid in parent.stdout.readline().split()]
    assert workers
    parent.send_signal(signal.SIGKILL)
    parent.wait(timeout=30)
    alive = workers
    for _ in range(1500):  # a hang guard of at most 300 s of polling, not a measurement
        if not alive:
            break
        time.sleep(0.2)
        alive = [pid for pid in alive if _running(pid)]
    assert not alive, f"workers {alive} outlived the killed run"


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(")")[-1].split()[0] != "Z"  # a zombie has ended
    except FileNotFoundError:
        return False


def test_resume_redoes_a_scene_whose_input_gained_or_changed_a_sidecar(tmp_path, make_scenes, write_chain, read):
    # A .aux.xml beside an input carries what GDAL applies when it reads the raster (here an
    # offset of 0.05 on every band): the fingerprint holds the files GDAL reads with each input,
    # so a resumed run redoes the scene instead of keeping outputs of the old values.
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    assert run_chain(load_config(chain)).ok
    before, _ = read(tmp_path / "out" / "line0_brdf.tif")
    image = tmp_path / "scenes" / "line0" / "image.tif"
    bands = "".join(f'<PAMRasterBand band="{band}"><Offset>0.05</Offset><Scale>1</Scale></PAMRasterBand>'
                    for band in range(1, 5))
    (tmp_path / "scenes" / "line0" / "image.tif.aux.xml").write_text(f"<PAMDataset>{bands}</PAMDataset>")
    assert f"image {image} changed since it was written" in plan_run(load_config(chain)).scenes[0].reason
    report = run_chain(load_config(chain))
    assert sorted(result["status"] for result in report.scenes) == ["ok", "skipped"]
    after, _ = read(tmp_path / "out" / "line0_brdf.tif")
    assert np.nanmean(after - before) > 0.03  # the offset, times the correction factors (about 1)


def test_the_fingerprint_holds_an_envi_header_and_keeps_the_state_of_a_file_without_sidecars(tmp_path, make_scenes,
                                                                                          write_chain):
    # An ENVI image's header is read with it (scale, nodata, wavelengths): an edit of the .hdr
    # alone changes the image's fingerprint. A file with no sidecar keeps the state earlier
    # versions recorded (path, size, time, content), so their outputs stay current on resume.
    make_scenes(tmp_path, count=1)
    folder = tmp_path / "scenes" / "line0"
    rasterio.shutil.copy(folder / "image.tif", folder / "image.img", driver="ENVI")
    chain = write_chain(tmp_path, inputs__images=["scenes/*/image.img"])

    def inputs() -> dict:
        return json.loads(plan_run(load_config(chain)).scenes[0].fingerprint)["inputs"]

    before = inputs()
    assert "image.hdr" in before["image"]["sidecars"]
    assert not (folder / "angles.tif.aux.xml").exists()
    assert set(before["angles"]) == {"path", "size", "mtime_ns", "content"}
    header = folder / "image.hdr"
    header.write_text(header.read_text() + "data ignore value = 0\n")
    after = inputs()
    assert after["image"] != before["image"] and after["angles"] == before["angles"]
