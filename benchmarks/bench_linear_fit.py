"""Benchmark: fitting a kernel-driven model (no shape parameters) to 10 classes x 200 bands from
1 million samples: one weighted linear least-squares pass per class (target: under 5 s on the
2-core reference machine).

Each class is an airborne line (sun zenith 30-50 deg along track, view zenith up to 40 deg on
either side of the track, the sun at a random azimuth to the heading) rendered with the
Ross-Thick Li-Sparse model and known per-band coefficients, times a 5 % per-pixel albedo, plus
1 % noise. Prints the wall time of the fits (:func:`brdfcorr.fit.classes.fit_one_class`, with
cluster-robust errors over spatial blocks and the guard rails) and, as machine-independent
figures, its ratio to two baselines measured in the same run on the same design matrices: the one
product ``design.T @ data`` per class (reading every sample of every band once; by einsum as in
the fit: threaded BLAS on this tall-skinny product is no faster and, on a loaded 2-core machine,
can be 100x slower), and ``numpy.linalg.lstsq(design, data)`` per class (the textbook solve,
without errors). Then the recovered-vs-true coefficients: the spread of the pulls
(fit - truth) / error (1 if the errors are right) and the largest relative error.

    python benchmarks/bench_linear_fit.py [--samples 1000000] [--classes 10] [--bands 200]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from brdfcorr.fit.classes import ClassSamples, fit_one_class
from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.models import get_model

MODEL = get_model("ross_thick_li_sparse")


def airborne_line(n: int, rng: np.random.Generator):
    """Sun and view angles [deg] of ``n`` pixels of one flight line."""
    sza = rng.uniform(30, 50, n)
    across = rng.uniform(-1, 1, n)  # position across the swath
    heading = rng.uniform(0, 360)
    saa = np.full(n, (heading + rng.uniform(0, 360)) % 360)
    vaa = np.where(across < 0, heading - 90.0, heading + 90.0) % 360
    return sza, 40.0 * np.abs(across), relative_azimuth(saa, vaa)


def synthesize(n: int, bands: int, rng: np.random.Generator):
    sza, vza, phi = airborne_line(n, rng)
    truth = {"f_iso": rng.uniform(0.015, 0.15, bands)}
    truth["f_vol"] = truth["f_iso"] * rng.uniform(0.1, 0.8, bands)
    truth["f_geo"] = truth["f_iso"] * rng.uniform(0.02, 0.2, bands)
    brdf = MODEL(sza[:, None], vza[:, None], phi[:, None], **truth)
    brdf *= rng.normal(1, 0.05, (n, 1))  # albedo, shared by the bands of a pixel
    brdf += 0.01 * truth["f_iso"] * rng.standard_normal(brdf.shape)
    blocks = rng.integers(0, 1000, n)  # spatial blocks, as fit_classes labels them
    return sza, vza, phi, brdf, blocks, truth


def baselines(data) -> tuple[float, float]:
    """Seconds for ``design.T @ data`` and for ``lstsq(design, data)`` over all classes."""
    designs = [
        np.column_stack(np.broadcast_arrays(*MODEL.terms(ScatteringGeometry(*item[:3]), {}))) for item in data
    ]
    start = time.perf_counter()
    for design, item in zip(designs, data):
        np.einsum("nk,nb->kb", design, item[3])
    product = time.perf_counter() - start
    start = time.perf_counter()
    for design, item in zip(designs, data):
        np.linalg.lstsq(design, item[3], rcond=None)
    return product, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="total samples (all classes)")
    parser.add_argument("--classes", type=int, default=10)
    parser.add_argument("--bands", type=int, default=200)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    per_class = args.samples // args.classes
    data = [synthesize(per_class, args.bands, rng) for _ in range(args.classes)]
    product, lstsq = baselines(data)

    start = time.perf_counter()
    fits = [
        fit_one_class(class_id, f"class_{class_id}", MODEL, ClassSamples(sza, vza, phi, brdf, block=blocks))
        for class_id, (sza, vza, phi, brdf, blocks, _) in enumerate(data, start=1)
    ]
    elapsed = time.perf_counter() - start

    print(f"{args.classes} classes x {args.bands} bands from {per_class * args.classes:,} samples ({MODEL.name})")
    print(f"fit time: {elapsed:.2f} s (status: {sorted({fit.status for fit in fits})})")
    print(f"baseline design.T @ data (one pass): {product:.3f} s; ratio {elapsed / product:.0f}x")
    print(f"baseline lstsq(design, data): {lstsq:.2f} s; ratio {elapsed / lstsq:.2f}x")
    for name in MODEL.linear:
        pulls = np.concatenate([(fit.params[name] - item[5][name]) / fit.errors[name] for fit, item in zip(fits, data)])
        relative = np.concatenate([np.abs(fit.params[name] / item[5][name] - 1) for fit, item in zip(fits, data)])
        print(
            f"{name}: pulls (fit - truth) / error: std {np.std(pulls):.2f}, mean {np.mean(pulls):+.2f}, "
            f"max |pull| {np.max(np.abs(pulls)):.1f}; max relative error {np.max(relative):.2e}"
        )


if __name__ == "__main__":
    main()
