"""Benchmark: the true error of ``--factor-at nodes`` over a whole real Sentinel-2 tile (run by hand;
not part of the test suite).

The c-factor of Roy et al. (2017) evaluated at the 23 x 23 nodes of the 5 km angle grids and
interpolated bilinearly to the pixels (:func:`brdfcorr.correction.nodes.normalize_at_nodes`,
sen2nbar's method) against the c-factor at every pixel from the angles interpolated to it
(:func:`brdfcorr.correction.normalize`, the default), both on a cube of ones, so that each output
is the factor itself. The grids are the real granule's (``MTD_TL.xml`` of T23LLF, 2019-04-25,
``shared/realdata``; ``--mtd-tl``), the whole 109.8 km tile at ``--resolution`` (default 60 m,
1830 x 1830 pixels: 83 pixels between nodes, enough to follow the error's shape between them), for
the nine bands with Roy 2017 weights, with the view grids averaged over the bands (the default)
and each band's own (``--view-band each``), the reference sun zenith each pixel's own
(``observed``, sen2nbar's) and a fixed one (``--fixed-sza``, default 40 deg).

Printed per configuration: the maximum and the 50th, 99th and 99.9th percentiles of
|nodes factor / per-pixel factor - 1| over every band and pixel, the share of pixels above 0.1 %,
where the maximum lies (pixel row and column, km from the tile's upper-left corner) and the largest
view azimuth step between the four nodes of its grid cell; then the same maximum split by that
step (cells whose nodes' view azimuths span more than ``--jump`` degrees, default 10, against the
rest): what evaluating the factor per pixel (interpolating the angles, not the factor) only in
the cells with a jump leaves, at the cost of the share of pixels in those cells. Then the error
of :func:`normalize_at_nodes` as it is (the per-pixel factor in the cells spanning more than
:data:`~brdfcorr.correction.nodes.JUMP`) and the seconds of the three methods (this process, a
cube of ones, the angle grids' interpolation included; ``bench_sen2nbar.py`` times whole runs
with files).

Measured (issue 40, 2 shared cores): ``docs/sensors.md`` ("Where the c-factor is evaluated").

Usage::

    python benchmarks/bench_nodes_error.py [--mtd-tl MTD_TL.xml] [--resolution 60] [--fixed-sza 40]
        [--jump 10 30 60 90] [--repeat 1] [--window RIGHT_KM DOWN_KM SIDE_KM]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import xarray as xr
from affine import Affine

from brdfcorr.correction import normalize
from brdfcorr.correction.nodes import JUMP, azimuth_span, node_angles, normalize_at_nodes
from brdfcorr.io.sensors.grids import GRID_SOURCE, grid_template
from brdfcorr.io.sensors.sentinel2 import parse_mtd_tl, read_sentinel2_angles
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.params import ClassEntry, ParameterTable, ReferenceGeometry

MTD = Path(__file__).resolve().parents[2] / "shared" / "realdata" / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"
#: The Sentinel-2 bands with Roy et al. (2017) weights.
BANDS = ("B02", "B03", "B04", "B05", "B06", "B07", "B08", "B11", "B12")
CHUNK = 610


def roy2017_table(bands) -> ParameterTable:
    """One class (id 1) with the Roy 2017 weights of ``bands`` (Sentinel-2 names), in their order."""
    entry = load_coefficients("roy2017").table_entry(1, sensor="sentinel2", bands=list(bands))
    return ParameterTable(classes=[ClassEntry(**entry)])


def factors(angles: xr.Dataset, bands, reference: ReferenceGeometry, repeat: int = 1) -> tuple[np.ndarray, ...]:
    """The c-factor of ``bands`` (band, y, x) at every pixel, at the nodes interpolated everywhere
    (``jump=None``, the default) and with the per-pixel factor in the cells with an azimuth jump,
    and the seconds each took (the best of ``repeat`` runs)."""
    ones = xr.ones_like(angles["sza"], dtype=np.float64).expand_dims(band=np.arange(1, len(bands) + 1))
    ones = ones.rio.write_transform(angles["sza"].rio.transform()).rio.write_crs(angles["sza"].rio.crs)
    classes = xr.ones_like(angles["sza"], dtype=np.uint8)
    table = roy2017_table(bands)
    layers = {name: angles[name] for name in ("sza", "saa", "vza", "vaa")}
    methods = (lambda: normalize(ones, classes, layers, table, reference, limits=None),
               lambda: normalize_at_nodes(ones, layers, table, reference, limits=None, jump=None),
               lambda: normalize_at_nodes(ones, layers, table, reference, limits=None, jump=JUMP))
    seconds, results = np.full(3, np.inf), []
    for _ in range(repeat):
        results = []
        for index, method in enumerate(methods):
            start = time.perf_counter()
            results.append(method().reflectance.values)
            seconds[index] = min(seconds[index], time.perf_counter() - start)
    return (*results, seconds)


def pixel_cells(layer: xr.DataArray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel row and column, the index of the grid cell (between node k and k + 1) it lies in,
    clamped to the outermost cells (beyond the outermost nodes the edge values are held)."""
    shape, values, source, target, _ = layer.encoding[GRID_SOURCE]
    rows = (target.f + target.e * (np.arange(shape[0]) + 0.5) - source.f) / source.e - 0.5
    cols = (target.c + target.a * (np.arange(shape[1]) + 0.5) - source.c) / source.a - 0.5
    return _cell_index(rows, values.shape[-2]), _cell_index(cols, values.shape[-1])


def _cell_index(positions: np.ndarray, nodes: int) -> np.ndarray:
    return np.clip(np.floor(positions), 0, nodes - 2).astype(int)


def read_angles(mtd: Path, resolution: int, band: str | None, window: tuple[float, float, float] | None):
    """The granule's angles at ``resolution`` [m] on the whole tile, or on ``window`` (km right of
    and below the tile's upper-left corner, and its side [km])."""
    if window is None:
        return read_sentinel2_angles(mtd, resolution=resolution, band=band, chunks=CHUNK)
    tile = parse_mtd_tl(mtd)
    corner = tile.geopositions[resolution]
    right, down, side = (1000.0 * value for value in window)
    transform = Affine(corner.a, 0.0, corner.c + right, 0.0, corner.e, corner.f - down)
    size = int(round(side / resolution))
    like = grid_template(transform, (size, size), tile.crs, chunks=CHUNK)
    return read_sentinel2_angles(mtd, like, band=band, chunks=CHUNK)


def report(what: str, error: np.ndarray, span_per_pixel: np.ndarray, resolution: int, jumps: list[float]) -> None:
    """Print the statistics of ``error`` (band, y, x) described in the module docstring."""
    flat = error[np.isfinite(error)]
    band, row, col = np.unravel_index(np.nanargmax(error), error.shape)
    p50, p99, p999 = np.percentile(flat, [50, 99, 99.9])
    print(f"{what}:\n  max {100 * flat.max():.3f} %, median {100 * p50:.4f} %, 99th {100 * p99:.3f} %, "
          f"99.9th {100 * p999:.3f} %; {100 * np.mean(flat > 1e-3):.1f} % of band-pixels above 0.1 %")
    print(f"  the maximum: band {BANDS[band] if error.shape[0] == len(BANDS) else band}, "
          f"{row * resolution / 1000:.1f} km down, {col * resolution / 1000:.1f} km right; its cell's nodes' "
          f"view azimuths span {span_per_pixel[row, col]:.0f} deg")
    for jump in jumps:
        jumping = np.broadcast_to(span_per_pixel > jump, error.shape)
        calm = error[~jumping & np.isfinite(error)]
        rest = (f"max {100 * calm.max():.4f} %, {100 * np.mean(calm > 1e-3):.2f} % above 0.1 %" if calm.size
                else "none")
        print(f"  cells whose view azimuths span > {jump:g} deg: {100 * jumping[0].mean():.1f} % of the pixels; "
              f"the other cells: {rest}")


def run(mtd: Path, resolution: int, view_band: str | None, reference: ReferenceGeometry, jumps: list[float],
        window=None, repeat: int = 1) -> None:
    """One configuration: the view grids of ``view_band`` (None: averaged; "each": per band)."""
    per_band = BANDS if view_band == "each" else (None,)
    errors, mixed_errors, spans, seconds = [], [], None, np.zeros(3)
    for band in per_band:
        angles = read_angles(mtd, resolution, band, window)
        pixels, nodes, mixed, taken = factors(angles, BANDS if band is None else (band,), reference, repeat)
        errors.append(np.abs(nodes / pixels - 1.0))
        mixed_errors.append(np.abs(mixed / pixels - 1.0))
        seconds += taken
        vaa = node_angles({name: angles[name] for name in ("sza", "saa", "vza", "vaa")})["vaa"].values
        rows, cols = pixel_cells(angles["vaa"])
        span = azimuth_span(vaa)[rows[:, None], cols[None, :]]
        spans = span if spans is None else np.maximum(spans, span)
    what = "each band's own view grids" if view_band == "each" else "view grids averaged over the bands"
    report(f"{what}, reference sun zenith {reference.sza}", np.concatenate(errors), spans, resolution, jumps)
    mixed = np.concatenate(mixed_errors)
    print(f"  with the per-pixel factor in the cells spanning > {JUMP:g} deg (jump={JUMP:g}): max "
          f"{100 * np.nanmax(mixed):.4f} %, {100 * np.nanmean(mixed > 1e-3):.2f} % of band-pixels above 0.1 %; "
          f"seconds (factor at the pixels, at the nodes, nodes with per-pixel jump cells; one process, "
          f"a cube of ones): {seconds[0]:.1f}, {seconds[1]:.1f}, {seconds[2]:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mtd-tl", type=Path, default=MTD, help="a granule's MTD_TL.xml [default: T23LLF]")
    parser.add_argument("--resolution", type=int, default=60, choices=(10, 20, 60), help="pixel size [m]")
    parser.add_argument("--fixed-sza", type=float, default=40.0, help="the fixed reference sun zenith [deg]")
    parser.add_argument("--jump", type=float, nargs="+", default=[10.0, 30.0, 60.0, 90.0],
                        help="cells' view azimuth spans [deg] that count as a jump [default: 10 30 60 90]")
    parser.add_argument("--repeat", type=int, default=1, help="timed runs of each method, the best kept")
    parser.add_argument("--window", type=float, nargs=3, metavar=("RIGHT_KM", "DOWN_KM", "SIDE_KM"),
                        help="a square window of the tile instead of the whole tile")
    args = parser.parse_args()
    where = "the whole tile" if args.window is None else "the window {} km right, {} km down, {} km wide".format(
        *args.window)
    print(f"{args.mtd_tl}: {where} at {args.resolution} m; |nodes factor / per-pixel factor - 1|, "
          f"bands {', '.join(BANDS)} (Roy 2017 weights)")
    for view_band in (None, "each"):
        for sza in ("observed", args.fixed_sza):
            run(args.mtd_tl, args.resolution, view_band, ReferenceGeometry(sza=sza, vza=0.0, raa=0.0), args.jump,
                args.window, args.repeat)


if __name__ == "__main__":
    main()
