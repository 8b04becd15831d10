"""Benchmark: are the imagery fit's errors calibrated on small scenes (issue 27)? Pull SDs by scene size.

The scene of issue 27: paper 003's red concrete (Table 1: t0 = 0.0192, t1 = 1.06 sr^-1, w = 0.0804
deg^-1, n = 1.48, k = 0.25; a second band with both intensities 1.6 times as large), Torrance-Sparrow,
under the push-broom geometry of :func:`brdfcorr.testing.synthetic_angles` (sun zenith 30-40 deg,
view zenith 0-40 deg across track), every pixel of the class, with the spatial blocks of
``fit-classes`` (32 pixels: a 50 x 80 scene has 6) as the clusters of the errors. Noise:
``multiplicative`` 3 % of the BRDF, independent (issue 27), or ``block`` 2 % shared by the pixels
of an 8 x 8 patch plus 2 % independent (correlated albedo, which the clusters must absorb).

For every size the fits of S seeds give the pull ``(fit - truth) / error`` of each free parameter;
calibrated errors give a pull standard deviation of 1, with a sampling error of about
``1 / sqrt(2 S)`` (0.065 for 120 seeds). Printed per size: the blocks G, the median effective
degrees of freedom of the errors, the share of fits flagged ``errors_reliable = False``, and the
pull SDs over all fits and over the reliable ones (``-`` where fewer than 20 are).

    python benchmarks/bench_small_scene_errors.py [--seeds 120] [--noise multiplicative] [--sizes 50x80 200x300]

About 0.1 s per fit of the 50 x 80 scene on one core.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.geometry import relative_azimuth
from brdfcorr.models import torrance_sparrow
from brdfcorr.testing import synthetic_angles

#: Paper 003, Table 1, red concrete (550 nm); band 2 has both intensities 1.6 times as large.
TRUTH = {"t0": np.array([0.0192, 0.0307]), "t1": np.array([1.06, 1.70]), "w": 0.0804, "n": 1.48, "k": 0.25}
NAMES = ("w", "n", "t0", "t1")
SIZES = ("50x80", "80x120", "120x200", "200x300")


def scene(ny: int, nx: int, block: int = 32):
    """Angles [deg] of every pixel of an ny x nx push-broom scene (view zenith 0-40 deg), the
    noise-free BRDF (N, 2) [sr^-1], each pixel's spatial block and its 8 x 8 texture patch."""
    angles = synthetic_angles(ny, nx, vza_max=40.0, dtype=np.float64)
    sza, vza = angles["sza"].ravel(), angles["vza"].ravel()
    phi = relative_azimuth(angles["saa"], angles["vaa"]).ravel()
    iy, ix = (index.ravel() for index in np.indices((ny, nx)))
    blocks = (iy // block) * -(-nx // block) + ix // block
    patches = (iy // 8) * -(-nx // 8) + ix // 8
    return sza, vza, phi, torrance_sparrow(sza[:, None], vza[:, None], phi[:, None], **TRUTH), blocks, patches


def noisy(clean: np.ndarray, patches: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    """The BRDF with noise of ``kind`` (module docstring)."""
    if kind == "multiplicative":
        return clean * (1 + 0.03 * rng.standard_normal(clean.shape))
    if kind == "block":
        shared = rng.standard_normal(patches.max() + 1)[patches, None]
        return clean * (1 + 0.02 * shared + 0.02 * rng.standard_normal(clean.shape))
    raise ValueError(f"unknown noise {kind!r}")


def sweep(ny: int, nx: int, seeds: int, kind: str) -> dict:
    """Pulls (seeds, 2 bands) per parameter, the flags and the smallest effective dof per fit."""
    sza, vza, phi, clean, blocks, patches = scene(ny, nx)
    pulls: dict[str, list] = {name: [] for name in NAMES}
    reliable, dof = [], []
    for seed in range(seeds):
        brdf = noisy(clean, patches, kind, np.random.default_rng(seed))
        result = fit_class_samples("torrance_sparrow", sza, vza, phi, brdf, clusters=blocks)
        for name in NAMES:
            pulls[name].append((result["params"][name] - TRUTH[name]) / result["errors"][name])
        reliable.append(result["errors_reliable"])
        dof.append(float(np.min(result["error_dof"])))
    return {"pulls": {name: np.array(values) for name, values in pulls.items()},
            "reliable": np.array(reliable), "dof": np.array(dof), "blocks": int(np.unique(blocks).size)}


def _sds(pulls: dict, keep: np.ndarray) -> str:
    if keep.sum() < 20:
        return " ".join(f"{'-':>11}" for _ in NAMES)
    return " ".join(f"{sd[0]:>5.2f}/{sd[1]:<5.2f}" if sd[0] != sd[1] else f"{sd[0]:>11.2f}"
                    for sd in (pulls[name][keep].std(axis=0, ddof=1) for name in NAMES))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=120)
    parser.add_argument("--noise", choices=("multiplicative", "block"), default="multiplicative")
    parser.add_argument("--sizes", nargs="+", default=list(SIZES), help="scene sizes, rows x columns")
    args = parser.parse_args()
    print(f"red concrete, {args.noise} noise, {args.seeds} seeds; sampling error of a pull SD "
          f"~ {1 / np.sqrt(2 * args.seeds):.3f}; SDs of {', '.join(NAMES)} (band 1/band 2)")
    print(f"{'scene':<9}{'G':>4}{'dof':>6}{'flagged':>8}  {'all fits':<47}  reliable fits")
    calibrated = True
    for size in args.sizes:
        start = time.perf_counter()
        ny, nx = (int(value) for value in size.split("x"))
        found = sweep(ny, nx, args.seeds, args.noise)
        reliable = found["reliable"]
        sds = np.array([found["pulls"][name][reliable].std(axis=0, ddof=1) for name in NAMES]) \
            if reliable.sum() >= 20 else np.ones(1)
        calibrated &= bool(np.all((sds >= 0.85) & (sds <= 1.15)))
        print(f"{size:<9}{found['blocks']:>4}{np.median(found['dof']):>6.1f}{1 - reliable.mean():>8.0%}  "
              f"{_sds(found['pulls'], np.ones_like(reliable)):<47}  {_sds(found['pulls'], reliable)}"
              f"   ({time.perf_counter() - start:.0f} s)")
    print(f"every pull SD of the reliable fits within 0.85-1.15: {'yes' if calibrated else 'NO'}")


if __name__ == "__main__":
    main()
