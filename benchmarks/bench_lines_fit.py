"""Benchmark: one fit over overlapping flight lines on different grids, each pixel's level free on
their common grid, against the same fit pooled (issue 37: time and peak memory; run by hand).

``--lines`` lazy (dask, chunks of 250 x 250 pixels) lines of ``--size`` x ``--size`` 10 m pixels
and 8 bands, each shifted east by 30 % of a line plus 0.37 pixel and south by 0.21 pixel from the
previous (so every line has its own grid), RTLSR reflectance with a smooth cover field of the
ground and 1 % noise, the view zenith rising across each swath, the lines seen alternately from
the east and the west, four classes. With ``levels="pixel"`` the lines are brought onto one common
grid (:mod:`brdfcorr.fit.grids`): only an integer index layer per line is resampled, and the
reflectance is read at the sampled pixels only. Each mode runs in a fresh process, whose peak
resident memory is read from ``resource.getrusage``; the ratio of the within fit to the pooled one
is printed for time and memory, next to the size the resampled float32 cubes would have had.

``--layout survey``: a survey block instead, long lines (``3 * --size`` rows) flown side by side
with the usual 30 % sidelap (each shifted east by 70 % of a line plus 0.37 pixel): the union of
the lines is many times one line, and each line's layers of the common grid are held over its
own window only (:mod:`brdfcorr.fit.grids`). ``--before CHECKOUT`` also runs the pixel-level fit
with the package of another checkout (e.g. the commit before the windows) in a fresh process and
prints the ratios of time and peak memory, after / before, measured in the same run.

    python benchmarks/bench_lines_fit.py [--lines 4] [--size 1000]
    python benchmarks/bench_lines_fit.py --lines 12 --size 500 --layout survey --before ../main
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import dask.array as da
import numpy as np
import xarray as xr
from bench_stack_fit import compare_levels

BANDS, CHUNK, PIXEL = 8, 250, 10.0
ORIGIN = (500_000.0, 5_400_000.0)
WEIGHTS = {"f_iso": np.linspace(0.03, 0.12, BANDS), "f_vol": np.linspace(0.02, 0.07, BANDS),
           "f_geo": np.linspace(0.005, 0.02, BANDS)}


#: Layouts: (east shift of each line [fraction of a line], line length [multiple of --size]).
LAYOUTS = {"strip": (0.3, 1), "survey": (0.7, 3)}


def _offset(line: int, size: int, layout: str = "strip") -> tuple[float, float]:
    """Columns east and rows south of line ``line``'s grid from the first's [pixels]."""
    return line * (LAYOUTS[layout][0] * size + 0.37), line * 0.21


def _line(line: int, size: int, layout: str = "strip"):
    """A lazy image, its class map and angles on the line's own (georeferenced) grid."""
    import rioxarray  # noqa: F401  (registers .rio)

    from brdfcorr.geometry import relative_azimuth
    from brdfcorr.models import get_model

    rtlsr = get_model("ross_thick_li_sparse")
    columns, rows = _offset(line, size, layout)
    length = LAYOUTS[layout][1] * size
    x = ORIGIN[0] + PIXEL * (columns + np.arange(size) + 0.5)
    y = ORIGIN[1] - PIXEL * (rows + np.arange(length) + 0.5)
    vza = np.linspace(2.0, 40.0, size)[None, :] * np.ones((length, 1))
    sza, saa = np.linspace(30.0, 38.0, length)[:, None] * np.ones((1, size)), np.full((length, size), 150.0)
    vaa = np.full((length, size), 90.0 if line % 2 == 0 else 270.0)
    phi = relative_azimuth(saa, vaa)
    classes = ((y[:, None] - y.min()) * 4 // (length * PIXEL) + 1).astype(np.int32) * np.ones((1, size), np.int32)

    def block(block_id=None):
        _, row, column = block_id
        rows_, columns_ = slice(row * CHUNK, (row + 1) * CHUNK), slice(column * CHUNK, (column + 1) * CHUNK)
        rng = np.random.default_rng(line * 10_000 + row * 100 + column)
        ground = (x[columns_] - ORIGIN[0]) / 1000.0  # [km]
        cover = 1.0 + 0.2 * np.sin(ground / 0.5)[None, None, :]
        brdf = rtlsr(sza[rows_, columns_][None], vza[rows_, columns_][None], phi[rows_, columns_][None],
                     **{k: v[:, None, None] for k, v in WEIGHTS.items()})
        noise = 1 + 0.01 * rng.standard_normal(brdf.shape)
        return (np.pi * brdf * cover * noise).astype(np.float32)

    cube = da.map_blocks(block, dtype=np.float32, chunks=((BANDS,), (CHUNK,) * (length // CHUNK),
                                                          (CHUNK,) * (size // CHUNK)))

    def on_grid(array):
        array = array.assign_coords(x=("x", x), y=("y", y)).rio.write_crs("EPSG:32632")
        return array.rio.write_transform(array.rio.transform(recalc=True))

    angles = xr.Dataset({k: on_grid(xr.DataArray(v, dims=("y", "x")))
                         for k, v in {"sza": sza, "saa": saa, "vza": vza, "vaa": vaa}.items()})
    return (on_grid(xr.DataArray(cube, dims=("band", "y", "x"), coords={"band": np.arange(1, BANDS + 1)})),
            on_grid(xr.DataArray(classes, dims=("y", "x"))), angles)


def run_one(levels: str, lines: int, size: int, layout: str = "strip") -> dict:
    from brdfcorr.fit import ClassModels, Sampling, fit_classes

    images, maps, angle_sets = zip(*(_line(line, size, layout) for line in range(lines)))
    start = time.perf_counter()
    result = fit_classes(list(images), list(maps), list(angle_sets), ClassModels("ross_thick_li_sparse"),
                         sampling=Sampling(levels=levels), wavelengths=list(np.linspace(450, 900, BANDS)))
    seconds = time.perf_counter() - start
    ratios = [float(f.params["f_vol"][-1] / f.params["f_iso"][-1]) for f in result.fits if f.params]
    return {"seconds": seconds, "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "f_vol/f_iso": ratios, "notes": [n for f in result.fits for n in f.notes if "resampled" in n][:1]}


def _before(checkout: str, arguments: list[str], after: dict) -> None:
    """The pixel-level fit with the package of ``checkout`` in a fresh process; after / before."""
    environment = dict(os.environ, PYTHONPATH=os.path.abspath(checkout))
    output = subprocess.run([sys.executable, __file__, "--one", "pixel", *arguments], check=True,
                            capture_output=True, text=True, env=environment).stdout
    before = json.loads(output.strip().splitlines()[-1])
    print(f"before ({checkout}): {before['seconds']:.1f} s, peak {before['peak_mib']:.0f} MiB, f_vol/f_iso "
          f"{np.round(before['f_vol/f_iso'], 3).tolist()}; after / before: time "
          f"{after['seconds'] / before['seconds']:.2f}x, peak memory {after['peak_mib'] / before['peak_mib']:.2f}x, "
          f"same f_vol/f_iso: {before['f_vol/f_iso'] == after['f_vol/f_iso']}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=4)
    parser.add_argument("--size", type=int, default=1000, help="pixels per side (a multiple of 250)")
    parser.add_argument("--layout", choices=tuple(LAYOUTS), default="strip")
    parser.add_argument("--before", metavar="CHECKOUT", help="also run the pixel fit with this checkout's package")
    parser.add_argument("--one", choices=("pooled", "pixel"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, args.lines, args.size, args.layout)))
        return
    arguments = ["--lines", str(args.lines), "--size", str(args.size), "--layout", args.layout]
    results = compare_levels(__file__, arguments)
    shift, length = LAYOUTS[args.layout]
    width = _offset(args.lines - 1, args.size, args.layout)[0] + args.size
    resampled = 4 * args.lines * BANDS * (length * args.size + 1) * np.ceil(width) / 2**20
    truth = WEIGHTS["f_vol"][-1] / WEIGHTS["f_iso"][-1]
    print(f"{args.lines} lines x {BANDS} bands x {length * args.size} x {args.size} ({args.layout}) on their own grids "
          f"(lazy): pixel levels on the common grid / pooled: time "
          f"{results['pixel']['seconds'] / results['pooled']['seconds']:.2f}x, peak "
          f"memory {results['pixel']['peak_mib'] / results['pooled']['peak_mib']:.2f}x (resampled float32 cubes "
          f"would hold {resampled:.0f} MiB); truth f_vol/f_iso {truth:.3f}")
    if args.before:
        _before(args.before, arguments, results["pixel"])


if __name__ == "__main__":
    main()
