"""The write path: one scene, or a chain, on a dask.distributed cluster gives the outputs of the
local run, and the local writer (one open handle, GDAL's compression threads) writes what
rioxarray's own writer writes."""

import errno
import json
import os
import re

import dask
import distributed
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.chain.config import load_config
from brdfcorr.chain.run import run_chain
from brdfcorr.cli import main
from brdfcorr.io import cluster, writer
from brdfcorr.testing import synthetic_scene


@pytest.fixture(autouse=True)
def patient_connections(monkeypatch):
    """Clusters in these tests are real and on this machine: under load, connecting to one may take
    longer than the library's timeout for unreachable schedulers (tests of that set their own)."""
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 300)


def test_distributed_matches_local(tmp_path, make_scenes, write_chain):
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


def test_unreachable_scheduler_is_a_clear_error(tmp_path, monkeypatch, make_scenes, write_chain):
    from brdfcorr.errors import InputError

    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 0.25)  # seconds; nothing listens on port 9: it fails anyway
    make_scenes(tmp_path, count=1)
    config = load_config(write_chain(tmp_path), {
        "engine": {"scheduler": "distributed", "address": "tcp://127.0.0.1:9"}})
    with dask.config.set({"distributed.comm.timeouts.connect": "0.25s"}):
        with pytest.raises(InputError, match="cannot reach the dask scheduler at tcp://127.0.0.1:9"):
            run_chain(config)
    assert not (tmp_path / "out" / "run_report.json").exists()


@pytest.fixture(scope="module")
def scene(tmp_path_factory, write_example_scene) -> dict:
    return write_example_scene(tmp_path_factory.mktemp("scene"), synthetic_scene(ny=96, nx=128), blocksize=32)


def _correct(scene, output, *extra, env=None):
    args = ["correct", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"], "--params",
            scene["params"], "-o", output, "--qa", output.with_name(f"{output.stem}_qa.tif"), "--chunk", 32,
            "--no-progress", *extra]
    return CliRunner().invoke(main, [str(a) for a in args], env=env)


def _assert_same_raster(a_path, b_path):
    with rasterio.open(a_path) as a, rasterio.open(b_path) as b:
        np.testing.assert_array_equal(a.read(), b.read())
        assert a.tags() == b.tags() and a.descriptions == b.descriptions
        assert {**a.profile, "nodata": 0} == {**b.profile, "nodata": 0}
        np.testing.assert_array_equal(a.nodatavals, b.nodatavals)  # NaN == NaN here


def test_one_scene_on_two_worker_processes_uses_both_and_matches_local(scene, tmp_path):
    local = _correct(scene, tmp_path / "local.tif")
    assert local.exit_code == 0, local.output
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as observer:
        workers = set(observer.scheduler_info()["workers"])
        with distributed.get_task_stream(client=observer) as stream:  # every task the scheduler runs
            remote = _correct(scene, tmp_path / "cluster.tif",
                              env={"DASK_SCHEDULER_ADDRESS": cluster.scheduler_address})
    assert remote.exit_code == 0, remote.output
    # 3 x 4 chunks of 32 pixels: the correction and the writes of both files ran on both processes.
    assert len(workers) == 2 and all(address.startswith("tcp://") for address in workers)
    writes = [task["worker"] for task in stream.data if "store" in str(task["key"])]
    assert len(writes) == 2 * 12 and set(writes) == workers
    assert {task["worker"] for task in stream.data} == workers
    for name in ("", "_qa"):
        _assert_same_raster(tmp_path / f"local{name}.tif", tmp_path / f"cluster{name}.tif")
    # The same summary (pixel counts, reference) but for the time taken.
    assert re.sub(r" in [0-9.]+ s", "", local.output).replace("local", "cluster") == re.sub(
        r" in [0-9.]+ s", "", remote.output)


def test_unreachable_scheduler_address_of_correct_is_one_clear_error(scene, tmp_path, monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 0.25)  # seconds; nothing listens on port 9: it fails anyway
    with dask.config.set({"distributed.comm.timeouts.connect": "0.25s"}):
        result = _correct(scene, tmp_path / "out.tif", "--scheduler", "tcp://127.0.0.1:9")
    assert result.exit_code == 2
    assert result.stderr.startswith("brdfcorr: error: --scheduler: cannot reach the dask scheduler at "
                                    "tcp://127.0.0.1:9"), result.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("compress", ["deflate", "none"])
def test_local_writer_writes_what_rioxarray_writes(scene, tmp_path, compress):
    """One open handle with GDAL's compression threads; the reference is rioxarray's own writer
    (a reopened file per chunk under a lock) with the same creation options."""
    import rioxarray

    array = rioxarray.open_rasterio(scene["image"], chunks={"x": 32, "y": 32}, masked=True)
    array = array.rio.write_nodata(np.nan, encoded=True)
    array.attrs["long_name"] = tuple(f"band {n}" for n in range(1, array.sizes["band"] + 1))
    writer.write_rasters({tmp_path / "ours.tif": array}, geotiff=writer.GeoTiffOutput(compress=compress, blocksize=32),
                         tags={"origin": "test"}, scheduler="threads", num_workers=2)
    options = writer._write_options(compress, 32, array)
    array.rio.to_raster(tmp_path / "rioxarray.tif", tags={"origin": "test"}, lock=True, **options)
    _assert_same_raster(tmp_path / "ours.tif", tmp_path / "rioxarray.tif")
    with rasterio.open(tmp_path / "ours.tif") as written:
        assert written.profile["compress" if compress != "none" else "tiled"] == (compress if compress != "none" else True)
        assert written.block_shapes == [(32, 32)] * written.count


@pytest.mark.parametrize("cog", [False, True])
def test_local_writer_disk_full_leaves_nothing(scene, tmp_path, monkeypatch, cog):
    """GDAL's writes fail with ENOSPC after two chunks, as on a full disk: one OutputError naming
    the targets, and no file left (the open handle is closed, the temporary files removed)."""
    original, calls = rasterio.io.DatasetWriter.write, []

    def fills_up(self, *args, **kwargs):
        calls.append(1)
        if len(calls) > 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(rasterio.io.DatasetWriter, "write", fills_up)
    (tmp_path / "out").mkdir()
    result = _correct(scene, tmp_path / "out" / "corrected.tif", *(["--cog"] if cog else []))
    assert len(calls) > 2, "the simulated disk never filled"
    assert result.exit_code == 2
    assert re.match(r"brdfcorr: error: cannot write \S*corrected\.tif, \S*corrected_qa\.tif: No space left on "
                    r"device", result.stderr), result.stderr
    assert list((tmp_path / "out").iterdir()) == []


def test_cog_keeps_the_predictor(scene, tmp_path):
    """GDAL's COG driver writes no predictor unless asked: the copy asks for the GeoTIFF's own."""
    assert _correct(scene, tmp_path / "cog.tif", "--cog").exit_code == 0
    with rasterio.open(tmp_path / "cog.tif") as cog, rasterio.open(tmp_path / "cog_qa.tif") as qa:
        assert cog.tags(ns="IMAGE_STRUCTURE")["PREDICTOR"] == "3"  # floating point
        assert qa.tags(ns="IMAGE_STRUCTURE")["PREDICTOR"] == "2"  # horizontal differencing
        assert cog.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"


def test_a_workers_read_failure_handed_back_plain_is_one_clear_error():
    # dask.distributed cannot send rasterio's chained GDAL errors back from a worker: it hands back
    # a plain Exception holding their repr (as a real cluster gave, by hand: exit 1, "internal
    # error"). Read passes and the writer turn it into the InputError of a local read.
    from brdfcorr.errors import InputError
    from brdfcorr.io.commit import remote_failure
    from brdfcorr.io.opening import reading

    handed_back = Exception("RasterioIOError('Read failed. See previous exception for details.')")
    assert "a read failed (on a dask.distributed worker" in remote_failure(handed_back)
    assert "s1/angles.tif: No such file" in remote_failure(Exception("RasterioIOError('s1/angles.tif: No such file')"))
    assert remote_failure(Exception("something else")) is None and remote_failure(ValueError("x")) is None
    with pytest.raises(InputError, match=r"^cannot read image a.tif: a read failed \(on a dask.distributed"):
        with reading("image a.tif"):
            raise handed_back
    with pytest.raises(Exception, match="something else"):
        with reading("image a.tif"):
            raise Exception("something else")


def test_rasters_are_read_by_absolute_path(scene, tmp_path, monkeypatch):
    # A scene opened by relative path is read lazily from another working directory, as a
    # dask.distributed worker started elsewhere reads it.
    from brdfcorr.io.opening import open_raster

    monkeypatch.chdir(scene["image"].parent)
    array = open_raster(scene["image"].name, "image", {"band": -1, "y": 16, "x": 16}, masked=True)
    assert array.encoding["source"] == scene["image"].name  # messages name the path as given
    monkeypatch.chdir(tmp_path)
    with rasterio.open(scene["image"]) as dataset:
        np.testing.assert_array_equal(array.values, dataset.read(masked=True).filled(np.nan))
