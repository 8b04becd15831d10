"""Sensor products given by relative paths are read by absolute ones, as rasters are
(tests/workflow/test_distributed.py::test_rasters_are_read_by_absolute_path): a scene opened lazily
in one folder is computed in another with no file open, as a dask.distributed worker started
elsewhere computes it, and reads the values opened by absolute path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

from brdfcorr.chain.demo import demo_scene
from brdfcorr.io.scene import SceneSources, open_scene
from brdfcorr.testing import write_emit_granules, write_envi_line, write_landsat_c2, write_neon_reflectance

LINE = "ang20260615t080000"
HLS = "HLS.S30.T33UUP.2023166T101559.v2.0"


@pytest.fixture(scope="module")
def products(tmp_path_factory) -> Path:
    """One small scene as each product, in ``data/`` of the folder returned."""
    root = tmp_path_factory.mktemp("relative")
    scene = demo_scene(rows=24)
    write_envi_line(root / "data" / "envi", scene, LINE)
    write_neon_reflectance(root / "data" / "neon", scene)
    write_emit_granules(root / "data" / "emit", scene)
    write_landsat_c2(root / "data" / "landsat", size=16, angle_bands=True)
    _write_hls(root / "data" / "hls" / HLS)
    return root


def _write_hls(folder: Path) -> None:
    """An HLS v2.0 S30 granule of 5 x 6 pixels: B04, B8A and an Fmask with a cloudy first row (as
    tests/workflow/test_nbar_hls.py writes it)."""
    folder.mkdir(parents=True)
    profile = dict(driver="GTiff", width=6, height=5, count=1, crs="EPSG:32633",
                   transform=Affine(30.0, 0, 300000.0, 0, -30.0, 5000040.0))
    for band, value in (("B04", 1200), ("B8A", 3100)):
        with rasterio.open(folder / f"{HLS}.{band}.tif", "w", dtype="int16", nodata=-9999, **profile) as dataset:
            dataset.write(np.full((5, 6), value, dtype="int16") + np.arange(6, dtype="int16"), 1)
            dataset.update_tags(NBAR_SOLAR_ZENITH="38.4")
    fmask = np.zeros((5, 6), dtype="uint8")
    fmask[0] = 1 << 1  # cloud
    with rasterio.open(folder / f"{HLS}.Fmask.tif", "w", dtype="uint8", nodata=255, **profile) as dataset:
        dataset.write(fmask, 1)


def _scene(sources: SceneSources) -> dict:
    data = open_scene(sources, chunks=16)
    return {"reflectance": data.reflectance, **data.angles}


def _envi(data: Path) -> dict:
    return _scene(SceneSources(data / "envi" / f"{LINE}_rfl", None, data / "envi" / f"{LINE}_obs_ort",
                               angles_kind="envi_obs"))


def _envi_terrain(data: Path) -> dict:
    from brdfcorr.io.sensors.envi import read_envi_obs_terrain

    return dict(read_envi_obs_terrain(data / "envi" / f"{LINE}_obs_ort").data_vars)


def _neon(data: Path) -> dict:
    path = next((data / "neon").glob("*.h5"))  # relative where data is (globbed in the working folder)
    return _scene(SceneSources(path, None, path, angles_kind="neon"))


def _emit(data: Path) -> dict:
    image, obs = (next((data / "emit").glob(f"EMIT_{kind}_*.nc")) for kind in ("L2A_RFL", "L1B_OBS"))
    return _scene(SceneSources(image, None, obs, angles_kind="emit"))


def _landsat(data: Path) -> dict:
    folder = data / "landsat" / "LE07_L2SP_225078_20110306_20200910_02_T1"
    return _scene(SceneSources(folder / f"{folder.name}_SR_B4.TIF", None, folder, angles_kind="landsat"))


def _landsat_folder(data: Path) -> dict:
    from brdfcorr.io.sensors.folders import find_product, open_stack

    return {"stack": open_stack(find_product(data / "landsat" / "LE07_L2SP_225078_20110306_20200910_02_T1"),
                                chunks=16)}  # masked by its QA_PIXEL, read lazily


def _hls(data: Path) -> dict:
    from brdfcorr.io.sensors.hls import find_hls_granule
    from brdfcorr.tasks.hls import hls_sun_zenith_layers

    corrected, qa, _, _ = hls_sun_zenith_layers(find_hls_granule(data / "hls" / HLS), coefficients="roy2016",
                                                reference_sza=45.0)
    return {"corrected": corrected, "qa": qa}


def _as_a_worker_started_elsewhere(monkeypatch, folder: Path) -> None:
    """Work in ``folder`` with no file open (xarray's cache of open files emptied, its handles
    closed): as a dask.distributed worker started there, which opens each file by the path the
    graph holds."""
    from xarray.backends.file_manager import FILE_CACHE

    monkeypatch.chdir(folder)
    FILE_CACHE.clear()


@pytest.mark.parametrize("opened", [_envi, _envi_terrain, _neon, _emit, _landsat, _landsat_folder, _hls],
                         ids=["envi_obs", "envi_obs_terrain", "neon", "emit", "landsat_angle_bands",
                              "landsat_folder_mask", "hls_granule"])
def test_a_product_given_by_relative_paths_is_read_from_another_folder(opened, products, tmp_path, monkeypatch):
    monkeypatch.chdir(products)
    lazy = opened(Path("data"))  # relative paths, opened lazily here
    expected = {name: layer.values for name, layer in opened(products / "data").items()}
    assert lazy and set(lazy) == set(expected)
    _as_a_worker_started_elsewhere(monkeypatch, tmp_path)
    for name, layer in lazy.items():
        values = layer.values  # the lazy reads, in the other folder
        assert np.isfinite(values).any() if values.dtype.kind == "f" else values.size, name
        np.testing.assert_array_equal(values, expected[name], err_msg=name)
