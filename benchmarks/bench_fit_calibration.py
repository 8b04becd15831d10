"""Benchmark: are the imagery fit's errors calibrated? Pull standard deviations over many seeds.

Synthetic classes from a known Torrance-Sparrow model (paper 003, eq. 1; two bands, k fixed at
0.25 as in paper 003) under imagery-like geometry are fitted with
:func:`brdfcorr.fit.solver.fit_class_samples`; for every parameter the pull
``(fit - truth) / error`` is collected over the seeds. Calibrated errors give a pull standard
deviation of 1; its sampling error over S seeds is about ``1 / sqrt(2 S)`` (0.035 for 400 seeds).
Three kinds of noise (issue 17):

- ``additive``: Gaussian, sigma = 0.003 sr^-1 in every sample (homoscedastic);
- ``multiplicative``: 3 % of the BRDF (heteroscedastic, as sensor noise is);
- ``block``: 2 % multiplicative shared by the samples of a spatial block (correlated albedo) plus
  2 % independent, with the blocks as the clusters of the error estimate.

    python benchmarks/bench_fit_calibration.py [--seeds 400] [--samples 3000] [--block 15] [--setup glossy]

Prints one row per noise kind and parameter (band 1 and band 2 for the intensities) and whether
every pull standard deviation lies within 0.9-1.1.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.models import torrance_sparrow

#: The model the samples are drawn from: per-band intensities [sr^-1], shared shape.
TRUTH = {"t0": np.array([0.02, 0.06]), "t1": np.array([0.15, 0.4]), "w": 0.06, "n": 1.6, "k": 0.25}
#: Setups of ``--setup``: ``matte`` (:data:`TRUTH`) and ``glossy``, a narrow, strong specular peak
#: (paper 003, Table 1 roof tile width) over a dark diffuse term, where the fit is most non-linear.
SETUPS = {
    "matte": TRUTH,
    "glossy": {"t0": np.array([0.005, 0.01]), "t1": np.array([0.3, 0.6]), "w": 0.03, "n": 1.6, "k": 0.25},
}
NOISE_KINDS = ("additive", "multiplicative", "block")


def synthetic_class(seed: int, kind: str, n: int = 3000, block: int = 15, truth=TRUTH):
    """One class's samples: sun zenith 25-50 deg, view zenith 0-40 deg, relative azimuth near the
    principal plane (0-30 or 150-180 deg, a wide across-track line), BRDF in two bands with noise
    of ``kind``. Returns theta_i, theta_r, phi [deg], brdf (n, 2) [sr^-1] and the block of each
    sample (``block`` consecutive samples)."""
    rng = np.random.default_rng(seed)
    sza, vza = rng.uniform(25, 50, n), rng.uniform(0, 40, n)
    phi = np.where(rng.random(n) < 0.5, rng.uniform(150, 180, n), rng.uniform(0, 30, n))
    brdf = torrance_sparrow(sza[:, None], vza[:, None], phi[:, None], **truth)
    blocks = np.arange(n) // block
    if kind == "additive":
        noisy = brdf + 0.003 * rng.standard_normal(brdf.shape)
    elif kind == "multiplicative":
        noisy = brdf * (1 + 0.03 * rng.standard_normal(brdf.shape))
    elif kind == "block":
        shared = rng.standard_normal(blocks[-1] + 1)[blocks, None]
        noisy = brdf * (1 + 0.02 * shared + 0.02 * rng.standard_normal(brdf.shape))
    else:
        raise ValueError(f"unknown noise kind {kind!r}; known: {', '.join(NOISE_KINDS)}")
    return sza, vza, phi, noisy, blocks


def pulls(kind: str, seeds: int, n: int = 3000, block: int = 15, truth=TRUTH) -> dict[str, np.ndarray]:
    """``(fit - truth) / error`` per free parameter, shape (seeds, 2 bands), over seeds 0..seeds-1."""
    collected: dict[str, list] = {name: [] for name in ("t0", "t1", "w", "n")}
    for seed in range(seeds):
        sza, vza, phi, brdf, blocks = synthetic_class(seed, kind, n, block, truth)
        result = fit_class_samples("torrance_sparrow", sza, vza, phi, brdf,
                                   clusters=blocks if kind == "block" else None)
        for name, values in collected.items():
            values.append((result["params"][name] - truth[name]) / result["errors"][name])
    return {name: np.array(values) for name, values in collected.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=400)
    parser.add_argument("--samples", type=int, default=3000, help="samples per class")
    parser.add_argument("--block", type=int, default=15, help="samples per spatial block")
    parser.add_argument("--setup", choices=sorted(SETUPS), default="matte")
    args = parser.parse_args()
    print(f"{args.setup}: {args.seeds} seeds, {args.samples} samples, blocks of {args.block}; "
          f"sampling error of a pull SD ~ {1 / np.sqrt(2 * args.seeds):.3f}")
    print(f"{'noise':<15}{'parameter':<10}{'SD band 1':>10}{'SD band 2':>10}{'mean band 1':>12}{'mean band 2':>12}")
    calibrated = True
    for kind in NOISE_KINDS:
        start = time.perf_counter()
        found = pulls(kind, args.seeds, args.samples, args.block, SETUPS[args.setup])
        for name, values in found.items():
            sd, mean = values.std(axis=0, ddof=1), values.mean(axis=0)
            calibrated &= bool(np.all((sd >= 0.9) & (sd <= 1.1)))
            print(f"{kind:<15}{name:<10}{sd[0]:>10.3f}{sd[1]:>10.3f}{mean[0]:>12.3f}{mean[1]:>12.3f}")
        print(f"{kind:<15}({time.perf_counter() - start:.1f} s)")
    print(f"every pull SD within 0.9-1.1: {'yes' if calibrated else 'NO'}")


if __name__ == "__main__":
    main()
