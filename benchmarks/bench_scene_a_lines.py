"""Benchmark: scene A' with a second, overlapping line over the same ground, fitted as overlapping
flight lines on their own grids (issue 37; run by hand, about a minute at ``--bands 12``).

Scene A' is ``bench_kernels.py``'s vegetation/soil line with its fields mirrored about the swath's
centre column (the truth's own east/west difference is 0). Here the ground is wider than a line:
the vegetation fraction and the albedo texture are drawn once over ``columns + --shift`` columns
(line 1's part mirrored about line 1's centre, as in A'), and two lines of ``rows x columns``
pixels see it, the second ``--shift`` columns further east: a different view ramp over the same
ground (the overlap lies in line 1's eastern, forward-scattering half and in line 2's western,
backscattering half), under the same morning sun, with noise drawn independently per line. Each
line is georeferenced on its own grid (10 m pixels; the second's extent differs), so a fit over
both takes ``fit_classes``' common-grid path (:mod:`brdfcorr.fit.grids`), as ``brdfcorr
fit-classes LINE1 LINE2 --levels ...`` does.

Each line's strata are cut from its own NDVI (five percentile strata, as ``brdfcorr classes ndvi``
per line: the strata that keep A' at 3.5 % east/west). The fit over both lines is pooled (one level
per stratum), ``auto`` or ``pixel`` (each common-grid pixel's level free, the shape fitted to the
differences between its two views); line 1 is then corrected with the table to its reference
(scene-mean sun, nadir view). Printed per row: the median error of the correction factor (against
the truth with the same noise), the worst east/west difference by true-fraction group on line 1
(goal <= 0.2 %), binned and with the strata's coefficients interpolated in NDVI, and the fit's
notes on free levels. Line 1 alone (``bench_kernels.py``'s A' workflow) is the first row.

Measured (400 x 600 x 60, 1 % noise, seed 0; binned / interpolated): line 1 alone 3.42 / 3.27 %,
both lines pooled 3.71 / 3.40 % (median error 0.258 %), both lines with each pixel's level free
(``auto`` picks it) 0.08 / 0.14 %, median error 0.033 %: the goal is met (seeds 1 and 2 at 12
bands: 0.13 / 0.17 % and 0.09 / 0.11 %). The fit frees no level
per line there (the spread within pixels left beside the lines' own levels is 3.3-3.6 deg): with
one (the fit before issue 37's follow-up) the same rows were 16.2 / 16.1 % at 12 bands, worse than pooled.

    python benchmarks/bench_scene_a_lines.py [--bands 12] [--shift 300]
"""

from __future__ import annotations

import math
import time

import numpy as np
import xarray as xr
from bench_kernels import (
    PERCENTILES,
    RTLSR,
    _package,
    _reference_angles,
    class_map,
    correct,
    evaluate,
    fit,
    fraction_groups,
    line_geometry,
    mirrored,
    rtlsr_weights,
    scene_parser,
    scores,
    smooth_field,
)
from bench_ndvi_strata import ndvi_of, strata_of

from brdfcorr.geometry import relative_azimuth

ORIGIN, PIXEL, CRS = (600_000.0, 5_100_000.0), 10.0, "EPSG:32632"
GOAL = 0.002


def georeferenced(array: xr.DataArray, offset: int) -> xr.DataArray:
    """``array`` (…, y, x) on a 10 m UTM grid whose first column lies ``offset`` columns east of
    line 1's."""
    import rioxarray  # noqa: F401  (registers .rio)

    x = ORIGIN[0] + PIXEL * (offset + np.arange(array.sizes["x"]) + 0.5)
    y = ORIGIN[1] - PIXEL * (np.arange(array.sizes["y"]) + 0.5)
    array = array.assign_coords(x=("x", x), y=("y", y)).rio.write_crs(CRS)
    return array.rio.write_transform(array.rio.transform(recalc=True))


def line_over(ground: dict, offset: int, rows: int, columns: int, wavelengths, rng, noise: float) -> dict:
    """A line of ``rows x columns`` over ``ground``'s columns ``offset ..``: observed at its own
    geometry (:func:`bench_kernels.line_geometry`), true at its reference, georeferenced."""
    angles = line_geometry(rows, columns)
    fraction = ground["fraction"][:, offset:offset + columns]
    texture = ground["texture"][:, offset:offset + columns]
    weights = rtlsr_weights(wavelengths)
    flat = {name: value.ravel().astype(float) for name, value in angles.items()}
    phi = relative_azimuth(flat["saa"], flat["vaa"])
    reference_sza = float(angles["sza"].mean())
    v, scale = fraction.ravel(), math.pi * texture.ravel()

    def render(*geometry):
        return (v * evaluate(RTLSR, weights["vegetation"], *geometry)
                + (1 - v) * evaluate(RTLSR, weights["soil"], *geometry)) * scale

    line = _package(render(flat["sza"], flat["vza"], phi), render(*_reference_angles(angles, reference_sza)),
                    angles, wavelengths, rng, noise, reference_sza, fraction=fraction, weights=weights)
    line["image"] = georeferenced(line["image"], offset)
    line["angles"] = xr.Dataset({name: georeferenced(line["angles"][name], offset) for name in line["angles"]})
    return line


def two_lines(rows: int, columns: int, bands: int, noise: float, shift: int, seed: int = 0) -> list[dict]:
    """Line 1 (scene A': its fields mirrored about its centre column) and line 2, ``shift``
    columns east, over one ground."""
    rng = np.random.default_rng(seed)
    width = columns + shift
    fraction = 1.0 / (1.0 + np.exp(-2.5 * smooth_field(rng, (rows, width), 12.0)))
    texture = 1.0 + 0.1 * smooth_field(rng, (rows, width), 2.0)
    fraction[:, :columns], texture[:, :columns] = mirrored(fraction[:, :columns]), mirrored(texture[:, :columns])
    ground = {"fraction": fraction, "texture": texture}
    wavelengths = np.linspace(400.0, 1000.0, bands)
    return [line_over(ground, offset, rows, columns, wavelengths, rng, noise) for offset in (0, shift)]


def row(label: str, lines: list[dict], strata: list[np.ndarray], levels: str) -> None:
    """Fit over ``lines`` (line 1 alone: one line) with ``levels``, correct line 1, print the scores."""
    start = time.perf_counter()
    maps = [class_map(line, s) for line, s in zip(lines, strata)]
    maps = [georeferenced(layer, 0) if len(lines) == 1 else layer.assign_coords(x=line["image"]["x"],
                                                                                  y=line["image"]["y"])
            for line, layer in zip(lines, maps)]
    result = fit(lines[0], maps[0], "ross_thick_li_sparse", list(zip(lines[1:], maps[1:])), levels=levels)
    groups, values = fraction_groups(lines[0]), []
    for continuous in (False, True):
        table = result.table.with_ndvi_interpolation({"classes": list(result.table.class_ids)}) \
            if continuous else result.table
        values.append(scores(lines[0], correct(lines[0], maps[0], table), groups, range(1, len(PERCENTILES) + 2)))
    free = sorted({fit_.levels for fit_ in result.fits})
    met = "met" if values[1]["after"] <= GOAL else "MISSED"
    print(f"  {label:44s} {values[0]['brdf']:6.3%} {values[0]['after']:6.2%} {values[1]['after']:6.2%} "
          f"({met})  levels {'/'.join(free)}  {time.perf_counter() - start:5.1f} s")
    for kind in ("seen by", "per scene", "pooled"):  # the first class's note of each kind
        note = next((note for fit_ in result.fits for note in fit_.notes if kind in note), None)
        if note is not None:
            print(f"    e.g. {note}")


def main() -> None:
    parser = scene_parser(__doc__.splitlines()[0])
    parser.add_argument("--shift", type=int, default=300, help="columns line 2 lies east of line 1")
    parser.add_argument("--seed", type=int, default=0, help="seed of the ground's fields and the noise")
    args = parser.parse_args()
    lines = two_lines(args.rows, args.columns, args.bands, args.noise, args.shift, args.seed)
    strata = [strata_of(ndvi_of(line, line["image"].values)) for line in lines]
    print(f"scene A' ({args.bands} bands x {args.rows} x {args.columns}, noise {args.noise:.1%}) and a second "
          f"line {args.shift} columns east over the same ground, each on its own grid; strata of each line's "
          f"own NDVI. Line 1 corrected: median error; worst east/west by true-fraction group, binned and "
          f"interpolated (goal <= {GOAL:.1%})")
    row("line 1 alone (pooled)", lines[:1], strata[:1], "pooled")
    for levels in ("pooled", "auto", "pixel"):
        row(f"2 lines, levels {levels}", lines, strata, levels)


if __name__ == "__main__":
    main()
