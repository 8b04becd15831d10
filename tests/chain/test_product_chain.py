"""A chain over product folders: ``inputs.images: ["tiles/*.SAFE"]`` runs every folder as one scene,
its bands, scaling and angles from the product, as ``brdfcorr fit-classes`` and ``brdfcorr correct``
take the folders. The chain's fitted table and corrected dates are compared value for value with
those commands' over the same folders; the bands' scratch stacks live only for the run; a resumed
run skips the dates and redoes the one whose band file changed."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import rioxarray
import yaml

from brdfcorr.chain.config import load_config
from brdfcorr.chain.plan import plan_run
from brdfcorr.chain.products import SCRATCH_PREFIX
from brdfcorr.chain.run import run_chain
from brdfcorr.params import ParameterTable
from brdfcorr.testing import write_sentinel2_series, write_stac_item

FIT = {"model": "ross_thick_li_sparse", "levels": "pixel", "block_size": 8, "min_samples": 50}
CHAIN = {
    "inputs": {"images": ["tiles/*.SAFE"], "classes": "{dir}/classes.tif"},
    "reference": {"sza": 45.0},
    "steps": {"fit": {"source": "imagery", **FIT}, "correct": {}},
    "outputs": {"directory": "out", "naming": "{stem}_nbar.tif", "existing": "skip"},
    "engine": {"scheduler": "synchronous"},
}


@pytest.fixture(scope="module")
def tiles(tmp_path_factory) -> Path:
    """Three dates of one synthetic tile (a known RTLSR shape in the 20 m bands) and its class map."""
    root = tmp_path_factory.mktemp("product_chain")
    write_sentinel2_series(root / "tiles", dates=3)
    return root


def _chain(root: Path, **inputs) -> Path:
    """A copy of ``tiles`` with the chain config (``inputs`` added to its inputs) in ``root``."""
    document = {**CHAIN, "inputs": {**CHAIN["inputs"], **inputs}}
    path = root / "chain.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


@pytest.fixture(scope="module")
def ran(tiles, tmp_path_factory) -> SimpleNamespace:
    """The chain run once over a copy of ``tiles`` (``root``: its tiles and ``out``), its system
    temporary folder a folder of its own: the ``report`` and the scratch ``stacks`` left there after
    the run. Read-only: the reference of the tests that compare other runs with it."""
    root = tmp_path_factory.mktemp("ran")
    shutil.copytree(tiles / "tiles", root / "tiles")
    scratch = root / "system_tmp"
    scratch.mkdir()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(tempfile, "tempdir", str(scratch))
        report = run_chain(_chain(root))
    return SimpleNamespace(root=root, report=report, stacks=_stacks(scratch))


@pytest.fixture
def copy(tiles, tmp_path) -> Path:
    shutil.copytree(tiles / "tiles", tmp_path / "tiles")
    return tmp_path


@pytest.fixture
def scratch(tmp_path, monkeypatch) -> Path:
    """The system's temporary folder for this test: where the run's scratch stacks go."""
    folder = tmp_path / "system_tmp"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def _stacks(folder: Path) -> list[Path]:
    return [path for path in folder.iterdir() if path.name.startswith(SCRATCH_PREFIX)]


def test_chain_over_products_is_fit_classes_and_correct_of_the_folders(ran, tmp_path, scratch, invoke):
    report, copy = ran.report, ran.root  # the chain run over the folders (read here, never changed)
    assert report.ok, report.scenes
    folders = sorted((copy / "tiles").glob("*.SAFE"))
    assert [result["image"] for result in report.scenes] == [str(folder) for folder in folders]
    assert not ran.stacks  # the scratch stacks were removed with the run

    by_hand = tmp_path / "by_hand"
    code, stderr = invoke(["fit-classes", *folders, "--classes", copy / "tiles" / "classes.tif",
                           "--model", "ross_thick_li_sparse", "--levels", "pixel", "--block-size", "8",
                           "--min-samples", "50", "-o", by_hand / "table.yaml"])
    assert code == 0, stderr
    chain_table = ParameterTable.load(copy / "out" / "fitted_params.yaml")
    assert chain_table == ParameterTable.load(by_hand / "table.yaml")
    # the fit's record names the folders, as fit-classes' does, not the run's scratch stacks
    assert folders[0].name in (copy / "out" / "fitted_params.yaml").read_text()
    assert ".vrt" not in (copy / "out" / "fitted_params.yaml").read_text()
    assert [entry.id for entry in chain_table.classes] == [1, 2]
    for folder in folders:
        output = by_hand / f"{folder.stem}_nbar.tif"
        code, stderr = invoke(["correct", folder, "--classes", copy / "tiles" / "classes.tif", "--params",
                               by_hand / "table.yaml", "--ref-sza", "45", "-o", output, "--no-progress"])
        assert code == 0, stderr
        chain = rioxarray.open_rasterio(copy / "out" / f"{folder.stem}_nbar.tif").values
        cli = rioxarray.open_rasterio(output).values
        np.testing.assert_array_equal(chain, cli)  # value for value
        assert np.isfinite(chain).mean() > 0.9


def test_a_resumed_run_skips_the_dates_and_refits_when_a_band_changed(copy, scratch):
    config = _chain(copy)
    assert run_chain(config).ok
    # The fit is reused, so the table is known before the run: every date is skipped.
    assert [scene.action for scene in plan_run(load_config(config)).scenes] == ["skip"] * 3
    band = sorted((copy / "tiles").glob("*.SAFE"))[1].glob("GRANULE/*/IMG_DATA/R20m/*_B8A_20m.jp2")
    band = next(band)
    stat = band.stat()
    os.utime(band, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    # A band the fit read changed: the table is fitted again, and every date corrected with it.
    plan = plan_run(load_config(config))
    assert not plan.reuses_fit and [scene.action for scene in plan.scenes] == ["run"] * 3
    report = run_chain(config)
    assert [result["status"] for result in report.scenes] == ["ok"] * 3
    assert not _stacks(scratch)


def test_a_resumed_run_redoes_a_date_whose_scaling_was_edited(copy, scratch):
    """MTD_MSIL2A.xml holds the scaling (BOA_ADD_OFFSET): an offset edited in place, with the
    file's size and time kept, was not seen and the date kept its output of the old offset."""
    config = _chain(copy)
    assert run_chain(config).ok
    metadata = sorted((copy / "tiles").glob("*.SAFE"))[1] / "MTD_MSIL2A.xml"
    text, stat = metadata.read_text(), metadata.stat()
    edited = text.replace(">-1000<", ">-1200<")
    assert edited != text and len(edited) == len(text)
    metadata.write_text(edited)
    os.utime(metadata, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    actions = [(scene.name, scene.action) for scene in plan_run(load_config(config)).scenes]
    assert [action for _, action in actions].count("run") >= 1
    assert dict(actions)[sorted(name for name, _ in actions)[1]] == "run"


def test_validate_says_a_product_without_a_band_is_not_ready(copy):
    """validate --strict said "valid; 3 scenes found" and run then failed the date (exit 3)."""
    from click.testing import CliRunner

    from brdfcorr.cli import main

    config = _chain(copy)
    band = next(sorted((copy / "tiles").glob("*.SAFE"))[1].glob("GRANULE/*/IMG_DATA/R20m/*_B8A_20m.jp2"))
    band.unlink()
    result = CliRunner().invoke(main, ["validate", str(config)])
    assert result.exit_code == 0, result.output
    assert "not ready to run, an input is missing: scene " in result.stdout
    strict = CliRunner().invoke(main, ["validate", "--strict", str(config)])
    assert strict.exit_code == 2, strict.output
    assert "would fail: " in strict.stderr and "no image file of band B8A" in strict.stderr


def test_the_plan_shows_the_products_and_their_files(copy):
    plan = plan_run(load_config(_chain(copy)), require_inputs=False)
    folder = sorted((copy / "tiles").glob("*.SAFE"))[0]
    scene = plan.describe()["scenes"][0]
    assert scene["image"] == str(folder) and scene["product"] is True
    assert scene["angles"]["kind"] == "sentinel2" and scene["angles"]["source"].endswith("MTD_TL.xml")
    roles = [role for role, _ in plan.scenes[0].inputs()]
    assert roles[0] == "product" and "band B8A" in roles and "quality mask" in roles


def test_outputs_never_overwrite_a_products_file(copy, invoke):
    folder = sorted((copy / "tiles").glob("*.SAFE"))[0]
    metadata = next(folder.glob("GRANULE/*/MTD_TL.xml"))  # the angle metadata, one of the product's files
    document = {**CHAIN, "outputs": {**CHAIN["outputs"], "directory": str(metadata.parent.relative_to(copy)),
                                     "report": "MTD_TL.xml"}}
    (copy / "chain.yaml").write_text(yaml.safe_dump(document))
    before = metadata.read_bytes()
    code, stderr = invoke(["run", copy / "chain.yaml"])
    assert code == 2 and len(stderr.strip().splitlines()) == 1
    assert "would overwrite an input" in stderr and f"angle metadata of scene {folder.stem}" in stderr
    assert metadata.read_bytes() == before


@pytest.mark.parametrize("inputs, named", [
    ({"angles": {"kind": "sentinel2", "path": "{dir}/x.xml"}}, "inputs.angles"),
    ({"scale": 0.0001}, "inputs.scale"),
    ({"wavelengths": [490.0, 560.0]}, "inputs.wavelengths"),
])
def test_products_refuse_what_they_bring_themselves(copy, invoke, inputs, named):
    code, stderr = invoke(["run", _chain(copy, **inputs)])
    lines = stderr.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert f"{named}: product folders bring their own angles, scaling and wavelengths" in lines[0]
    assert not (copy / "out").exists()


def test_a_mix_of_products_and_files_and_files_without_angles_are_refused(copy, invoke):
    (copy / "tiles" / "image.tif").write_bytes((copy / "tiles" / "classes.tif").read_bytes())
    code, stderr = invoke(["run", _chain(copy, images=["tiles/*.SAFE", "tiles/image.tif"])])
    assert code == 2 and "not both" in stderr and len(stderr.strip().splitlines()) == 1
    code, stderr = invoke(["run", _chain(copy, images=["tiles/image.tif"])])
    assert code == 2 and "inputs.angles is missing" in stderr and len(stderr.strip().splitlines()) == 1


def test_the_scratch_stacks_are_removed_after_a_failing_run(copy, scratch, monkeypatch):
    import brdfcorr.chain.run as run

    def fail(*args, **kwargs):
        assert _stacks(scratch), "the stacks exist while the run works"
        raise RuntimeError("a failure in the middle of the run")

    monkeypatch.setattr(run, "build_table", fail)
    with pytest.raises(RuntimeError, match="middle of the run"):
        run_chain(_chain(copy))
    assert not _stacks(scratch)


def test_a_folder_that_is_no_product_fails_its_scene_and_the_others_go_on(copy, scratch):
    (copy / "tiles" / "S2B_MSIL2A_broken.SAFE").mkdir()  # matched by the glob, holds no product
    report = run_chain(_chain(copy))
    status = {Path(result["image"]).name: result["status"] for result in report.scenes}
    assert status.pop("S2B_MSIL2A_broken.SAFE") == "failed" and set(status.values()) == {"ok"}
    failed = next(result for result in report.scenes if result["status"] == "failed")
    assert "S2B_MSIL2A_broken.SAFE" in failed["error"]
    assert len(report.fit["scenes_left_out"]) == 1  # the fit over the three dates that are products
    assert not _stacks(scratch)


def test_strata_derived_from_each_products_stack(copy, scratch):
    """``steps.strata`` reads each product's stacked bands (not the folder: no raster), with their
    scaling and band centres (NDVI needs red and NIR): every date gets a class map on the products'
    grid, split at its median NDVI into two strata."""
    document = {**CHAIN, "inputs": {"images": ["tiles/*.SAFE"]},
                "steps": {"strata": {"percentiles": [50]}, "fit": {"source": "imagery", **FIT, "allow_uncorrected": True},
                          "correct": {}}}
    (copy / "chain.yaml").write_text(yaml.safe_dump(document))
    report = run_chain(copy / "chain.yaml")
    assert report.ok, report.scenes
    classes = rioxarray.open_rasterio(copy / "tiles" / "classes.tif")
    for folder in sorted((copy / "tiles").glob("*.SAFE")):
        strata = rioxarray.open_rasterio(copy / "out" / f"{folder.stem}_strata.tif")
        assert strata.shape == classes.shape and strata.rio.transform() == classes.rio.transform()
        assert {1, 2} <= set(np.unique(strata.values))


def test_stac_items_run_as_their_folders(ran, copy, scratch):
    """Sentinel-2 STAC items with local assets (``tiles/*.json``) are products as the SAFE folders
    are: the item of each folder reads the same pixels, scaling and angles, so the chain over the
    items fits the same table and writes the same dates as the chain over the folders (``ran``: the
    chain over another copy of the same folders)."""
    items = [write_stac_item(folder) for folder in sorted((copy / "tiles").glob("*.SAFE"))]
    assert ran.report.ok
    document = {**CHAIN, "inputs": {**CHAIN["inputs"], "images": ["tiles/*.json"]},
                "outputs": {**CHAIN["outputs"], "directory": "items_out"}}
    (copy / "items.yaml").write_text(yaml.safe_dump(document))
    report = run_chain(copy / "items.yaml")
    assert report.ok, report.scenes
    assert [result["image"] for result in report.scenes] == [str(item) for item in items]
    tables = [ParameterTable.load(root / "fitted_params.yaml") for root in (copy / "items_out", ran.root / "out")]
    # the same fit (its record names what it read: the items, or the folders)
    assert [(entry.id, entry.model, entry.params) for entry in tables[0].classes] == [
        (entry.id, entry.model, entry.params) for entry in tables[1].classes]
    for item, folder in zip(items, sorted((copy / "tiles").glob("*.SAFE"))):
        np.testing.assert_array_equal(rioxarray.open_rasterio(copy / "items_out" / f"{item.stem}_nbar.tif").values,
                                      rioxarray.open_rasterio(ran.root / "out" / f"{folder.stem}_nbar.tif").values)
    assert not _stacks(scratch)


def test_process_workers_read_the_runs_stacks(ran, copy, scratch):
    """With ``engine.scheduler: processes`` the scenes are corrected in worker processes,
    which read the stacks of the run's scratch folder: the same dates as in the calling thread
    (``ran``: the chain over another copy of the same folders)."""
    assert ran.report.ok
    document = {**CHAIN, "outputs": {**CHAIN["outputs"], "directory": "processes"},
                "engine": {"scheduler": "processes", "workers": 2, "threads_per_worker": 1}}
    (copy / "processes.yaml").write_text(yaml.safe_dump(document))
    report = run_chain(copy / "processes.yaml")
    assert report.ok, report.scenes
    for folder in sorted((copy / "tiles").glob("*.SAFE")):
        name = f"{folder.stem}_nbar.tif"
        np.testing.assert_array_equal(rioxarray.open_rasterio(copy / "processes" / name).values,
                                      rioxarray.open_rasterio(ran.root / "out" / name).values)
    assert not _stacks(scratch)


def test_each_product_is_identified_once_per_run(copy, scratch, identified):
    """The plan finds each product (its metadata read: MTD_MSIL2A.xml, the files, the angle source)
    and the run stacks its bands from the product the scene carries: one identification per folder
    and run (issue 42), counted where every way of finding a SAFE passes (``identified``)."""
    report = run_chain(_chain(copy))
    assert report.ok, report.scenes
    assert identified == {folder.name: 1 for folder in (copy / "tiles").glob("*.SAFE")}
    assert len(identified) == 3


def test_a_product_chain_names_a_coefficient_set_as_nbar_does(copy, scratch, invoke):
    # parameters.table: roy2017 was read as a file beside the config ("does not exist", exit 2).
    document = {"inputs": {"images": ["tiles/*.SAFE"]}, "parameters": {"table": "roy2017"},
                "reference": {"sza": 45.0}, "steps": {"correct": {}},
                "outputs": {"directory": "out", "naming": "{stem}_nbar.tif"}, "engine": {"scheduler": "synchronous"}}
    (copy / "chain.yaml").write_text(yaml.safe_dump(document))
    assert "coefficient set roy2017" in plan_run(load_config(copy / "chain.yaml")).table_sources
    report = run_chain(copy / "chain.yaml")
    assert report.ok, report.scenes
    for folder in sorted((copy / "tiles").glob("*.SAFE")):
        code, stderr = invoke(["nbar", folder, "--ref-sza", "45", "-o", copy / f"{folder.stem}_cli.tif"])
        assert code == 0, stderr
        np.testing.assert_array_equal(rioxarray.open_rasterio(copy / "out" / f"{folder.stem}_nbar.tif").values,
                                      rioxarray.open_rasterio(copy / f"{folder.stem}_cli.tif").values)
