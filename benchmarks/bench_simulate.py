"""Accuracy/time trade-off of the V-cavity simulation (brdfcorr.analysis.simulate.simulate_vcavity).

For each grid setting, the simulation (normalized at 45/45/180, as paper 000 fig. 2) is compared
with the analytic Torrance-Sparrow model normalized the same way, at the geometries of paper 000
fig. 2 (theta_i = 10, 45, 75 deg in the principal plane and phi = 150 deg at theta_i = 45 deg;
theta_r = 0..85 deg), for w = 0.01, 0.05, 0.15 deg^-1. Errors are taken where the normalized TS
value is above 0.1 (the issue's criterion). Times are printed as ratios to the default setting
measured in the same run (absolute times depend on the machine and its load).

Run: python benchmarks/bench_simulate.py [--quick]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from brdfcorr.analysis.simulate import NORMALIZATION_GEOMETRY, FacetGrid, simulate_vcavity
from brdfcorr.models import torrance_sparrow

ROUGHNESSES = (0.01, 0.05, 0.15)
CUTS = ((10.0, 180.0), (45.0, 180.0), (75.0, 180.0), (45.0, 150.0))
DEFAULT = FacetGrid(step_fraction=0.5, cutoff=5.0, pole="horizontal")
SETTINGS = (
    FacetGrid(step_fraction=0.25, cutoff=6.0, pole="horizontal"),
    DEFAULT,
    FacetGrid(step_fraction=1.0, cutoff=5.0, pole="horizontal"),
    FacetGrid(step_fraction=1.0, cutoff=4.0, pole="horizontal"),
    FacetGrid(step_fraction=1.5, cutoff=4.0, pole="horizontal"),
    FacetGrid(step_fraction=2.0, cutoff=4.0, pole="horizontal"),
    FacetGrid(step_fraction=1.0, cutoff=3.0, pole="horizontal"),
    FacetGrid(step_fraction=0.5, cutoff=5.0, pole="zenith"),
    FacetGrid(step_fraction=1.0, cutoff=4.0, pole="zenith"),
)


def geometries(step):
    theta_r = np.arange(0.0, 85.0 + 1e-9, step)
    return [(theta_i, theta_r, phi) for theta_i, phi in CUTS]


def analytic(theta_i, theta_r, phi, w):
    # TS specular part with F = 1 (very large n), normalized like the simulation.
    def ts(ti, tr, ph):
        return torrance_sparrow(ti, tr, ph, t0=0.0, t1=1.0, w=w, n=1e9, k=0.0)

    return ts(theta_i, theta_r, phi) / ts(*NORMALIZATION_GEOMETRY)


def run(setting, step, sigma=None):
    worst, count, elapsed = 0.0, 0, 0.0
    for w in ROUGHNESSES:
        for theta_i, theta_r, phi in geometries(step):
            start = time.perf_counter()
            simulated = simulate_vcavity(theta_i, theta_r, phi, w, sigma=sigma, grid=setting, normalize=True)
            elapsed += time.perf_counter() - start
            count += theta_r.size + 1  # + the normalization point
            expected = analytic(theta_i, theta_r, phi, w)
            mask = expected > 0.1
            if not mask.any():  # e.g. w = 0.15 at phi = 150: below 0.1 everywhere (paper 000)
                continue
            worst = max(worst, float(np.max(np.abs(simulated[mask] / expected[mask] - 1.0))))
    return worst, elapsed / count


def main(quick=False):
    step = 10.0 if quick else 5.0
    baseline = run(DEFAULT, step)[1]
    print(f"V-cavity simulation vs analytic TS (normalized at 45/45/180), theta_r step {step:g} deg")
    print(f"{'step/sigma':>10} {'cutoff':>6} {'pole':>10} {'max |rel err| (TS>0.1)':>24} {'time/geom vs default':>21}")
    for setting in SETTINGS:
        worst, per_geometry = run(setting, step)
        print(
            f"{setting.step_fraction:>10g} {setting.cutoff:>6g} {setting.pole:>10} "
            f"{worst:>24.2e} {per_geometry / baseline:>21.2f}"
        )
    print(f"(default setting: {baseline * 1e3:.2f} ms per geometry on this machine, this run)")
    print("\nFinite width of the facet peak (default grid): the error floor is proportional to sigma")
    print(f"{'sigma [deg]':>11} {'max |rel err| (TS>0.1)':>24}")
    for sigma in (0.14, 0.07, 0.035):
        print(f"{sigma:>11g} {run(DEFAULT, step, sigma=sigma)[0]:>24.2e}")


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
