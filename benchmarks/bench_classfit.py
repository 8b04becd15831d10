"""Benchmark: fitting 10 classes x 200 bands from 1 million samples (issue 6 target: well under a
minute on the 2-core reference machine).

Prints the wall time of the whole fit and, as a machine-independent figure, its ratio to the time
of one pass of the bare linear algebra the fit cannot avoid (``basis @ data`` for every class, i.e.
reading every sample of every band once), measured in the same run.

    python benchmarks/bench_classfit.py [--samples 1000000] [--classes 10] [--bands 200]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from brdfcorr.fit.classes import ClassSamples, fit_one_class
from brdfcorr.models import torrance_sparrow


def synthesize(n: int, bands: int, rng: np.random.Generator):
    sza, vza = rng.uniform(25, 50, n), rng.uniform(0, 40, n)
    phi = np.where(rng.random(n) < 0.5, rng.uniform(150, 180, n), rng.uniform(0, 30, n))
    t0 = rng.uniform(0.005, 0.1, bands)
    t1 = rng.uniform(0.05, 0.5, bands)
    w = rng.uniform(0.03, 0.15)
    brdf = torrance_sparrow(sza[:, None], vza[:, None], phi[:, None], t0=t0, t1=t1, w=w, n=1.6, k=0.25)
    brdf *= rng.normal(1, 0.05, (n, 1)) * (1 + 0.01 * rng.standard_normal(brdf.shape))
    return sza, vza, phi, brdf, w


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="total samples (all classes)")
    parser.add_argument("--classes", type=int, default=10)
    parser.add_argument("--bands", type=int, default=200)
    args = parser.parse_args()
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
