"""Benchmark: one fit over a stack of dates, each pixel's level free, against the same fit pooled
(issue 37: time and peak memory; run by hand).

The stack is lazy (dask, chunks of 250 x 250 pixels): ``--dates`` images of ``--size`` x ``--size``
pixels and 8 bands on one grid, RTLSR reflectance with a smooth cover field (the level) and 1 %
noise, the view zenith across the swath flipping side from date to date, four classes. The image
bands are computed chunk by chunk when the sampler reads the sampled pixels; the class maps and
angles are computed whole (they are (y, x) per date). Each mode runs in a fresh process, whose peak
resident memory is read from ``resource.getrusage``; the ratio of the within fit (``pixel``) to the
pooled one is printed for time and memory.

    python benchmarks/bench_stack_fit.py [--dates 20] [--size 1000]

Measured (issue 37, 2 cores, two light jobs beside): pooled 11.0 s, peak 1079 MiB, NIR
f_vol/f_iso 1.585-1.598 per class; pixel levels 12.8 s, peak 1173 MiB, 0.568-0.580 (truth 0.583):
time 1.17 x, peak memory 1.09 x the pooled fit's.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

import dask.array as da
import numpy as np
import xarray as xr

BANDS, CHUNK = 8, 250


def stack(dates: int, size: int):
    """Lazy images, class maps and angle sets of ``dates`` dates on one ``size`` x ``size`` grid."""
    from brdfcorr.geometry import relative_azimuth
    from brdfcorr.models import get_model

    rtlsr = get_model("ross_thick_li_sparse")
    coords = {"y": np.arange(size), "x": np.arange(size)}
    across = np.linspace(-1.0, 1.0, size)
    weights = {"f_iso": np.linspace(0.03, 0.12, BANDS), "f_vol": np.linspace(0.02, 0.07, BANDS),
               "f_geo": np.linspace(0.005, 0.02, BANDS)}
    classes = (np.arange(size)[:, None] * 4 // size + 1) * np.ones((1, size), np.int32)
    images, maps, angle_sets = [], [], []
    for date in range(dates):
        side = 1.0 if date % 2 == 0 else -1.0
        vza = np.abs(across * 30.0)[None, :] * np.ones((size, 1))
        vaa = np.where(across * side < 0, 270.0, 90.0)[None, :] * np.ones((size, 1))
        sza, saa = np.full((size, size), 30.0 + date % 5), np.full((size, size), 110.0)
        phi = relative_azimuth(saa, vaa)

        def block(block_id=None, date=date, sza=sza, vza=vza, phi=phi):
            _, row, column = block_id
            rows, columns = slice(row * CHUNK, (row + 1) * CHUNK), slice(column * CHUNK, (column + 1) * CHUNK)
            rng = np.random.default_rng(date * 10_000 + row * 100 + column)
            shape = (1, *sza[rows, columns].shape)
            cover = 1.0 + 0.2 * np.sin(np.arange(size)[columns] / 50.0)[None, None, :]
            brdf = rtlsr(sza[rows, columns][None], vza[rows, columns][None], phi[rows, columns][None],
                         **{k: v[:, None, None] for k, v in weights.items()})
            return (np.pi * brdf * cover * (1 + 0.01 * rng.standard_normal((BANDS, *shape[1:])))).astype(np.float32)

        cube = da.map_blocks(block, dtype=np.float32, chunks=((BANDS,), (CHUNK,) * (size // CHUNK),
                                                              (CHUNK,) * (size // CHUNK)))
        images.append(xr.DataArray(cube, dims=("band", "y", "x"), coords=coords))
        maps.append(xr.DataArray(classes, dims=("y", "x"), coords=coords))
        angle_sets.append(xr.Dataset({k: (("y", "x"), v) for k, v in
                                      {"sza": sza, "saa": saa, "vza": vza, "vaa": vaa}.items()}, coords=coords))
    return images, maps, angle_sets


def run_one(levels: str, dates: int, size: int) -> dict:
    from brdfcorr.fit import ClassModels, Sampling, fit_classes

    images, maps, angle_sets = stack(dates, size)
    start = time.perf_counter()
    result = fit_classes(images, maps, angle_sets, ClassModels("ross_thick_li_sparse"),
                         sampling=Sampling(levels=levels), wavelengths=list(np.linspace(450, 900, BANDS)))
    seconds = time.perf_counter() - start
    ratios = [float(f.params["f_vol"][-1] / f.params["f_iso"][-1]) for f in result.fits]
    return {"seconds": seconds, "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "f_vol/f_iso": ratios}


def compare_levels(script: str, arguments: list[str]) -> dict[str, dict]:
    """``script --one LEVELS ARGUMENTS`` for pooled and per-pixel levels, each in a fresh process (its
    own peak RSS): each run's result (its last stdout line, JSON), printed (shared with
    bench_lines_fit.py)."""
    results = {}
    for levels in ("pooled", "pixel"):
        output = subprocess.run([sys.executable, script, "--one", levels, *arguments], check=True,
                                capture_output=True, text=True).stdout
        result = results[levels] = json.loads(output.strip().splitlines()[-1])
        print(f"{levels:7s}: {result['seconds']:.1f} s, peak {result['peak_mib']:.0f} MiB, f_vol/f_iso of the "
              f"NIR band per class {np.round(result['f_vol/f_iso'], 3).tolist()} {result.get('notes', '')}".rstrip())
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dates", type=int, default=20)
    parser.add_argument("--size", type=int, default=1000, help="pixels per side (a multiple of 250)")
    parser.add_argument("--one", choices=("pooled", "pixel"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, args.dates, args.size)))
        return
    results = compare_levels(__file__, ["--dates", str(args.dates), "--size", str(args.size)])
    gib = 4 * args.dates * BANDS * args.size**2 / 2**30
    time_ratio = results["pixel"]["seconds"] / results["pooled"]["seconds"]
    print(f"{args.dates} dates x {BANDS} bands x {args.size} x {args.size} (lazy, {gib:.1f} GiB float32): "
          f"pixel levels / pooled: time {time_ratio:.2f}x, "
          f"peak memory {results['pixel']['peak_mib'] / results['pooled']['peak_mib']:.2f}x; truth f_vol/f_iso 0.583")


if __name__ == "__main__":
    main()
