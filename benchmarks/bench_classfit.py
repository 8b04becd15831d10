"""Benchmark: fitting 10 classes x 200 bands from 1 million samples (issue 6 target: well under a
minute on the 2-core reference machine); and ``fit-classes --model auto`` on the 1 GiB bench cube
against one model (issue 36 target: at most 3x the time of one model).

Prints the wall time of the whole fit and, as a machine-independent figure, its ratio to the time
of one pass of the bare linear algebra the fit cannot avoid (``basis @ data`` for every class, i.e.
reading every sample of every band once), measured in the same run.

With ``--cube``: the bench cube of ``bench_memory.py`` (``1g``: 64 bands x 2048^2 float32, three
classes in 8-pixel patches; ``small``: 64 bands x 1024^2, 256 MiB), rendered with a BRDF per class
(:func:`make_cube`), is written to a temporary directory (or ``--dir``, kept), then ``brdfcorr
fit-classes`` runs on it twice in fresh processes, with the default model (torrance_sparrow) and
with ``--model auto``, and the ratio of their times is printed.

    python benchmarks/bench_classfit.py [--samples 1000000] [--classes 10] [--bands 200]
    python benchmarks/bench_classfit.py --cube 1g [--dir /tmp/scenes]
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
from rasterio.windows import Window

from brdfcorr.fit.classes import ClassSamples, fit_one_class
from brdfcorr.models import get_model, torrance_sparrow


def synthesize(n: int, bands: int, rng: np.random.Generator):
    sza, vza = rng.uniform(25, 50, n), rng.uniform(0, 40, n)
    phi = np.where(rng.random(n) < 0.5, rng.uniform(150, 180, n), rng.uniform(0, 30, n))
    t0 = rng.uniform(0.005, 0.1, bands)
    t1 = rng.uniform(0.05, 0.5, bands)
    w = rng.uniform(0.03, 0.15)
    brdf = torrance_sparrow(sza[:, None], vza[:, None], phi[:, None], t0=t0, t1=t1, w=w, n=1.6, k=0.25)
    brdf *= rng.normal(1, 0.05, (n, 1)) * (1 + 0.01 * rng.standard_normal(brdf.shape))
    return sza, vza, phi, brdf, w


#: Cubes of ``--cube``: name -> (bands, side [pixels]); ``1g`` is bench_memory's.
CUBES = {"1g": (64, 2048), "small": (64, 1024)}


def fit_classes_seconds(paths: dict[str, Path], output: Path, model: str | None) -> float:
    """Wall time [s] of ``brdfcorr fit-classes`` on the cube in a fresh process (its start-up and
    imports included, as a user runs it), with ``--model model`` (None: the default)."""
    command = [sys.executable, "-c", "from brdfcorr.cli import main; main()", "fit-classes", str(paths["image"]),
               "--angles", str(paths["angles"]), "--classes", str(paths["classes"]), "-o", str(output),
               "--no-progress", "--overwrite", *(["--model", model] if model else [])]
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def make_cube(directory: Path, bands: int, side: int, tile: int = 256) -> dict[str, Path]:
    """bench_memory's cube (:func:`bench_memory.make_scene`: its grid, GeoTIFF layout and class map
    of ids 1-3 in 8-pixel patches) with a BRDF: each class rendered by its model of bench_memory's
    ``ts`` mix (paper 003's roof tile, a metal, an empirical asphalt) times a spectrum, a 5 %
    texture and 1 % noise; the line flown across the sun's plane (sun from the east, view zenith
    0-25 deg on both sides), so every class has an angular signal to fit. Kept when already there."""
    from bench_memory import MIXES, _profile

    directory.mkdir(parents=True, exist_ok=True)
    paths = {name: directory / f"{name}.tif" for name in ("image", "angles", "classes")}
    if all(path.exists() for path in paths.values()):
        return paths
    rng = np.random.default_rng(0)
    wavelengths = np.linspace(400, 2500, bands)
    spectrum = (0.5 + 2.0 * (wavelengths - 400) / 2100)[:, None]
    with rasterio.open(paths["image"], "w", **_profile(side, bands, "float32", tile, float("nan"))) as image, \
            rasterio.open(paths["angles"], "w", **_profile(side, 4, "float32", tile)) as angles, \
            rasterio.open(paths["classes"], "w", **_profile(side, 1, "uint8", tile, 255)) as classes:
        image.descriptions = tuple(f"{w:.1f} nm" for w in wavelengths)
        for row in range(0, side, tile):
            height = min(tile, side - row)
            y, x = np.meshgrid((row + np.arange(height)) / side, np.arange(side) / side, indexing="ij")
            sza, vza, vaa = 30 + 10 * y, 25 * np.abs(2 * x - 1), np.where(x < 0.5, 270.0, 90.0)
            phi = np.where(x < 0.5, 180.0, 0.0)  # relative azimuth of the sun (az. 90) and the view
            ids = np.kron(rng.integers(1, 4, size=(-(-height // 8), -(-side // 8))), np.ones((8, 8)))[:height, :side]
            brdf = np.zeros((height, side))
            for entry in MIXES["ts"]:
                where = ids == entry["id"]
                brdf[where] = get_model(entry["model"])(sza[where], vza[where], phi[where], **entry["params"])
            noise = 1 + 0.01 * rng.standard_normal((bands, height, side))
            texture = (1 + 0.05 * np.sin(40 * x) * np.cos(30 * y)) * noise
            window = Window(0, row, side, height)
            image.write((np.pi * brdf * spectrum[:, :, None] * texture).astype("float32"), window=window)
            angles.write(np.stack([sza, np.full_like(sza, 90.0), vza, vaa]).astype("float32"), window=window)
            classes.write(ids.astype("uint8"), 1, window=window)
    return paths


def cube_timing(cube: str, directory: str | None) -> None:
    """``fit-classes`` with the default model and with ``--model auto`` on one bench cube, and the
    ratio of their times (goal of issue 36: <= 3)."""
    bands, side = CUBES[cube]
    with contextlib.ExitStack() as stack:
        root = Path(directory or stack.enter_context(tempfile.TemporaryDirectory(prefix="bench_classfit_")))
        start = time.perf_counter()
        paths = make_cube(root / f"cube_{bands}x{side}", bands, side)
        print(f"cube: {bands} bands x {side}^2 float32 ({bands * side * side * 4 / 2**30:.2f} GiB), "
              f"written or found in {time.perf_counter() - start:.0f} s")
        one = fit_classes_seconds(paths, root / "one.yaml", None)
        auto = fit_classes_seconds(paths, root / "auto.yaml", "auto")
    print(f"fit-classes (torrance_sparrow): {one:.1f} s; --model auto: {auto:.1f} s; "
          f"ratio {auto / one:.2f}x (goal <= 3x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="total samples (all classes)")
    parser.add_argument("--classes", type=int, default=10)
    parser.add_argument("--bands", type=int, default=200)
    parser.add_argument("--cube", choices=sorted(CUBES), help="time fit-classes --model auto on a bench cube")
    parser.add_argument("--dir", help="directory for the cube, kept for the next run (default: a temporary one)")
    args = parser.parse_args()
    if args.cube:
        cube_timing(args.cube, args.dir)
        return
    rng = np.random.default_rng(0)
    per_class = args.samples // args.classes
    data = [synthesize(per_class, args.bands, rng) for _ in range(args.classes)]

    start = time.perf_counter()
    for sza, _, _, brdf, _ in data:
        _ = (sza / 90.0) @ brdf
    baseline = time.perf_counter() - start

    start = time.perf_counter()
    errors = []
    for class_id, (sza, vza, phi, brdf, w) in enumerate(data, start=1):
        # Spatial blocks as fit_classes labels them (about 1000 blocks of 32 x 32 pixels a class).
        blocks = np.random.default_rng(class_id).integers(0, 1000, sza.size)
        samples = ClassSamples(sza, vza, phi, brdf, block=blocks)
        fit = fit_one_class(class_id, f"class_{class_id}", "torrance_sparrow", samples)
        errors.append(abs(fit.params["w"][0] - w) / fit.errors["w"][0])
    elapsed = time.perf_counter() - start
    print(f"{args.classes} classes x {args.bands} bands from {per_class * args.classes:,} samples")
    print(f"fit time: {elapsed:.1f} s; one pass of basis @ data: {baseline:.3f} s; ratio {elapsed / baseline:.0f}x")
    print(f"|w - truth| / error per class: {np.round(errors, 2).tolist()}")


if __name__ == "__main__":
    main()
