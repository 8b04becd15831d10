"""Chunks aligned to the input's tiles (issue 28), GDAL's block cache bounded from the first read,
and progress bars from the first pass of the commands that read whole images."""

from __future__ import annotations

import math

import dask.callbacks
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from brdfcorr.cli import main
from brdfcorr.defaults import CHUNK_RANGE
from brdfcorr.io import rasters, scale_check
from brdfcorr.io.rasters import (
    CHUNK_TARGET,
    MAX_GDAL_CACHE,
    MIN_GDAL_CACHE,
    Layout,
    auto_chunk,
    cache_bytes,
    choose_chunk,
    image_layout,
)
from brdfcorr.testing import synthetic_scene


def _check_chunk(layout: Layout, chunk: int) -> None:
    """The properties of a chosen chunk: a GeoTIFF tile size within the byte target; a multiple of
    the input's blocks (tiles in y and x, strips in y) where one block of all bands fits the
    target; else (too large a block) a cache that holds the full-width rows of blocks one row of
    chunks touches (up to its bound), so that no block is decompressed twice."""
    low, high = CHUNK_RANGE
    assert chunk % 16 == 0 and low <= chunk <= high
    rows = layout.block_rows if layout.block_rows < layout.height else 1
    columns = layout.block_columns if layout.block_columns < layout.width else 1
    unit = math.lcm(16, rows, columns)
    chunk_bytes = layout.bands * chunk * chunk * 4
    cache = cache_bytes(layout, chunk)
    assert MIN_GDAL_CACHE <= cache <= MAX_GDAL_CACHE
    assert chunk_bytes <= CHUNK_TARGET or chunk == 64  # 64: the smallest chunk, for > 1024 bands
    if layout.bands * unit * unit * 4 <= CHUNK_TARGET:
        assert chunk % rows == 0 and chunk % columns == 0
    else:
        band_rows = min(math.lcm(min(layout.block_rows, layout.height), chunk), layout.height)
        assert cache >= min(band_rows * layout.width * layout.bands * layout.itemsize, MAX_GDAL_CACHE)
    # Room for two blocks of all bands: GDAL decompresses a pixel-interleaved tile once for all bands.
    block = min(layout.block_rows, layout.height) * min(layout.block_columns, layout.width)
    assert cache >= min(2 * block * layout.bands * layout.itemsize, MAX_GDAL_CACHE)


@settings(max_examples=100, deadline=None)
@given(bands=st.integers(1, 500), tile=st.sampled_from([256, 512, 1024]), extra=st.integers(1, 20_000),
       itemsize=st.sampled_from([1, 2, 4]))
def test_chunks_are_multiples_of_square_tiles(bands, tile, extra, itemsize):
    layout = Layout(bands, tile + extra, tile + 2 * extra, tile, tile, itemsize)
    _check_chunk(layout, choose_chunk(layout))


@settings(max_examples=100, deadline=None)
@given(bands=st.integers(1, 500), tile_rows=st.sampled_from([128, 256, 512]),
       tile_columns=st.sampled_from([256, 512, 1024]), extra=st.integers(1, 5_000))
def test_chunks_are_multiples_of_oblong_tiles(bands, tile_rows, tile_columns, extra):
    layout = Layout(bands, tile_rows + extra, tile_columns + extra, tile_rows, tile_columns)
    _check_chunk(layout, choose_chunk(layout))


@settings(max_examples=100, deadline=None)
@given(bands=st.integers(1, 500), strip=st.sampled_from([1, 3, 8, 16, 64, 100, 256]),
       width=st.integers(17, 20_000), height=st.integers(300, 20_000))
def test_chunks_are_multiples_of_strips(bands, strip, width, height):
    layout = Layout(bands, height, width, strip, width)
    _check_chunk(layout, choose_chunk(layout))


def test_chunks_of_the_issue_cubes():
    # The cubes of benchmarks/bench_memory.py: 64 bands in 256-pixel tiles -> one tile per chunk
    # (16 MiB); 64 bands in 512-pixel tiles (64 MiB a tile) -> 256-pixel chunks and a cache holding
    # the row of tiles, 512 * 2048 * 64 * 4 bytes = 256 MiB; 425 bands in 256-pixel tiles (106 MiB a
    # tile) -> 64-pixel chunks (6.6 MiB) and a cache holding the 800-pixel-wide row of tiles:
    # 256 * 800 * 425 * 4 bytes = 332 MiB.
    assert choose_chunk(Layout(64, 2048, 2048, 256, 256)) == 256
    assert choose_chunk(Layout(64, 2048, 2048, 512, 512)) == 256
    assert cache_bytes(Layout(64, 2048, 2048, 512, 512), 256) == 512 * 2048 * 64 * 4
    assert choose_chunk(Layout(16, 4096, 4096, 512, 512)) == 512  # 16 bands: 16 MiB a tile, aligned
    hyper = Layout(425, 800, 800, 256, 256)
    assert choose_chunk(hyper) == 64
    assert cache_bytes(hyper, 64) == 256 * 800 * 425 * 4
    # The small tiles of brdfcorr.testing.write_scene (16) ask nothing: the band-count rule (100
    # bands: 128, as tests/workflow/test_pipeline.py expects of correct and of chains).
    assert choose_chunk(Layout(100, 160, 160, 16, 16)) == 128


@pytest.mark.parametrize("blocks", [
    {"tiled": True, "blockxsize": 256, "blockysize": 256},
    {"tiled": True, "blockxsize": 512, "blockysize": 512},
    {"tiled": True, "blockxsize": 1024, "blockysize": 1024},
    {"tiled": False, "blockysize": 8},  # strips of 8 rows
])
def test_auto_chunk_of_files_is_a_multiple_of_their_blocks(tmp_path, blocks):
    # Sparse files (no tile written): only the layout is read.
    path = tmp_path / "image.tif"
    with rasterio.open(path, "w", driver="GTiff", width=2304, height=2304, count=4, dtype="float32",
                       crs="EPSG:32632", transform=rasterio.transform.from_origin(500000, 5400000, 10, 10),
                       compress="deflate", sparse_ok=True, **blocks):
        pass
    layout = image_layout(path)
    assert layout == Layout(4, 2304, 2304, blocks["blockysize"], blocks.get("blockxsize", 2304), 4)
    chunk = auto_chunk(path)
    assert chunk % blocks["blockysize"] == 0 and chunk % blocks.get("blockxsize", 16) == 0
    _check_chunk(layout, chunk)


# ------------------------------------------------------------------------------------ progress
@pytest.fixture(scope="module")
def files(tmp_path_factory, write_example_scene):
    directory = tmp_path_factory.mktemp("progress")
    paths = write_example_scene(directory, synthetic_scene(ny=32, nx=48))
    result = CliRunner().invoke(main, ["correct", str(paths["image"]), "--angles", str(paths["angles"]),
                                       "--classes", str(paths["classes"]), "--params", str(paths["params"]),
                                       "--ref-sza", "35", "-o", str(directory / "corrected.tif")])
    assert result.exit_code == 0, result.output
    paths["corrected"] = directory / "corrected.tif"
    return paths


def _commands(files, out):
    return {
        "correct": ["correct", files["image"], "--angles", files["angles"], "--classes", files["classes"],
                    "--params", files["params"], "--ref-sza", "35", "-o", out / "corrected.tif"],
        "classes ndvi": ["classes", "ndvi", files["image"], "--edges", "0.2,0.5", "-o", out / "strata.tif"],
        "fit-classes": ["fit-classes", files["image"], "--angles", files["angles"], "--classes", files["classes"],
                        "--model", "lambertian", "--max-samples", "200", "--min-samples", "10",
                        "--min-vza-spread", "0",
                        "-o", out / "table.yaml"],
        "assess": ["assess", files["image"], files["corrected"], "--classes", files["classes"],
                   "--angles", files["angles"], "-o", out / "assess.json"],
    }


@pytest.mark.parametrize("command", ["correct", "classes ndvi", "fit-classes", "assess"])
def test_progress_on_request_and_not_without(files, tmp_path, command):
    # (The default, a bar on a terminal only, is the runner's "no terminal": as --no-progress.)
    for option, shown in (("--progress", True), ("--no-progress", False)):
        out = tmp_path / str(option)
        out.mkdir()
        arguments = [str(a) for a in _commands(files, out)[command]] + [option]
        result = CliRunner().invoke(main, arguments)
        assert result.exit_code == 0, result.output
        # tqdm's bar: "<command>: 100%|...| n/n", on stderr only.
        assert (f"{command}:" in result.stderr) is shown, (option, result.stderr)
        assert f"{command}:" not in result.stdout


def test_correct_progress_runs_from_the_first_pass(files, tmp_path, monkeypatch):
    # The bar is active when the scale check (the first pass that reads the image, before the
    # write) runs: progress from the start of the work, not only during the write.
    active = []
    check = scale_check.check_reflectance_scale

    def recording_check(*args, **kwargs):
        active.append(len(dask.callbacks.Callback.active))
        return check(*args, **kwargs)

    monkeypatch.setattr(scale_check, "check_reflectance_scale", recording_check)
    for option in ("--progress", "--no-progress"):
        arguments = [str(a) for a in _commands(files, tmp_path)["correct"]] + [option, "--overwrite"]
        result = CliRunner().invoke(main, arguments)
        assert result.exit_code == 0, result.output
    assert active[0] >= 1 and active[1] == 0


def test_gdal_cache_is_bounded_while_the_scale_check_reads(files, monkeypatch):
    # The check reads a few chunks before the write: under GDAL's default cache (5 % of RAM) every
    # tile read stayed in memory for the rest of the run (issue 28: +390 MiB on a 1 GiB cube).
    seen = []
    sample = scale_check._valid_sample

    def recording_sample(block, *args, **kwargs):
        seen.append(rasterio.env.getenv().get("GDAL_CACHEMAX"))
        return sample(block, *args, **kwargs)

    monkeypatch.setattr(scale_check, "_valid_sample", recording_sample)
    image = rasters.open_image(files["image"], chunks=16)
    assert scale_check.check_reflectance_scale(image, scheduler="synchronous") == pytest.approx(
        np.nanpercentile(image.values, 99), rel=0.05)
    assert seen and all(value == rasters.gdal_cache_bytes(files["image"], 16) for value in seen)


def test_fit_classes_counts_the_classes_it_has_fitted(files, tmp_path):
    # The fit itself (classes x bands, no dask) has its own bar: one step per class of the map.
    from brdfcorr.io.rasters import open_classes

    ids = np.unique(open_classes(files["classes"]).values)
    n_classes = int(np.sum((ids > 0) & (ids != 255)))  # 0: no class, 255: the map's nodata
    arguments = [str(a) for a in _commands(files, tmp_path)["fit-classes"]] + ["--progress"]
    result = CliRunner().invoke(main, arguments)
    assert result.exit_code == 0, result.output
    assert f"fit classes: {n_classes}" in result.stderr.replace("\r", "\n"), result.stderr


def _flat_measurements():
    """A Lambertian surface (t0 = 0.1) measured at 100 geometries, 1 % noise: angles [deg], BRDF [sr^-1]."""
    grid = np.meshgrid([10, 25, 40, 55], [0, 15, 30, 45, 60], [0, 45, 90, 135, 180], indexing="ij")
    ti, tr, phi = (np.asarray(a, dtype=float).ravel() for a in grid)
    brdf = 0.1 * (1 + 0.01 * np.random.default_rng(0).standard_normal(ti.size))
    return ti, tr, phi, brdf


def test_fit_counts_its_fits_on_request(tmp_path):
    # One step per wavelength fitted (with --model auto, one more per candidate: choose_model's
    # progress, the next test).
    ti, tr, phi, brdf = _flat_measurements()
    csv = tmp_path / "flat.csv"
    csv.write_text("theta_i,theta_r,phi,brdf,wavelength\n" + "".join(
        f"{a},{b},{c},{d},{w}\n" for w in (450, 550, 650) for a, b, c, d in zip(ti, tr, phi, brdf)))
    for option, shown in (("--progress", True), ("--no-progress", False)):
        result = CliRunner().invoke(main, ["fit", str(csv), "--model", "lambertian", option])
        assert result.exit_code == 0, result.output
        assert ("fit: 3fit " in result.stderr.replace("\r", "\n")) is shown, result.stderr
        assert "fit:" not in result.stdout


def test_the_model_choice_reports_each_candidate_once_its_folds_are_fitted():
    from brdfcorr.fit.measurements import Measurements
    from brdfcorr.fit.selection import choose_model

    seen = []
    choice = choose_model(Measurements(*_flat_measurements()), candidates=("lambertian", "ross_thick_li_sparse"), progress=seen.append)
    assert seen == ["lambertian", "ross_thick_li_sparse"] and choice.chosen == "lambertian"
