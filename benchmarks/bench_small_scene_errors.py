"""Benchmark: are the imagery fit's errors calibrated on small scenes (issue 27)? Pull SDs by model,
scene size and noise.

The scene of issue 27: paper 003's red concrete (Table 1: t0 = 0.0192, t1 = 1.06 sr^-1, w = 0.0804
deg^-1, n = 1.48, k = 0.25; a second band with both intensities 1.6 times as large), Torrance-Sparrow,
under the push-broom geometry of :func:`brdfcorr.testing.synthetic_angles` (sun zenith 30-40 deg,
view zenith 0-40 deg across track, relative azimuth 60-120 deg), every pixel of the class, with the
spatial blocks of ``fit-classes`` (32 pixels: a 50 x 80 scene has 6) as the clusters of the errors.
The same scene with the other imagery models (:data:`TRUTHS`): the simplified Torrance-Sparrow
model (G = 1) with the same parameters, the empirical model, Ross-Thick/Li-Sparse (MODIS-like red
and near-infrared weights) and RPV. Noise: ``multiplicative`` 3 % of the BRDF, independent (issue
27), or ``block`` 2 % shared by the pixels of an 8 x 8 patch plus 2 % independent (correlated
albedo, which the clusters must absorb).

For every model and size the fits of S seeds give the pull ``(fit - truth) / error`` of each free
parameter; calibrated errors give a pull standard deviation of 1, with a sampling error of about
``1 / sqrt(2 S)`` (0.065 for 120 seeds). Printed per model and size: the blocks G, the median
smallest effective degrees of freedom of the errors, the share of fits flagged ``errors_reliable =
False``, the pull SDs over all fits (range, and the parameter farthest from 1) and over the
reliable ones (``-`` where fewer than 20 are), then every parameter's SD (band 1/band 2).

    python benchmarks/bench_small_scene_errors.py [--models torrance_sparrow rpv] [--seeds 120] \
        [--noise multiplicative] [--sizes 50x80 200x300] [--quick]

On one core a fit of the 50 x 80 scene takes 0.01 (Ross-Thick/Li-Sparse) to 0.3 s (RPV), of the
200 x 300 scene 0.1 to 1.5 s. ``--quick`` (every model, 20 seeds, 50 x 80 and 120 x 200: about 40 s) is a
smoke test: its sampling error of 0.16 per SD is too large to judge calibration, so it gives no verdict.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.testing import SMALL_SCENE_TRUTHS as TRUTHS
from brdfcorr.testing import pixel_blocks, small_scene_samples

SIZES = ("50x80", "80x120", "120x200", "200x300")
#: Bounds of a calibrated pull SD (issue 27's goal).
CALIBRATED = (0.85, 1.15)
#: Fewest seeds for a verdict: a pull SD's sampling error 1 / sqrt(2 S) is then <= 0.07, so a
#: calibrated SD leaves 0.85-1.15 only beyond about two sampling errors.
MIN_SEEDS = 100


def scene(model: str, ny: int, nx: int, block: int = 32):
    """Angles [deg] of every pixel of an ny x nx push-broom scene (view zenith 0-40 deg), the
    noise-free BRDF (N, 2) [sr^-1] of ``model`` with its :data:`TRUTHS`
    (:mod:`brdfcorr.testing.small_scenes`), each pixel's spatial block and its 8 x 8 texture patch."""
    sza, vza, phi, clean = small_scene_samples(model, ny, nx)
    return sza, vza, phi, clean, pixel_blocks(ny, nx, block), pixel_blocks(ny, nx, 8)


def noisy(clean: np.ndarray, patches: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    """The BRDF with noise of ``kind`` (module docstring)."""
    if kind == "multiplicative":
        return clean * (1 + 0.03 * rng.standard_normal(clean.shape))
    if kind == "block":
        shared = rng.standard_normal(patches.max() + 1)[patches, None]
        return clean * (1 + 0.02 * shared + 0.02 * rng.standard_normal(clean.shape))
    raise ValueError(f"unknown noise {kind!r}")


def sweep(model: str, ny: int, nx: int, seeds: int, kind: str, block: int = 32) -> dict:
    """Pulls (seeds, 2 bands) per free parameter, the flags and the smallest effective dof per fit."""
    sza, vza, phi, clean, blocks, patches = scene(model, ny, nx, block)
    truth = TRUTHS[model]
    pulls: dict[str, list] = {}
    reliable, dof = [], []
    for seed in range(seeds):
        brdf = noisy(clean, patches, kind, np.random.default_rng(seed))
        result = fit_class_samples(model, sza, vza, phi, brdf, clusters=blocks)
        for name in result["free"]:
            pulls.setdefault(name, []).append((result["params"][name] - truth[name]) / result["errors"][name])
        reliable.append(result["errors_reliable"])
        dof.append(float(np.min(result["error_dof"])))
    return {"pulls": {name: np.array(values) for name, values in pulls.items()},
            "reliable": np.array(reliable), "dof": np.array(dof), "blocks": int(np.unique(blocks).size)}


def pull_sds(pulls: dict, keep: np.ndarray) -> dict | None:
    """Pull SD per parameter and band (None where fewer than 20 fits are kept); a shape parameter
    (equal in both bands) keeps one value."""
    if keep.sum() < 20:
        return None
    sds = {name: values[keep].std(axis=0, ddof=1) for name, values in pulls.items()}
    return {name: sd[:1] if np.allclose(pulls[name][:, 0], pulls[name][:, -1]) else sd for name, sd in sds.items()}


def summary(sds: dict | None) -> str:
    """``min-max (worst NAME SD)`` of the pull SDs, ``-`` without them."""
    if sds is None:
        return "-"
    flat = [(abs(value - 1.0), value, name) for name, values in sds.items() for value in values]
    low, high = min(value for _, value, _ in flat), max(value for _, value, _ in flat)
    _, worst, name = max(flat)
    return f"{low:.2f}-{high:.2f} (worst {name} {worst:.2f})"


def details(sds: dict | None) -> str:
    if sds is None:
        return ""
    return ", ".join(f"{name} " + "/".join(f"{value:.2f}" for value in values) for name, values in sds.items())


def within(sds: dict | None) -> bool:
    """Every SD within :data:`CALIBRATED` (True without SDs: nothing reliable to judge)."""
    return sds is None or all(CALIBRATED[0] <= value <= CALIBRATED[1] for values in sds.values() for value in values)


def pull_means(pulls: dict) -> str:
    """Every parameter's mean pull per band over all fits, with the mean's own 1-sigma (SD / sqrt(S))."""
    parts = []
    for name, values in pulls.items():
        means, errors = values.mean(axis=0), values.std(axis=0, ddof=1) / np.sqrt(values.shape[0])
        bands = range(1) if np.allclose(values[:, 0], values[:, -1]) else range(values.shape[1])
        parts.append(f"{name} " + "/".join(f"{means[b]:+.2f}" for b in bands) + " (+-" +
                     "/".join(f"{errors[b]:.2f}" for b in bands) + ")")
    return ", ".join(parts)


def report(model: str, size: str, seeds: int, kind: str, block: int = 32) -> bool:
    """Fit ``seeds`` scenes, print one table row and the per-parameter SDs; whether the reliable
    fits are calibrated."""
    start = time.perf_counter()
    ny, nx = (int(value) for value in size.split("x"))
    found = sweep(model, ny, nx, seeds, kind, block)
    reliable = found["reliable"]
    every, trusted = pull_sds(found["pulls"], np.ones_like(reliable)), pull_sds(found["pulls"], reliable)
    print(f"{model:<28}{size:<9}{found['blocks']:>4}{np.median(found['dof']):>7.1f}{1 - reliable.mean():>8.0%}  "
          f"{summary(every):<30}{summary(trusted):<30}({time.perf_counter() - start:.0f} s)")
    print(f"{'':<37}all: {details(every)}")
    print(f"{'':<37}mean pulls, all: {pull_means(found['pulls'])}")
    if trusted is not None and reliable.mean() < 1:
        print(f"{'':<37}reliable: {details(trusted)}")
    return within(trusted)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", choices=list(TRUTHS), default=list(TRUTHS))
    parser.add_argument("--seeds", type=int, default=120)
    parser.add_argument("--noise", nargs="+", choices=("multiplicative", "block"), default=["multiplicative"])
    parser.add_argument("--sizes", nargs="+", default=list(SIZES), help="scene sizes, rows x columns")
    parser.add_argument("--quick", action="store_true", help="20 seeds of the 50 x 80 and 120 x 200 scenes")
    parser.add_argument("--block-size", type=int, default=32,
                        help="side of the error clusters [pixels; default: 32, fit-classes' default; 8 is what its "
                             "UNRELIABLE message advises on a small scene]")
    args = parser.parse_args()
    if args.quick:
        args.seeds, args.sizes = 20, ["50x80", "120x200"]
    calibrated = True
    for kind in args.noise:
        print(f"\n{kind} noise, {args.seeds} seeds, blocks of {args.block_size} pixels; sampling error of a pull "
              f"SD ~ {1 / np.sqrt(2 * args.seeds):.3f}")
        print(f"{'model':<28}{'scene':<9}{'G':>4}{'dof':>7}{'flagged':>8}  {'pull SDs, all fits':<30}"
              f"{'reliable fits':<30}")
        for model in args.models:
            for size in args.sizes:
                calibrated &= report(model, size, args.seeds, kind, args.block_size)
    if args.seeds < MIN_SEEDS:
        print(f"{args.seeds} seeds: too few to judge calibration (at least {MIN_SEEDS})")
    else:
        print(f"every pull SD of the reliable fits within {CALIBRATED[0]}-{CALIBRATED[1]}: "
              f"{'yes' if calibrated else 'NO'}")


if __name__ == "__main__":
    main()
