"""Benchmark: held-out R^2 of each model, and of ``--model auto``, on goniometer-like measurements
of one-lobe and two-lobe surfaces (issue 36).

No real goniometer measurements licensed for redistribution could be found for the repository (see
docs/models.md, "Which model for which surface"), so the surfaces are built from published parameter
values: the Torrance-Sparrow fits of paper 003, Table 1 (roof tile, red and blue concrete, red
aluminium; specular), the global RTLSR kernel weights of Roy et al. (2016), Table 1 (red and NIR;
backscatter and hot spot), and two-lobe surfaces that add a Table-1 specular lobe to a Roy et al.
backscatter part. Each is measured at 73 geometries drawn from a grid with sun and view zenith
<= 60 deg over both halves of the azimuth circle (as a laboratory goniometer samples them), with
3 % multiplicative noise.

The procedure is the issue's: fit on half of the geometries (``brdfcorr fit`` with the model, or
``--model auto``), evaluate the fitted model on the other half, then swap; the printed R^2 is the
mean of the two held-out R^2.

    python benchmarks/bench_model_choice.py [--noise 0.03] [--seed 0]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from brdfcorr.fit.goniometer import fit_brdf
from brdfcorr.fit.measurements import Measurements
from brdfcorr.fit.selection import choose_model
from brdfcorr.fit.shapes import DEFAULT_FIXED
from brdfcorr.models import get_model, load_material
from brdfcorr.models.coefficients import load_coefficients

MODELS = ("torrance_sparrow", "ross_thick_li_sparse", "rpv", "ross_li_ts", "ross_li_peak")


def _kernels(band: str) -> dict[str, float]:
    """Roy et al. (2016) weights of one band as BRDF weights [sr^-1] (reflectance factor / pi)."""
    return load_coefficients("roy2016").params(band)


def _lobe(material: str) -> dict[str, float]:
    params = load_material(material).params
    return {name: params[name] for name in ("t1", "w", "n", "k")}


def surfaces() -> dict[str, tuple[str, dict[str, float]]]:
    """Name -> (true model, parameters), all from published values."""
    specular = {name: ("torrance_sparrow", dict(load_material(name).params))
                for name in ("roof_tile", "red_concrete", "blue_concrete", "red_aluminium")}
    backscatter = {f"rtlsr_{band}": ("ross_thick_li_sparse", _kernels(band)) for band in ("red", "nir")}
    two_lobe = {
        "tile_lobe_on_red_kernels": ("ross_li_ts", {**_kernels("red"), **_lobe("roof_tile")}),
        "concrete_lobe_on_nir_kernels": ("ross_li_ts", {**_kernels("nir"), **_lobe("red_concrete")}),
    }
    return {**specular, **backscatter, **two_lobe}


def geometries(rng: np.random.Generator, count: int = 73):
    grid = np.meshgrid([0, 15, 30, 45, 60], [0, 10, 20, 30, 40, 50, 60], np.arange(0, 181, 30), indexing="ij")
    ti, tr, phi = (np.asarray(a, dtype=float).ravel() for a in grid)
    rows = rng.choice(ti.size, count, replace=False)
    return ti[rows], tr[rows], phi[rows]


def _r2(observed, predicted) -> float:
    return 1.0 - float(np.sum((observed - predicted) ** 2) / np.sum((observed - observed.mean()) ** 2))


def held_out(model: str, angles, brdf, halves) -> tuple[float, str]:
    """Mean held-out R^2 over the two swaps, and the model fitted (the choice for ``auto``)."""
    scores, used = [], []
    for train in halves:
        test = ~train
        name = model
        if model == "auto":
            name = choose_model(Measurements(*(a[train] for a in angles), brdf[train])).chosen
        result = fit_brdf(name, *(a[train] for a in angles), brdf[train], fixed=DEFAULT_FIXED.get(name))
        scores.append(_r2(brdf[test], result.predict(*(a[test] for a in angles))))
        used.append(name)
    return float(np.mean(scores)), "/".join(dict.fromkeys(used))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--noise", type=float, default=0.03, help="multiplicative noise, 1 sigma [-]")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    header = f"{'surface':<30} {'truth':<22}" + "".join(f"{name:>22}" for name in (*MODELS, "auto")) + "  auto chose"
    print(header)
    auto_r2 = []
    start = time.perf_counter()
    for name, (truth, params) in surfaces().items():
        angles = geometries(rng)
        brdf = np.asarray(get_model(truth)(*angles, **params), dtype=float)
        brdf = brdf * (1 + args.noise * rng.standard_normal(brdf.size))
        first = np.zeros(brdf.size, dtype=bool)
        first[rng.choice(brdf.size, brdf.size // 2, replace=False)] = True
        halves = (first, ~first)
        row = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for model in (*MODELS, "auto"):
                try:
                    r2, used = held_out(model, angles, brdf, halves)
                except Exception as error:  # a model that cannot be fitted here scores nothing
                    r2, used = float("nan"), type(error).__name__
                row.append(r2)
        auto_r2.append(row[-1])
        print(f"{name:<30} {truth:<22}" + "".join(f"{value:>22.3f}" for value in row) + f"  {used}")
    auto_r2 = np.array(auto_r2)
    print(f"\nauto: held-out R^2 >= 0.9 for {int(np.sum(auto_r2 >= 0.9))} of {auto_r2.size} surfaces, "
          f"median {np.median(auto_r2):.3f}, worst {auto_r2.min():.3f} ({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
