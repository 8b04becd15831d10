"""Peak memory of ``brdfcorr correct`` against the peak-memory model of ``docs/scaling.md``
(run by hand; not part of the test suite).

For each cube of ``--sizes`` (``1g``: 64 bands x 2048^2 float32; ``4g``: 64 bands x 4096^2;
``hyper``: 425 bands x 800^2, about 1 GiB) and each model mix of ``--mixes`` (``ts``: two
Torrance-Sparrow classes and one empirical; ``kernel``: three Ross-Thick/Li-Sparse classes), the
scene is written to a temporary directory (tiled deflate GeoTIFF with the float predictor, input
tiles of ``--tile`` pixels, pixel-interleaved as GDAL writes multi-band GeoTIFFs by default), then
``brdfcorr correct`` runs in a fresh process, which reports its own peak RSS (``VmHWM``, the
kernel's high-water mark of that process's memory; :data:`CHILD`). Printed beside it: the model's
prediction (:func:`predicted_mib`, the terms of ``docs/scaling.md``) and the goal of issue 28
(``0.6 x cube + 250 MiB``).

Usage::

    python benchmarks/bench_memory.py                       # 1g, 4g and hyper, both mixes
    python benchmarks/bench_memory.py --sizes 1g --mixes ts # one run
    python benchmarks/bench_memory.py --dir /tmp/scenes     # keep the scenes for the next run
"""

from __future__ import annotations

import argparse
import contextlib
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rasterio
import yaml
from rasterio.windows import Window

#: name: (bands, side [pixels])
SIZES = {"1g": (64, 2048), "4g": (64, 4096), "hyper": (425, 800)}

#: Three classes per mix (class ids 1-3 of the scene's class map).
MIXES = {
    "ts": [
        {"id": 1, "name": "roof_tile", "model": "torrance_sparrow",
         "params": {"t0": 0.0245, "t1": 0.2, "w": 0.0362, "n": 1.77, "k": 0.25}},
        {"id": 2, "name": "metal", "model": "torrance_sparrow",
         "params": {"t0": 0.01, "t1": 0.5, "w": 0.08, "n": 2.5, "k": 3.0}},
        {"id": 3, "name": "asphalt", "model": "empirical",
         "params": {"a": 0.02, "b": 1.0, "c": 0.05, "t0": 0.03}},
    ],
    "kernel": [
        {"id": 1, "name": "roof", "model": "ross_thick_li_sparse",
         "params": {"f_iso": 0.04, "f_vol": 0.01, "f_geo": 0.005}},
        {"id": 2, "name": "lawn", "model": "ross_thick_li_sparse",
         "params": {"f_iso": 0.03, "f_vol": 0.02, "f_geo": 0.004}},
        {"id": 3, "name": "soil", "model": "ross_thick_li_sparse",
         "params": {"f_iso": 0.05, "f_vol": 0.01, "f_geo": 0.01}},
    ],
}


def _profile(side: int, count: int, dtype: str, tile: int, nodata=None) -> dict:
    return {"driver": "GTiff", "width": side, "height": side, "count": count, "dtype": dtype,
            "crs": "EPSG:32632", "transform": rasterio.transform.from_origin(500000, 5400000, 10, 10),
            "tiled": True, "blockxsize": tile, "blockysize": tile, "compress": "deflate",
            "predictor": 3 if dtype.startswith("float") else 2, "nodata": nodata, "BIGTIFF": "IF_SAFER",
            "num_threads": "ALL_CPUS"}


def make_scene(directory: Path, bands: int, side: int, tile: int) -> dict[str, Path]:
    """Image, angles (sza, saa, vza, vaa) and a class map of ids 1-3 in 8-pixel patches, written
    tile row by tile row (never the whole cube in memory); kept when already there."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = {name: directory / f"{name}.tif" for name in ("image", "angles", "classes")}
    if all(path.exists() for path in paths.values()):
        return paths
    rng = np.random.default_rng(0)
    wavelengths = np.linspace(400, 2500, bands)
    spectrum = (0.05 + 0.3 * (wavelengths - 400) / 2100)[:, None, None]
    with rasterio.open(paths["image"], "w", **_profile(side, bands, "float32", tile, float("nan"))) as image, \
            rasterio.open(paths["angles"], "w", **_profile(side, 4, "float32", tile)) as angles, \
            rasterio.open(paths["classes"], "w", **_profile(side, 1, "uint8", tile, 255)) as classes:
        image.descriptions = tuple(f"{w:.1f} nm" for w in wavelengths)
        for row in range(0, side, tile):
            height = min(tile, side - row)
            window = Window(0, row, side, height)
            y = (row + np.arange(height))[:, None] / side
            x = np.arange(side)[None, :] / side
            texture = 1 + 0.2 * np.sin(40 * x) * np.cos(30 * y) + rng.normal(0, 0.01, (height, side))
            image.write((spectrum * texture).astype("float32"), window=window)
            sza = 30 + 10 * y + 0 * x
            vza = 25 * np.abs(2 * x - 1) + 0 * y
            vaa = np.where(x < 0.5, 270.0, 90.0) + 0 * y
            angles.write(np.stack([sza, np.full_like(sza, 150.0), vza, vaa]).astype("float32"), window=window)
            patches = rng.integers(1, 4, size=(-(-height // 8), -(-side // 8)))
            classes.write(np.kron(patches, np.ones((8, 8)))[:height, :side].astype("uint8"), 1, window=window)
    return paths


#: A fresh process that runs the CLI and, at exit, writes its own peak RSS [KiB] (``VmHWM``) to the
#: file named by its first argument. Not ``ru_maxrss`` from ``wait4``: Linux carries the parent's
#: memory at the fork into a child's ``ru_maxrss``, and the parent held the cube it had just written
#: (1160 MiB for every run of the 4 GiB cube, 1899 MiB for the hyperspectral one).
CHILD = ("import atexit, pathlib, sys; report = pathlib.Path(sys.argv.pop(1)); "
         "atexit.register(lambda: report.write_text(next(line.split()[1] for line in "
         "open('/proc/self/status') if line.startswith('VmHWM:')))); "
         "from brdfcorr.cli import main; main()")


def run_correct(paths: dict[str, Path], table: Path, output: Path) -> tuple[float, float]:
    """``brdfcorr correct`` in a fresh process: (seconds, peak RSS [MiB]) of that process."""
    report = output.with_suffix(".vmhwm")
    command = [sys.executable, "-c", CHILD, str(report), "correct", str(paths["image"]),
               "--angles", str(paths["angles"]), "--classes", str(paths["classes"]), "--params", str(table),
               "-o", str(output), "--overwrite", "--ref-sza", "mean", "--no-progress"]
    start = time.perf_counter()
    process = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=False)
    seconds = time.perf_counter() - start
    if process.returncode != 0:
        sys.exit(f"brdfcorr correct failed: {process.stderr.decode()}")
    peak = int(report.read_text()) / 1024  # KiB
    report.unlink()
    return seconds, peak


def base_mib() -> float:
    """Peak RSS [MiB] of a process that only imports what ``correct`` imports (the model's base)."""
    code = ("import brdfcorr.tasks.correct, brdfcorr.cli.correct;"
            "print(next(line.split()[1] for line in open('/proc/self/status') if line.startswith('VmHWM:')))")
    return int(subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                              text=True).stdout.split()[-1]) / 1024  # KiB


def predicted_mib(image: Path, base: float) -> dict[str, float]:
    """The peak-memory model of ``docs/scaling.md`` for ``brdfcorr correct`` of ``image`` on this
    machine [MiB] (:func:`brdfcorr.io.rasters.peak_memory_terms`): the imports (``base``, measured),
    per dask thread its input block and chunks, GDAL's block cache, per compression thread the
    output tiles it holds, and the run's fixed overhead."""
    from brdfcorr.defaults import available_cores, default_threads
    from brdfcorr.io.rasters import auto_chunk, image_layout, peak_memory_terms

    chunk = auto_chunk(image)
    terms = peak_memory_terms(image_layout(image), chunk, default_threads(), available_cores())
    mib = {name: value / 2**20 for name, value in terms.items()}
    return {"base": base, **mib, "total": base + sum(mib.values()), "chunk": chunk}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", choices=sorted(SIZES), default=["1g", "4g", "hyper"])
    parser.add_argument("--mixes", nargs="+", choices=sorted(MIXES), default=["ts", "kernel"])
    parser.add_argument("--tile", type=int, default=256, help="input tile size [pixels] (default 256)")
    parser.add_argument("--dir", help="directory for the scenes, kept for the next run (default: a temporary one)")
    args = parser.parse_args()
    with contextlib.ExitStack() as stack:
        root = Path(args.dir or stack.enter_context(tempfile.TemporaryDirectory(prefix="bench_memory_")))
        base = base_mib()
        print(f"{'cube':>6} {'mix':>6} {'MiB':>6} {'chunk':>5} {'time [s]':>8} {'peak RSS':>8} {'model':>6} "
              f"{'(base':>6} {'threads':>7} {'cache':>6} {'compr.':>6} {'other)':>6} {'goal':>6}  [MiB]")
        for size in args.sizes:
            bands, side = SIZES[size]
            paths = make_scene(root / f"{size}_t{args.tile}", bands, side, args.tile)
            cube_mib = bands * side * side * 4 / 2**20
            for mix in args.mixes:
                table = root / f"{mix}.yaml"
                table.write_text(yaml.safe_dump({"classes": MIXES[mix]}, sort_keys=False))
                seconds, peak = run_correct(paths, table, root / f"{size}_{mix}.tif")
                model = predicted_mib(paths["image"], base)
                print(f"{size:>6} {mix:>6} {cube_mib:6.0f} {model['chunk']:5d} {seconds:8.1f} {peak:8.0f} "
                      f"{model['total']:6.0f} {model['base']:6.0f} {model['threads']:7.0f} {model['cache']:6.0f} "
                      f"{model['compression']:6.0f} {model['overhead']:6.0f} {0.6 * cube_mib + 250:6.0f}",
                      flush=True)
                (root / f"{size}_{mix}.tif").unlink()


if __name__ == "__main__":
    main()
