"""The chain's assess step over a cluster layer (``steps.assess.clusters``, issue 40): its report's
slopes' 1-sigma is the one ``brdfcorr assess --clusters`` gives on the same files."""

import json
import shutil

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from brdfcorr.chain.config import ConfigError, load_config
from brdfcorr.chain.run import plan_run, run_chain
from brdfcorr.cli import main
from brdfcorr.errors import InputError
from brdfcorr.testing import georeference


def _errors(report: dict) -> dict:
    return {entry["id"]: entry["after"]["relative_slope_error"] for entry in report["view_angles"]["classes"]}


@pytest.mark.filterwarnings("ignore:the slopes. 1-sigma grows")
def test_the_chains_assess_clusters_give_the_commands_sigma(tmp_path, make_scenes, write_chain):
    scene, paths = make_scenes(tmp_path, count=1)["line0"]
    shape = scene["classes"].shape
    # Band 2 holds the ids (stripes of 4 columns, a detector's); band 1 one id everywhere.
    stripes = np.broadcast_to(np.arange(shape[1]) // 4 + 100, shape)
    layer = georeference(xr.DataArray(np.stack([np.zeros(shape), stripes]).astype(np.int32), dims=("band", "y", "x"),
                                      coords={"band": [1, 2]}))
    layer.rio.to_raster(paths["image"].parent / "ids.tif")
    chain = write_chain(tmp_path, steps={"correct": {"limits": None},
                                         "assess": {"clusters": "{dir}/ids.tif", "cluster_band": 2, "block_size": 8}})
    report = run_chain(load_config(chain))
    assert report.ok, report.scenes
    outputs = report.scenes[0]["outputs"]
    from_chain = json.loads(open(outputs["assess"]).read())
    assert from_chain["view_angles"]["errors"]["clusters"] == "the cluster layer's ids"
    assert from_chain["inputs"]["clusters"].endswith("ids.tif band 2")
    common = ["assess", str(paths["image"]), outputs["corrected"], "--classes", str(paths["classes"]), "--angles",
              str(paths["angles"]), "--block-size", "8"]
    found = {}
    for name, extra in (("clusters", ["--clusters", str(paths["image"].parent / "ids.tif"), "--cluster-band", "2"]),
                        ("blocks", [])):
        result = CliRunner().invoke(main, [*common, *extra, "-o", str(tmp_path / f"{name}.json")])
        assert result.exit_code == 0, result.output
        found[name] = json.loads((tmp_path / f"{name}.json").read_text())
    chain_errors, command_errors = _errors(from_chain), _errors(found["clusters"])
    assert chain_errors.keys() == command_errors.keys()
    for class_id, values in command_errors.items():
        np.testing.assert_allclose(chain_errors[class_id], values, rtol=1e-9)
    # The stripes are what the 1-sigma follows: the blocks' differs.
    assert not np.allclose(_errors(found["blocks"])[1], command_errors[1], rtol=1e-3)


def test_the_clusters_key_is_a_name_pattern(tmp_path, write_chain):
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}, "assess": {"clusters": "{nope}/ids.tif"}})
    with pytest.raises(ConfigError, match="nope"):
        load_config(chain)


@pytest.mark.filterwarnings("ignore:the slopes. 1-sigma grows")
def test_a_resumed_run_redoes_a_scene_whose_cluster_layer_changed(tmp_path, make_scenes, write_chain):
    # A resumed run redid nothing when the cluster layer changed (it was no input of the scene's
    # fingerprint).
    scene, paths = make_scenes(tmp_path, count=1)["line0"]
    shape = scene["classes"].shape
    ids = paths["image"].parent / "ids.tif"

    def write_ids(width: int) -> None:
        stripes = np.broadcast_to(np.arange(shape[1]) // width + 100, shape)[None].astype(np.int32)
        georeference(xr.DataArray(stripes, dims=("band", "y", "x"), coords={"band": [1]})).rio.to_raster(ids)

    write_ids(4)
    steps = {"correct": {"limits": None}, "assess": {"clusters": "{dir}/ids.tif", "block_size": 8}}
    chain = write_chain(tmp_path, steps=steps)
    assert run_chain(load_config(chain)).ok
    assert run_chain(load_config(chain)).n_skipped == 1
    write_ids(8)  # stripes of 8 columns: another 1-sigma
    assert f"cluster layer {ids} changed since it was written" in plan_run(load_config(chain)).scenes[0].reason
    report = run_chain(load_config(chain))
    assert report.n_ok == 1 and report.n_skipped == 0


def test_an_output_of_the_run_may_not_overwrite_the_cluster_layer(tmp_path, make_scenes, write_chain):
    # The output guard checks every output against the files the scenes read, the cluster layer
    # of steps.assess.clusters among them: a QA raster named as the layer is refused before any
    # scene runs (the plan), not written over it.
    _, paths = make_scenes(tmp_path, count=1)["line0"]
    (tmp_path / "out").mkdir()
    shutil.copy(paths["classes"], tmp_path / "out" / "line0_qa.tif")
    chain = write_chain(tmp_path, steps={"correct": {"limits": None, "qa": True},
                                         "assess": {"clusters": "out/{parent}_qa.tif"}})
    with pytest.raises(InputError, match=r"would overwrite an input \(the same file as the cluster layer of scene"):
        plan_run(load_config(chain))
