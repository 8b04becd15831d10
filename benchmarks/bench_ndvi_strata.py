"""Benchmark: scene A' of ``bench_kernels.py`` (a vegetation/soil line whose truth is the same on
both sides), where the east/west bias of NDVI strata comes from and what reduces it (run by hand).

Each row fits ``ross_thick_li_sparse`` per stratum (``fit_classes``) and corrects (``normalize``),
binned or with the strata's coefficients interpolated in NDVI (``ndvi_interpolation``), and prints
the median error, the worst east/west difference by true-fraction group after the correction and
its residual ``after - truth`` (equal on A': the truth's own is 0), the whole scene's, and the
seconds taken (``bench_kernels.py``'s docstring defines the scenes and metrics). Rows:

* the sources: no sensor noise; spatially white fraction and texture (no patches); no fit (each
  stratum's mean true weights, binned: what the correction does with the right weights);
* (a) one joint fit with weights linear in NDVI, ``rho = sum_k (a_k + b_k NDVI) K_k``, one
  non-negative least squares per band over every pixel, applied as two strata with centres at the
  1st and 99th NDVI percentiles (``ndvi_interpolation`` expresses it exactly, no new correction);
* (b) strata re-cut from the NDVI of the image corrected in the previous pass (one, two passes),
  on A' and on A (as flown); (c) 3 and 10 strata instead of 5;
* two lines over the same ground, the second under an afternoon sun (from the west; the same fields
  and noise draw), fitted together: strata cut per line, or from the two lines' mean NDVI (each
  point seen from both sides); pooled (one level per stratum), or with each pixel's level free
  (``fit_classes``' ``levels="pixel"``, issue 37: the shape fitted to each pixel's two views);
* strata from a view-independent NDVI (of the nadir image: e.g. an NBAR product's);
* (e) strata of the observed NDVI less its least-squares trend in the kernels, on A' and A;
* (f) strata of the self-consistent NDVI ((b) taken to its fixed point by the secant method), on A'
  and A;
* (d) no strata: a two-end-member kernel mixture, ``rho / pi = a P(g) + b Q(g)`` per pixel, fitted
  by alternating least squares (the end members' weights from the fractions t = b / (a + b), then
  each pixel's t from all its bands at its own geometry, which the view does not bias), on A' and A;
* the oracle: weights linear in the true fraction v, the truth's own form (applied by hand).

Measured (issue 24, 400 x 600 x 60, 1 % noise, seed 0): ``bench_kernels.py``'s docstring.

Usage::

    python benchmarks/bench_ndvi_strata.py            # 400 x 600 x 60 (about a minute)
    python benchmarks/bench_ndvi_strata.py --bands 12 # a quicker check (the red and NIR bands suffice)
"""

from __future__ import annotations

import math

import numpy as np
from bench_kernels import (
    PERCENTILES,
    RTLSR,
    _reference_angles,
    best_of,
    class_map,
    correct,
    east_west,
    fit,
    fraction_groups,
    scene_parser,
    scene_vegetation_soil,
    scores,
)
from scipy.optimize import nnls

from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.params import ParameterTable
from brdfcorr.strata import ndvi


def mean_mixture_table(scene: dict, classes: np.ndarray) -> ParameterTable:
    """One RTLSR per class with the class's mean true weights ``mean(v) w_veg + mean(1 - v) w_soil``:
    the best a single model per stratum can do, without a fit."""
    wavelengths = scene["image"]["wavelength"].values.tolist()
    entries = []
    for class_id in np.unique(classes[classes > 0]):
        v = float(scene["fraction"][classes == class_id].mean())
        params = {k: (v * scene["weights"]["vegetation"][k] + (1 - v) * scene["weights"]["soil"][k]).tolist()
                  for k in ("f_iso", "f_vol", "f_geo")}
        entries.append({"id": int(class_id), "name": f"stratum_{class_id}", "model": "ross_thick_li_sparse",
                        "wavelengths": wavelengths, "params": params})
    return ParameterTable(classes=entries)


def strata_correction(scene: dict, strata: np.ndarray, continuous: bool, pooled=(),
                      levels: str = "pooled") -> np.ndarray:
    """Fit one RTLSR per stratum of ``strata`` (with the (scene, strata) of more lines over the same
    ground; ``levels="pixel"``: each pixel's level free, the shape fitted to its own views) and
    correct ``scene``, binned or interpolated in NDVI."""
    layer = class_map(scene, strata)
    table = fit(scene, layer, "ross_thick_li_sparse", [(line, class_map(line, s)) for line, s in pooled],
                levels=levels).table
    if continuous:
        table = table.with_ndvi_interpolation({"classes": list(table.class_ids)})
    return correct(scene, layer, table)


def ndvi_of(scene: dict, cube: np.ndarray) -> np.ndarray:
    """NDVI of ``cube`` (the observed, a corrected or the nadir image) with the scene's bands."""
    return np.asarray(ndvi(scene["image"].copy(data=cube.astype(np.float32))).values)


def strata_of(index: np.ndarray, percentiles=PERCENTILES) -> np.ndarray:
    """NDVI percentile strata 1..n+1 of an NDVI layer (any: the scene has no water or shadow)."""
    return (np.digitize(index, np.percentile(index, percentiles)) + 1).astype(np.uint8)


def two_point_fit(scene: dict, t: np.ndarray) -> tuple[dict, dict]:
    """``rho / pi = sum_k [(1 - t) p_k + t q_k] K_k`` (the RTLSR kernels K_k; t in [0, 1] per pixel)
    fitted to every pixel, per band, by non-negative least squares (the registry's bound f >= 0 at
    both ends): the weights p at t = 0 and q at t = 1. With t = (NDVI - c1) / (c2 - c1) clamped to
    [0, 1] this is what ``ndvi_interpolation`` applies to two classes with centres c1, c2: weights
    linear in NDVI between them, rho = sum_k (a_k + b_k NDVI) K_k, held outside."""
    flat = {name: scene["angles"][name].values.ravel().astype(float) for name in ("sza", "saa", "vza", "vaa")}
    geometry = ScatteringGeometry(flat["sza"], flat["vza"], relative_azimuth(flat["saa"], flat["vaa"]))
    kernels = [np.broadcast_to(np.asarray(kernel, float), t.shape) for kernel in RTLSR.terms(geometry, {})]
    design = np.column_stack([weight * kernel for weight in (1 - t, t) for kernel in kernels])
    data = np.asarray(scene["image"].values, float).reshape(scene["image"].sizes["band"], -1).T / math.pi
    root = np.linalg.cholesky(design.T @ design).T  # |D x - y|^2 = |R x - R^-T D^T y|^2 + const
    targets = np.linalg.solve(root.T, design.T @ data)
    solution = np.column_stack([nnls(root, target)[0] for target in targets.T])  # (6, bands)
    return ({name: solution[j] for j, name in enumerate(RTLSR.linear)},
            {name: solution[3 + j] for j, name in enumerate(RTLSR.linear)})


def ndvi_linear_correction(scene: dict) -> np.ndarray:
    """(a) weights linear in the observed NDVI from one joint fit, applied by ``normalize`` as two
    strata (split at the median NDVI) interpolated between centres at the 1st and 99th percentile."""
    index = ndvi_of(scene, scene["image"].values)
    centres = [float(c) for c in np.percentile(index, [1, 99])]
    low, high = two_point_fit(scene, np.clip((index.ravel() - centres[0]) / (centres[1] - centres[0]), 0, 1))
    wavelengths = scene["image"]["wavelength"].values.tolist()
    table = ParameterTable(classes=[
        {"id": k, "name": f"ndvi_{centre:.2f}", "model": "ross_thick_li_sparse", "wavelengths": wavelengths,
         "params": {name: values.tolist() for name, values in weights.items()}}
        for k, (centre, weights) in enumerate(zip(centres, (low, high)), 1)
    ]).with_ndvi_interpolation({"classes": [1, 2], "centres": centres})
    return correct(scene, class_map(scene, strata_of(index, (50,))), table)


def fraction_linear_correction(scene: dict) -> np.ndarray:
    """Oracle: weights linear in the true vegetation fraction v (the truth's own form), applied by hand."""
    return weights_linear_correction(scene, scene["fraction"].ravel())


def weights_linear_correction(scene: dict, v: np.ndarray) -> np.ndarray:
    """Weights linear in a per-pixel fraction v (fitted by :func:`two_point_fit`), applied by hand."""
    low, high = two_point_fit(scene, v)
    flat = {name: scene["angles"][name].values.ravel().astype(float) for name in ("sza", "saa", "vza", "vaa")}
    params = {name: (1 - v) * low[name][:, None] + v * high[name][:, None] for name in low}
    observed = RTLSR(flat["sza"], flat["vza"], relative_azimuth(flat["saa"], flat["vaa"]), **params)
    reference = RTLSR(*(a[None] for a in _reference_angles(scene["angles"], scene["reference_sza"])), **params)
    return np.asarray(scene["image"].values) * (reference / observed).reshape(scene["image"].shape)


def _flat_geometry(scene: dict) -> ScatteringGeometry:
    flat = {name: scene["angles"][name].values.ravel().astype(float) for name in ("sza", "saa", "vza", "vaa")}
    return ScatteringGeometry(flat["sza"], flat["vza"], relative_azimuth(flat["saa"], flat["vaa"]))


def unmixed_fraction(scene: dict, low: dict, high: dict) -> np.ndarray:
    """Per pixel, the fraction t of ``rho / pi = a P(g) + b Q(g)`` fitted over all bands (P, Q: the
    two end members' BRDFs at the pixel's own geometry g, so t does not depend on the view; a + b
    takes the albedo texture): t = b / (a + b), clipped to [0, 1]."""
    terms = [np.asarray(kernel, float) for kernel in RTLSR.terms(_flat_geometry(scene), {})]
    ends = [sum(weights[name][:, None] * kernel[None] for name, kernel in zip(RTLSR.linear, terms))
            for weights in (low, high)]  # (bands, pixels) each
    data = np.asarray(scene["image"].values, float).reshape(scene["image"].sizes["band"], -1) / math.pi
    pp, pq, qq = (np.sum(x * y, axis=0) for x, y in ((ends[0], ends[0]), (ends[0], ends[1]), (ends[1], ends[1])))
    py, qy = np.sum(ends[0] * data, axis=0), np.sum(ends[1] * data, axis=0)
    determinant = pp * qq - pq**2
    a, b = (qq * py - pq * qy) / determinant, (pp * qy - pq * py) / determinant
    return b / (a + b)


def unmixing_correction(scene: dict, iterations: int = 4) -> np.ndarray:
    """(d) A two-end-member kernel mixture fitted by alternating least squares, no strata: from t
    the observed NDVI rescaled between its 1st and 99th percentiles, fit the end members' weights
    (:func:`two_point_fit`), re-estimate each pixel's t from all its bands at its own geometry
    (:func:`unmixed_fraction`), repeat; correct with weights linear in the last t."""
    def gauge(t: np.ndarray) -> np.ndarray:  # any two mixtures fit alike: t's 1st and 99th percentiles at 0 and 1
        low_end, high_end = np.percentile(t, [1, 99])
        return np.clip((t - low_end) / (high_end - low_end), 0.0, 1.0)

    t = gauge(ndvi_of(scene, scene["image"].values).ravel())
    for _ in range(iterations):
        t = gauge(unmixed_fraction(scene, *two_point_fit(scene, t)))
    return weights_linear_correction(scene, t)


def detrended_ndvi(scene: dict) -> np.ndarray:
    """(e) The observed NDVI less its least-squares trend in the RTLSR kernels over the whole
    scene, relative to the reference geometry: view-independent where the cover is uncorrelated
    with the kernels across the line (A'), not where it differs between the sides (A)."""
    index = ndvi_of(scene, scene["image"].values).ravel()
    observed = RTLSR.terms(_flat_geometry(scene), {})
    reference = RTLSR.terms(ScatteringGeometry(*_reference_angles(scene["angles"], scene["reference_sza"])), {})
    trend = np.column_stack([np.broadcast_to(np.asarray(k, float) - np.asarray(r, float), index.shape)
                             for k, r in zip(observed[1:], reference[1:])])  # the volume and geometric kernels
    coefficients = np.linalg.lstsq(np.column_stack([np.ones_like(index), trend]), index, rcond=None)[0]
    return (index - trend @ coefficients[1:]).reshape(scene["image"].shape[1:])


def recut_passes(scene: dict, passes: int) -> np.ndarray:
    """(b) 5 strata cut from the NDVI of the image corrected with the previous pass's interpolated strata."""
    cube = np.asarray(scene["image"].values)
    for _ in range(passes):
        cube = strata_correction(scene, strata_of(ndvi_of(scene, cube)), continuous=True)
    return strata_of(ndvi_of(scene, cube))


def east_west_mean(field: np.ndarray) -> float:
    """Mean of the eastern third of the swath less the western third's."""
    third = field.shape[1] // 3
    return float(field[:, -third:].mean() - field[:, :third].mean())


def self_consistent_ndvi(scene: dict, rounds: int = 3) -> np.ndarray:
    """(f) Strata of the NDVI that the correction they give leaves unchanged between the sides:
    ``NDVI + lam * d``, with d the change of the NDVI by the first pass's correction ((b)'s) and lam
    solved by the secant method so that the east/west mean of (NDVI of the corrected image - the
    NDVI cut) vanishes: (b) iterated to its fixed point, which it approaches by about 12 % a pass."""
    observed = ndvi_of(scene, scene["image"].values)

    def mismatch(index: np.ndarray) -> float:
        corrected = strata_correction(scene, strata_of(index), continuous=True)
        return east_west_mean(ndvi_of(scene, corrected) - index)

    change = ndvi_of(scene, strata_correction(scene, strata_of(observed), continuous=True)) - observed
    steps = [(0.0, east_west_mean(change)), (1.0, mismatch(observed + change))]
    for _ in range(rounds):
        (lam0, r0), (lam1, r1) = steps[-2:]
        lam = lam1 - r1 * (lam1 - lam0) / (r1 - r0)
        steps.append((lam, mismatch(observed + lam * change)))
    return strata_of(observed + steps[-1][0] * change)


def diagnose(args, scene: dict, flown: dict) -> None:
    """Scene A' (its truth the same on both sides): where the east/west bias of strata cut from the
    observed NDVI comes from, and what reduces it: (a) a joint fit linear in NDVI, (b) strata re-cut
    from the corrected image's NDVI, (c) fewer or more strata, a view-independent NDVI; oracles."""
    observed, strata = ndvi_of(scene, scene["image"].values), recut_passes(scene, 0)
    clean = dict(scene, image=scene["image"].copy(data=scene["clean"].astype(np.float32)),
                 noise_factor=np.ones_like(scene["noise_factor"]))
    white = scene_vegetation_soil(args.rows, args.columns, args.bands, args.noise, args.seed, 0.0, 0.0, mirror=True)
    afternoon = scene_vegetation_soil(args.rows, args.columns, args.bands, args.noise, args.seed, mirror=True,
                                      sun_azimuth=260)
    both = (observed + ndvi_of(afternoon, afternoon["image"].values)) / 2  # the same ground seen from both sides
    nadir = ndvi_of(scene, scene["truth"] * scene["noise_factor"])  # e.g. of a nadir (NBAR) product
    strata_cases = [
        ("5 NDVI strata (as run)", scene, strata, ()),
        ("(c) 3 NDVI strata", scene, strata_of(observed, (33.3, 66.7)), ()),
        ("(c) 10 NDVI strata", scene, strata_of(observed, tuple(range(10, 100, 10))), ()),
        ("(b) 5 strata re-cut from the corrected NDVI", scene, recut_passes(scene, 1), ()),
        ("(b) 5 strata re-cut twice", scene, recut_passes(scene, 2), ()),
        ("A (as flown), 5 NDVI strata", flown, recut_passes(flown, 0), ()),
        ("A (as flown), (b) 5 strata re-cut twice", flown, recut_passes(flown, 2), ()),
        ("no sensor noise", clean, strata, ()), ("spatially white v and texture", white, recut_passes(white, 0), ()),
        ("2 lines pooled (sun east, west), strata per line", scene, strata, [(afternoon, recut_passes(afternoon, 0))]),
        ("2 lines pooled, strata of their mean NDVI", scene, strata_of(both), [(afternoon, strata_of(both))]),
        ("2 lines, each pixel's level free, strata per line", scene, strata,
         [(afternoon, recut_passes(afternoon, 0))], "pixel"),
        ("2 lines, each pixel's level free, strata of their mean NDVI", scene, strata_of(both),
         [(afternoon, strata_of(both))], "pixel"),
        ("5 strata of a view-independent NDVI (nadir)", scene, strata_of(nadir), ()),
        ("10 strata of a view-independent NDVI (nadir)", scene, strata_of(nadir, tuple(range(10, 100, 10))), ()),
        ("(e) 5 strata of the NDVI less its kernel trend", scene, strata_of(detrended_ndvi(scene)), ()),
        ("A (as flown), (e) 5 strata of the NDVI less its kernel trend", flown, strata_of(detrended_ndvi(flown)), ()),
        ("(f) 5 strata of the self-consistent NDVI", scene, self_consistent_ndvi(scene), ()),
        ("A (as flown), (f) 5 strata of the self-consistent NDVI", flown, self_consistent_ndvi(flown), ()),
    ]
    cases = [(f"{label}, {'interpolated' if continuous else 'binned'}", strata_correction,
              (case, classes, continuous, *rest)) for label, case, classes, *rest in strata_cases
             for continuous in (False, True)]
    cases += [("(a) joint fit linear in NDVI (2 interpolated strata)", ndvi_linear_correction, (scene,)),
              ("no fit: each stratum's mean true weights, binned",
               lambda case, s: correct(case, class_map(case, s), mean_mixture_table(case, s)), (scene, strata)),
              ("(d) two-end-member mixture, alternating least squares", unmixing_correction, (scene,)),
              ("A (as flown), (d) two-end-member mixture", unmixing_correction, (flown,)),
              ("oracle: joint fit linear in the true v", fraction_linear_correction, (scene,))]
    print("\n  diagnosis (A' unless named): median error; worst E/W by true-fraction group after, residual "
          "after - truth; whole scene after; seconds")
    for label, function, arguments in cases:
        corrected, seconds = best_of(1, function, *arguments)
        case, groups = arguments[0], fraction_groups(arguments[0])
        values = scores(case, corrected, groups, range(1, len(PERCENTILES) + 2))
        whole = np.max(np.abs(east_west(corrected, groups > 0)))
        print(f"    {label:66s} {values['brdf']:6.3%} {values['after']:6.2%} {values['residual']:6.2%} "
              f"{whole:6.2%} {seconds:5.1f}")


def main() -> None:
    parser = scene_parser(__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of the scene's fields and noise")
    args = parser.parse_args()
    flown, mirrored = (scene_vegetation_soil(args.rows, args.columns, args.bands, args.noise, args.seed, mirror=mirror)
                       for mirror in (False, True))
    diagnose(args, mirrored, flown)


if __name__ == "__main__":
    main()
