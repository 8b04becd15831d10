"""The same chain on a dask.distributed cluster gives the same outputs as the local run."""

import json

import dask
import numpy as np
import pytest
import rasterio

from brdfcorr.workflow.chain import run_chain
from brdfcorr.workflow.config import load_config

distributed = pytest.importorskip("distributed")

from test_pipeline import make_scenes, write_chain  # noqa: E402


def test_distributed_matches_local(tmp_path):
    make_scenes(tmp_path, count=3)
    chain = write_chain(tmp_path, steps={"correct": {"limits": [0.95, 1.05]}, "quicklook": {}})
    local = run_chain(load_config(chain, {"outputs.directory": "local"}))
    schedulers = []  # this process's dask setting while scene tasks run in it (a worker thread each)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        remote = run_chain(load_config(chain, {
            "outputs.directory": "cluster",
            "engine": {"scheduler": "distributed", "address": cluster.scheduler_address,
                       "threads_per_worker": 2, "chunk": 16},
        }), progress=lambda event, info: schedulers.append(dask.config.get("scheduler", None)))
    assert local.ok and remote.ok, remote.scenes
    # Scene tasks name their scheduler in each computation: nothing process-wide to set or undo.
    assert schedulers == [None] * 4 and dask.config.get("scheduler", None) is None
    for name in ("line0", "line1", "line2"):
        for suffix in ("brdf", "qa"):
            with rasterio.open(tmp_path / "local" / f"{name}_{suffix}.tif") as a, \
                    rasterio.open(tmp_path / "cluster" / f"{name}_{suffix}.tif") as b:
                np.testing.assert_array_equal(a.read(), b.read())
                assert a.profile.keys() == b.profile.keys()
                assert all(a.profile[key] == b.profile[key] for key in a.profile if key != "nodata")
                assert a.nodatavals == b.nodatavals or np.isnan(a.nodata) and np.isnan(b.nodata)
    report = json.loads((tmp_path / "cluster" / "run_report.json").read_text())
    assert report["engine"]["scheduler"] == "distributed" and "distributed" in report["versions"]
    assert [s["qa"] for s in report["scenes"]] == [s["qa"] for s in local.scenes]
    assert any(s["qa"]["limited"] for s in local.scenes)  # the limits were exercised


def test_unreachable_scheduler_is_a_clear_error(tmp_path):
    from brdfcorr.errors import InputError

    make_scenes(tmp_path, count=1)
    config = load_config(write_chain(tmp_path), {
        "engine": {"scheduler": "distributed", "address": "tcp://127.0.0.1:9"}})
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(InputError, match="cannot reach the dask scheduler at tcp://127.0.0.1:9"):
            run_chain(config)
    assert not (tmp_path / "out" / "run_report.json").exists()
