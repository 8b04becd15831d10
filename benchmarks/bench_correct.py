"""Benchmark of the BRDF normalization (run by hand; not part of the test suite).

Prints ratios against baselines measured in the same run, never absolute targets:

1. end to end, GeoTIFF in -> GeoTIFF out (``brdfcorr.tasks.correct.correct_files``, as the CLI runs it)
   versus a plain chunked rasterio read + write of the same image with the same output options
   (tiles, deflate + predictor); target <= 1.5;
2. in memory, per band: ``normalize`` on a numpy cube versus the bare ``cube * factor``, for a
   table with band-independent parameters and for a per-wavelength (spectral) table;
3. peak RSS of the end-to-end run at the given scene size and at 4x the pixels (twice the side),
   each in a fresh subprocess; target: growth < 25 % and well under 1 GiB for a 1 GiB scene;
4. integer output: the scene stored as int16 (scale 1e-4) corrected to its own type
   (``--output-type input``) versus to float32, same run; target <= 1.1 (issue 28).

How the end-to-end time scales with the cores, against GDAL's own multithreaded copy, and one
scene on a dask.distributed cluster: ``benchmarks/bench_scaling.py``.

Usage::

    python benchmarks/bench_correct.py --size 2048 --bands 64      # the 1 GiB scene of the issue
    python benchmarks/bench_correct.py --size 512 --bands 16       # a quick run
    python benchmarks/bench_correct.py --size 2048 --bands 64 --repeat 2 --skip in-memory end-to-end memory
                                                                   # integer output only
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rasterio
from rasterio.windows import Window

from brdfcorr.testing import example_table

CRS = "EPSG:32632"


def _profile(size: int, count: int, dtype: str, chunk: int, nodata=None) -> dict:
    return {
        "driver": "GTiff", "width": size, "height": size, "count": count, "dtype": dtype,
        "crs": CRS, "transform": rasterio.transform.from_origin(500000, 5400000, 10, 10),
        "tiled": True, "blockxsize": chunk, "blockysize": chunk, "compress": "deflate",
        "predictor": 3 if dtype.startswith("float") else 2, "nodata": nodata, "BIGTIFF": "IF_SAFER",
    }


def make_scene(directory: Path, size: int, bands: int, chunk: int = 512) -> dict[str, Path]:
    """Write a synthetic scene tile by tile (never the whole cube in memory)."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = {name: directory / f"{name}.tif" for name in ("image", "angles", "classes")}
    rng = np.random.default_rng(0)
    wavelengths = np.linspace(450, 850, bands)
    image_profile = _profile(size, bands, "float32", chunk, nodata=float("nan"))
    with rasterio.open(paths["image"], "w", **image_profile) as image, \
            rasterio.open(paths["angles"], "w", **_profile(size, 4, "float32", chunk)) as angles, \
            rasterio.open(paths["classes"], "w", **_profile(size, 1, "uint8", chunk, nodata=255)) as classes:
        image.descriptions = tuple(f"{w:.1f} nm" for w in wavelengths)
        for row in range(0, size, chunk):
            for col in range(0, size, chunk):
                window = Window(col, row, min(chunk, size - col), min(chunk, size - row))
                h, w = window.height, window.width
                y = (row + np.arange(h))[:, None] / size
                x = (col + np.arange(w))[None, :] / size
                spectrum = 0.05 + 0.3 * (wavelengths[:, None, None] - 450) / 400
                texture = 1 + 0.2 * np.sin(40 * x) * np.cos(30 * y) + rng.normal(0, 0.01, (h, w))
                image.write((spectrum * texture).astype("float32"), window=window)
                sza = 30 + 10 * y + 0 * x
                vza = 25 * np.abs(2 * x - 1) + 0 * y
                vaa = np.where(x < 0.5, 270.0, 90.0) + 0 * y
                saa = np.full((h, w), 150.0)
                angles.write(np.stack([sza, saa, vza, vaa]).astype("float32"), window=window)
                patches = rng.integers(1, 5, size=(-(-h // 8), -(-w // 8)))
                classes.write(np.kron(patches, np.ones((8, 8)))[:h, :w].astype("uint8"), 1, window=window)
    return paths


def spectral_table_path(directory: Path) -> Path:
    return example_table().save(directory / "params.yaml")


def plain_copy(source: Path, target: Path, chunk: int) -> None:
    """The baseline: a chunked rasterio read + write with the same output options (tiles of
    ``chunk`` pixels, deflate with the floating-point predictor)."""
    with rasterio.open(source) as src:
        profile = _profile(src.width, src.count, src.dtypes[0], chunk, nodata=src.nodata)
        with rasterio.open(target, "w", **profile) as dst:
            for row in range(0, src.height, chunk):
                for col in range(0, src.width, chunk):
                    window = Window(col, row, min(chunk, src.width - col), min(chunk, src.height - row))
                    dst.write(src.read(window=window), window=window)


def run_correct(paths: dict, output: Path, chunk: int | None, data_type: str = "float") -> object:
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles

    return correct_files(CorrectionRequest(
        SceneSources(paths["image"], paths["classes"], paths["angles"]), paths["params"],
        OutputFiles(output, data_type=data_type, overwrite=True),
        reference={"sza": "mean", "vza": 0, "raa": 0}, engine=Engine(chunks=chunk),
    ))


def stored_as_int16(source: Path, target: Path, scale: float = 1e-4, nodata: int = -9999) -> Path:
    """The float image as int16 counts (``round(value / scale)``, NaN as ``nodata``) with its GDAL
    scale, written block by block."""
    with rasterio.open(source) as src:
        profile = {**src.profile, "dtype": "int16", "nodata": nodata, "predictor": 2}
        with rasterio.open(target, "w", **profile) as dst:
            for _, window in src.block_windows(1):
                values = src.read(window=window)
                dst.write(np.where(np.isfinite(values), np.round(values / scale), nodata).astype("int16"),
                          window=window)
            dst.descriptions, dst.scales = src.descriptions, (scale,) * src.count
    return target


def integer_output(directory: Path, size: int, bands: int, chunk: int, repeat: int) -> None:
    """``--output-type input`` against the float output of the same int16 scene (issue 28: the
    integers are encoded in the writing pass, so the correction is computed once)."""
    from brdfcorr.io.rasters import auto_chunk

    paths = make_scene(directory, size, bands)
    paths["params"] = spectral_table_path(directory)
    paths["image"] = stored_as_int16(paths["image"], directory / "image_int16.tif")
    chunk = chunk or auto_chunk(paths["image"])
    floats = integers = np.inf
    for _ in range(repeat):  # interleaved, best of each: the machine is shared
        floats = min(floats, timed(run_correct, paths, directory / "float.tif", chunk, "float"))
        integers = min(integers, timed(run_correct, paths, directory / "int16.tif", chunk, "input"))
    print(f"[integer output] {bands} bands x {size}^2 int16, chunk {chunk}: float32 output {floats:.2f} s, "
          f"int16 output (--output-type input) {integers:.2f} s, ratio {integers / floats:.2f} (target <= 1.1)")


def timed(function, *args, repeat: int = 1) -> float:
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        function(*args)
        best = min(best, time.perf_counter() - start)
    return best


def end_to_end(directory: Path, size: int, bands: int, chunk: int, repeat: int) -> None:
    from brdfcorr.io.rasters import auto_chunk

    paths = make_scene(directory, size, bands)
    paths["params"] = spectral_table_path(directory)
    chunk = chunk or auto_chunk(paths["image"])  # brdfcorr's default; the baseline writes the same tiles
    gib = size * size * bands * 4 / 2**30
    plain = corrected = np.inf
    for _ in range(repeat):  # interleaved, best of each: the machine is shared
        plain = min(plain, timed(plain_copy, paths["image"], directory / "plain.tif", chunk))
        corrected = min(corrected, timed(run_correct, paths, directory / "corrected.tif", chunk))
    print(f"[end to end] {bands} bands x {size}^2 float32 ({gib:.2f} GiB), chunk {chunk}: "
          f"plain rasterio read+write {plain:.2f} s, brdfcorr correct {corrected:.2f} s, "
          f"ratio {corrected / plain:.2f} (target <= 1.5)")


def in_memory(size: int, bands: int, repeat: int) -> None:
    from brdfcorr.correction import normalize
    from brdfcorr.params import ParameterTable
    from brdfcorr.testing import synthetic_angles, synthetic_classes

    rng = np.random.default_rng(1)
    cube = rng.uniform(0.01, 0.5, (bands, size, size)).astype("float32")
    angles = synthetic_angles(size, size)
    classes = synthetic_classes(size, size, ids=(1, 2, 3, 4))
    factor = rng.uniform(0.5, 2.0, (size, size)).astype("float32")
    wavelengths = list(np.linspace(450, 850, bands))
    scalar = ParameterTable(classes=[
        {"id": 1, "name": "tile", "model": "torrance_sparrow",
         "params": {"t0": 0.0245, "t1": 0.2, "w": 0.0362, "n": 1.77, "k": 0.25}},
        {"id": 2, "name": "grass", "model": "empirical", "params": {"a": 0.02, "b": 1.0, "c": 0.02, "t0": 0.05}},
        {"id": 3, "name": "paving", "model": "torrance_sparrow_simplified",
         "params": {"t0": 0.05, "t1": 0.3, "w": 0.06, "n": 1.6, "k": 0.1}},
        {"id": 4, "name": "flat", "model": "lambertian", "params": {"t0": 0.1}},
    ])
    spectral = example_table()
    normalize(cube[:1], classes, angles, scalar, reference={"sza": 35.0})  # warm-up (imports)
    bare = timed(lambda: cube * factor, repeat=repeat)
    few = max(bands // 4, 1)
    for label, table in (("band-independent table", scalar), ("per-wavelength table", spectral)):
        def run(n):
            return timed(lambda: normalize(cube[:n], classes, angles, table, wavelengths=wavelengths[:n],
                                           reference={"sza": 35.0}), repeat=repeat)
        full, part = run(bands), run(few)
        marginal = (full - part) / (bands - few)  # cost of one more band; the geometry is shared
        print(f"[in memory] {bands} bands x {size}^2, {label}: bare cube*factor {bare / bands * 1e3:.2f} "
              f"ms/band; normalize {full / bands * 1e3:.2f} ms/band on average (ratio {full / bare:.1f}), "
              f"{marginal * 1e3:.2f} ms per additional band (ratio {marginal / (bare / bands):.2f})")


def _peak_rss_mib() -> float:
    # VmHWM is this process's own high-water mark; getrusage's ru_maxrss would include the RSS the
    # parent had when it forked this child.
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def child_rss(args: argparse.Namespace) -> None:
    """In a fresh process: run the end-to-end correction and print peak RSS [MiB] as JSON."""
    import brdfcorr.correction  # noqa: F401  (count the imports in the baseline below)

    directory = Path(args.dir)
    paths = {name: directory / f"{name}.tif" for name in ("image", "angles", "classes")}
    paths["params"] = directory / "params.yaml"
    before = _peak_rss_mib()
    run_correct(paths, directory / "corrected_rss.tif", args.chunk)
    print(json.dumps({"peak_mib": _peak_rss_mib(), "import_mib": before}))


def memory(directory: Path, size: int, bands: int, chunk: int) -> None:
    results = {}
    for factor, side in ((1, size), (4, 2 * size)):
        scene_dir = directory / f"rss_{side}"
        make_scene(scene_dir, side, bands)
        spectral_table_path(scene_dir)
        output = subprocess.run(
            [sys.executable, __file__, "--child-rss", "--dir", str(scene_dir)]
            + (["--chunk", str(chunk)] if chunk else []),
            check=True, capture_output=True, text=True,
        ).stdout
        results[factor] = json.loads(output.strip().splitlines()[-1])
        gib = side * side * bands * 4 / 2**30
        print(f"[memory] {bands} bands x {side}^2 ({gib:.2f} GiB): peak RSS {results[factor]['peak_mib']:.0f} MiB "
              f"(after imports {results[factor]['import_mib']:.0f} MiB)")
        for path in scene_dir.glob("*.tif"):
            path.unlink()
    growth = results[4]["peak_mib"] / results[1]["peak_mib"] - 1
    print(f"[memory] 4x pixels raise peak RSS by {100 * growth:.1f} % (target < 25 %)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=int, default=512, help="scene side [pixels] (2048 for the 1 GiB scene)")
    parser.add_argument("--bands", type=int, default=16)
    parser.add_argument("--chunk", type=int, help="chunk and output tile size (default: brdfcorr's auto_chunk)")
    parser.add_argument("--memory-size", type=int, default=1024, help="side of the in-memory cube")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--skip", nargs="*", default=(),
                        choices=("end-to-end", "in-memory", "memory", "integer-output"))
    parser.add_argument("--dir", help="working directory (default: a temporary one)")
    parser.add_argument("--child-rss", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child_rss:
        child_rss(args)
        return
    with tempfile.TemporaryDirectory(dir=args.dir) as directory:
        directory = Path(directory)
        if "in-memory" not in args.skip:
            in_memory(args.memory_size, args.bands, args.repeat)
        if "end-to-end" not in args.skip:
            end_to_end(directory / "e2e", args.size, args.bands, args.chunk, args.repeat)
        if "memory" not in args.skip:
            memory(directory, args.size, args.bands, args.chunk)
        if "integer-output" not in args.skip:
            integer_output(directory / "integer", args.size, args.bands, args.chunk, args.repeat)


if __name__ == "__main__":
    main()
