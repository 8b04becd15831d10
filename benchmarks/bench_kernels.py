"""Benchmark: kernel-driven (RTLSR) and mixed Torrance-Sparrow / RTLSR normalization of synthetic
airborne lines, fitted from the imagery itself (run by hand; not part of the test suite).

The scenes are rendered with brdfcorr's registered models (``ross_thick_li_sparse``,
``torrance_sparrow``) at the geometry of a push-broom line flown north: view zenith -20..+20 deg
across track, view azimuths perpendicular to the track (90 deg west of it, 270 deg east of it,
towards the sensor), sun zenith ~35 deg from the east (saa 100 deg), so the western half of the
swath looks into backscatter (phi ~10 deg) and the eastern half into forward scatter (phi ~170 deg).
Every pixel is ``pi * f(sun, view; p(band)) * texture * (1 + noise)``: texture a smoothed random
albedo field (10 %), noise multiplicative and white (``--noise``, 1 % by default). The truth is
the same pixel without noise at the reference geometry (scene-mean sun, nadir view).

* **A, vegetation/soil**: a linear mixture ``v f_veg + (1 - v) f_soil`` with a smoothly varying
  vegetation fraction ``v``, both RTLSR with MODIS-like kernel weights per band (60 bands
  400-1000 nm, red edge). brdfcorr workflow: NDVI percentile strata (``ndvi_strata``, as
  FlexBRDF) -> ``fit_classes`` with ``ross_thick_li_sparse`` per stratum -> ``normalize``, once
  with one model per stratum and once with the strata's coefficients interpolated in NDVI between
  their centres (the table's ``ndvi_interpolation``, as FlexBRDF applies its bins).
* **A', the same with a symmetric truth**: v and the texture mirrored about the swath's centre
  column (the geometry is not: the west still looks into backscatter, the east into forward
  scatter), so the truth's east/west difference over any mirror-symmetric set of pixels is 0.
  Goals (A, A'): median error <= 0.7 %; on A', east/west by true-fraction group <= 0.2 %.
* **B, urban**: a true class map of roof tile and red concrete (Torrance-Sparrow, paper 003
  Table 1 materials, t0 and t1 scaled by an illustrative spectrum) and grass and bare soil
  (RTLSR); fitted with per-class models in one ``fit_classes`` call (``class_models``), and again
  with the TS refractive index held at a generic n = 1.6 (not the materials' own). Goals: median
  error <= 1 %, every class's east/west difference <= 1 %, held against the residual ``after -
  truth``: B's class map and texture are not mirrored, so each class's truth has an east/west
  difference of its own (up to 1.3 % at seed 1: its pixels' mean texture differs between the
  thirds), and a small "after" there rewards flattening it.
* **B', the same with a symmetric truth**: class map and texture mirrored as in A' (the truth's own
  east/west is 0, so "after" is the correction's own error; default guard rails only).

Metrics. *Error*: ``|corrected - truth| / truth`` per pixel and band, median over all. The sensor
noise is in the corrected image but not in the truth, so against the noise-free truth the median
cannot fall below 0.674 sigma (0.67 % at 1 % noise) whatever the correction; the error held
against the goals compares with the truth carrying the same noise realization, i.e. it is the
error of the correction factor itself (both are printed). *East/west*: mean of the eastern third
of the swath over the western third, minus 1, per class (or group) and band, worst band and class;
after the correction, of the truth, and the residual ``after - truth``. Scene A's goal is held
against A', over five groups cut from the true fraction v: each holds the same mixture on both
sides and the truth's own east/west is 0, so "after" is the correction's own error. Not per NDVI
stratum: strata cut from the observed NDVI hold different mixtures on the two sides (NDVI depends
on the view), so a perfect correction leaves their own east/west (4.0 % on A', 3.9 % on A) and a
small "after" there rewards flattening real differences. Not on A: its few large patches give the
truth 2.5 % by group (10 % over the whole scene), which an image-based fit partly takes for BRDF.

Measured (issue 24, 400 x 600 x 60, 1 % noise; binned / interpolated): on A the median error is
0.325 / 0.306 %, the residual by group 4.64 / 4.36 %; on A' 0.257 / 0.243 % and 3.95 / 3.50 % by
group (whole scene 1.28 / 1.23 %): the 0.2 % goal is missed. ``bench_ndvi_strata.py`` (A',
interpolated unless said): the bias is the fit's, not the application's (each stratum's own mean
true weights, binned: 0.08 %), nor the noise's (none: 3.49 %) or the patches' (spatially white
fields: 3.49 %). At equal fraction the NDVI is 0.003-0.012 higher in forward scatter, so an
observed-NDVI stratum holds less vegetation there, and the fit takes the brightness difference for
BRDF. Tried: (a) one joint fit with weights linear in NDVI (``ndvi_interpolation`` over two classes
with centres at the 1st and 99th NDVI percentiles expresses it exactly; non-negative least squares):
5.58 %, worse; (b) strata re-cut from the corrected image's NDVI: 3.05 %, then 2.67 % (about 12 %
less per pass, but on A the median error rises to 0.346 %: it converges to flattening whatever
differs between the sides); (c) 3 strata 2.94 %, 10 strata 3.60 % (seeds 1-3, 12 bands: 1.1-3.2 %
with 3 strata, 3.1-3.3 % with 5; on A fewer strata raise the residual up to 6.6 %). None is kept.
Pooling a second line over the same ground under an afternoon sun, strata cut per line: 3.59 % (the
NDVI's view dependence is the same in both). What works is a view-independent NDVI for the strata:
the mean NDVI of those two lines 0.58 %; a nadir image's NDVI (e.g. an NBAR product) 0.63 % with 5
strata, 0.40 % with 10. Only weights linear in the true fraction reach the goal (0.18 %, an oracle).
(d) Estimating that fraction from the image (a two-end-member kernel mixture fitted by alternating
least squares, each pixel's fraction from all its bands at its own geometry, its 1st and 99th
percentiles held at 0 and 1): 5.03 % after 4 rounds, 2.52 % after 12 on A'; on A the residual
grows (2.30 %, then 8.44 %): the albedo texture, which the end members' fit ignores, and the
fractions' noise let the alternation drift. Without the held percentiles it drifts as well (A':
2.27, 1.91, 2.39 % after 4, 12, 30 rounds; A: 2.43, 6.13, 16.6 %). Not kept. (e) Strata of the
observed NDVI less its least-squares trend in the kernels over the scene: 0.92 / 0.77 % on A'
(near the nadir NDVI's 0.63 %), but 15.4 / 14.7 % on A, where the cover differs between the sides
and the trend removes real differences. Not kept. (f) Strata of the self-consistent NDVI, (b) taken
to its fixed point by the secant method (the NDVI cut equal, east against west, to the NDVI of the
image it corrects; about 3.7 times (b)'s first change): 2.24 / 1.96 % on A', and on A a median error
of 0.398 / 0.385 % (residual 4.07 / 3.57 %). The fixed point exists but is not the truth: the
strata's fits still take part of the mixture difference for BRDF. Not kept.

Timing: fit + correct (and for A the strata) of the default 400 x 600 x 60 float32 line; goal
< 6 s on the 2-core reference machine. As a machine-independent figure the time is also given
relative to a baseline measured in the same run: one ``cube * factor`` over the whole cube (read
the cube once, write it once), the memory traffic any per-pixel correction cannot avoid.

Usage::

    python benchmarks/bench_kernels.py            # 400 x 600 x 60 (well under a minute)
    python benchmarks/bench_kernels.py --small    # 120 x 180 x 20, a quick check
    python benchmarks/bench_ndvi_strata.py        # scene A': where the east/west bias comes from
"""

from __future__ import annotations

import argparse
import math
import time
import warnings

import numpy as np
import xarray as xr
from scipy.ndimage import gaussian_filter

from brdfcorr import normalize
from brdfcorr.fit import ClassModels, Sampling, fit_classes
from brdfcorr.geometry import relative_azimuth
from brdfcorr.models import get_model
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable
from brdfcorr.strata import ndvi_strata

RTLSR = get_model("ross_thick_li_sparse")
TS = get_model("torrance_sparrow")
PERCENTILES = (20, 40, 60, 80)  # five NDVI strata of near-equal size (FlexBRDF bins by percentiles)
ROOF, CONCRETE, GRASS, SOIL = 1, 2, 3, 4
URBAN_NAMES = {ROOF: "roof_tile", CONCRETE: "red_concrete", GRASS: "grass", SOIL: "soil"}
#: A generic refractive index for the TS classes when n is held fixed (the middle of paper 003's
#: Table 1, 1.48-1.77; deliberately not the materials' own n, 1.77 and 1.48).
N_GENERIC = 1.6


# ----------------------------------------------------------------------------------- the scenes
def line_geometry(rows: int, columns: int, vza_max: float = 20.0, sza=(34.0, 36.0), saa: float = 100.0):
    """Angles [deg] of a line flown north: sza ramps along track, vza = atan(|d| / H) across."""
    across = np.linspace(-1.0, 1.0, columns) * math.tan(math.radians(vza_max))  # d / H, east positive
    shape = (rows, columns)
    return {
        "sza": np.broadcast_to(np.linspace(*sza, rows)[:, None], shape).astype(np.float32),
        "saa": np.full(shape, saa, np.float32),
        "vza": np.broadcast_to(np.degrees(np.arctan(np.abs(across))), shape).astype(np.float32),
        "vaa": np.broadcast_to(np.where(across > 0, 270.0, 90.0), shape).astype(np.float32),
    }


def smooth_field(rng: np.random.Generator, shape, sigma: float) -> np.ndarray:
    """A Gaussian random field smoothed over ``sigma`` pixels, scaled to zero mean, unit variance."""
    field = gaussian_filter(rng.standard_normal(shape), sigma)
    return (field - field.mean()) / field.std()


def endmember_spectra(wavelengths: np.ndarray) -> dict[str, np.ndarray]:
    """Nadir-sun nadir-view reflectance factors of vegetation and soil (illustrative shapes)."""
    w = np.asarray(wavelengths, float)
    edge = 1.0 / (1.0 + np.exp(-(w - 715.0) / 12.0))  # the red edge
    visible = 0.035 + 0.045 * np.exp(-(((w - 555.0) / 40.0) ** 2)) - 0.012 * np.exp(-(((w - 675.0) / 20.0) ** 2))
    vegetation = (1 - edge) * visible + edge * (0.42 + 0.03 * (w - 750.0) / 250.0)
    soil = 0.07 + 0.25 * np.clip((w - 400.0) / 600.0, 0, None) ** 0.8
    return {"vegetation": vegetation, "soil": soil, "edge": edge}


def rtlsr_weights(wavelengths) -> dict[str, dict[str, np.ndarray]]:
    """MODIS-like RTLSR weights [sr^-1] per band: vegetation f_vol/f_iso 0.6 (visible) to 0.8 (NIR),
    f_geo/f_iso 0.2 to 0.12; soil f_vol/f_iso 0.1, f_geo/f_iso 0.3 (rougher, little volume)."""
    spectra = endmember_spectra(wavelengths)
    edge = spectra["edge"]
    ratios = {"vegetation": (0.6 + 0.2 * edge, 0.2 - 0.08 * edge),
              "soil": (np.full_like(edge, 0.1), np.full_like(edge, 0.3))}
    weights = {}
    for kind, (vol, geo) in ratios.items():
        f_iso = spectra[kind] / math.pi
        weights[kind] = {"f_iso": f_iso, "f_vol": vol * f_iso, "f_geo": geo * f_iso}
    return weights


def ts_params(name: str, wavelengths) -> dict[str, np.ndarray]:
    """A paper-003 material (550 nm) with its intensities t0, t1 scaled by an illustrative spectrum
    (relative to 550 nm): red clay roof tile, red concrete."""
    w = np.asarray(wavelengths, float)
    material = load_material(name)
    if name == "roof_tile":
        spectrum = 0.55 + 0.45 * np.clip((w - 400) / 150, 0, 1) + 1.3 / (1 + np.exp(-(w - 600) / 20))
    else:
        spectrum = 0.7 + 0.3 * np.clip((w - 400) / 150, 0, 1) + 0.5 / (1 + np.exp(-(w - 590) / 25))
    spectrum = spectrum / np.interp(550.0, w, spectrum)
    params = {key: np.full(w.shape, float(value)) for key, value in material.params.items()}
    params["t0"], params["t1"] = params["t0"] * spectrum, params["t1"] * spectrum
    return params


def evaluate(model, params: dict[str, np.ndarray], sza, vza, phi) -> np.ndarray:
    """(band, n) BRDF of one registered model: parameters per band, angles per pixel (1-D)."""
    if model is TS:  # one evaluation per band: the shape parameters of the paper are scalars
        return np.stack([model(sza, vza, phi, **{k: v[b] for k, v in params.items()})
                         for b in range(len(params["t0"]))])
    return model(sza[None], vza[None], phi[None], **{k: v[:, None] for k, v in params.items()})


def _reference_angles(angles, reference_sza: float):
    n = angles["sza"].size
    return np.full(n, reference_sza), np.zeros(n), np.zeros(n)


def mirrored(field: np.ndarray) -> np.ndarray:
    """The field's western half beside its mirror image: symmetric about the swath's centre column."""
    half = -(-field.shape[1] // 2)
    return np.concatenate([field[:, :half], field[:, :field.shape[1] - half][:, ::-1]], axis=1)


def scene_vegetation_soil(rows: int, columns: int, bands: int, noise: float, seed: int = 0,
                          fraction_sigma: float = 12.0, texture_sigma: float = 2.0, mirror: bool = False,
                          sun_azimuth: float = 100.0) -> dict:
    """Scene A: a vegetation/soil mixture; the vegetation fraction v is a random field smoothed over
    ``fraction_sigma`` pixels squashed into (0, 1), the albedo texture (10 %) one smoothed over
    ``texture_sigma`` pixels (0: white). ``mirror``: both fields mirrored about the centre column
    (:func:`mirrored`; the geometry is not), so the truth is the same on both sides of the line.
    ``sun_azimuth`` 260 deg: the same ground under an afternoon sun, from the west."""
    rng = np.random.default_rng(seed)
    wavelengths = np.linspace(400.0, 1000.0, bands)
    angles = line_geometry(rows, columns, saa=sun_azimuth)
    fraction = 1.0 / (1.0 + np.exp(-2.5 * smooth_field(rng, (rows, columns), fraction_sigma)))
    texture = 1.0 + 0.1 * smooth_field(rng, (rows, columns), texture_sigma)
    if mirror:
        fraction, texture = mirrored(fraction), mirrored(texture)
    weights = rtlsr_weights(wavelengths)
    sza, vza = angles["sza"].ravel().astype(float), angles["vza"].ravel().astype(float)
    phi = relative_azimuth(angles["saa"].ravel().astype(float), angles["vaa"].ravel().astype(float))
    reference_sza = float(angles["sza"].mean())
    v, scale = fraction.ravel(), math.pi * texture.ravel()
    observed = (v * evaluate(RTLSR, weights["vegetation"], sza, vza, phi)
                + (1 - v) * evaluate(RTLSR, weights["soil"], sza, vza, phi)) * scale
    at_ref = _reference_angles(angles, reference_sza)
    truth = (v * evaluate(RTLSR, weights["vegetation"], *at_ref)
             + (1 - v) * evaluate(RTLSR, weights["soil"], *at_ref)) * scale
    return _package(observed, truth, angles, wavelengths, rng, noise, reference_sza,
                    fraction=fraction, weights=weights)


def urban_classes(rows: int, columns: int, rng: np.random.Generator) -> np.ndarray:
    """Grass with bare-soil patches, a concrete street grid and tiled roofs in the blocks."""
    classes = np.where(smooth_field(rng, (rows, columns), 6.0) > 0.8, SOIL, GRASS).astype(np.uint8)
    block, street = max(12, rows // 8), max(2, rows // 60)
    for start in range(block // 2, rows, block):
        classes[start:start + street] = CONCRETE
    for start in range(block // 3, columns, block):
        classes[:, start:start + street] = CONCRETE
    for top in range(0, rows, block):
        for left in range(0, columns, block):
            for _ in range(rng.integers(2, 5)):
                height, width = rng.integers(block // 6, block // 3, size=2)
                y0, x0 = top + street + rng.integers(0, block - height), left + street + rng.integers(0, block - width)
                classes[y0:y0 + height, x0:x0 + width] = ROOF if rng.uniform() < 0.7 else CONCRETE
    return classes


def scene_urban(rows: int, columns: int, bands: int, noise: float, seed: int = 1, mirror: bool = False) -> dict:
    """Scene B: roof tile and red concrete (TS), grass and soil (RTLSR) on a true class map;
    ``mirror``: B', class map and texture mirrored about the centre column (:func:`mirrored`)."""
    rng = np.random.default_rng(seed)
    wavelengths = np.linspace(400.0, 1000.0, bands)
    angles = line_geometry(rows, columns)
    classes = urban_classes(rows, columns, rng)
    texture = 1.0 + 0.1 * smooth_field(rng, (rows, columns), 2.0)
    if mirror:
        classes, texture = mirrored(classes), mirrored(texture)
    weights = rtlsr_weights(wavelengths)
    models = {ROOF: (TS, ts_params("roof_tile", wavelengths)), CONCRETE: (TS, ts_params("red_concrete", wavelengths)),
              GRASS: (RTLSR, weights["vegetation"]), SOIL: (RTLSR, weights["soil"])}
    return render_classes(models, classes, texture, angles, wavelengths, rng, noise)


def render_classes(models: dict, classes: np.ndarray, texture: np.ndarray, angles: dict, wavelengths, rng,
                   noise: float) -> dict:
    """A scene whose class ``c`` of ``classes`` follows ``models[c]`` = (model, per-band
    parameters) times the albedo ``texture``, observed at ``angles`` and true at the reference
    (scene-mean sun, nadir view), packaged with noise (:func:`_package`)."""
    bands, size = len(wavelengths), classes.size
    reference_sza = float(angles["sza"].mean())
    flat = {name: value.ravel().astype(float) for name, value in angles.items()}
    phi = relative_azimuth(flat["saa"], flat["vaa"])
    at_ref = _reference_angles(angles, reference_sza)
    observed, truth = np.empty((bands, size)), np.empty((bands, size))
    for class_id, (model, params) in models.items():
        mask = classes.ravel() == class_id
        scale = math.pi * texture.ravel()[mask]
        observed[:, mask] = evaluate(model, params, flat["sza"][mask], flat["vza"][mask], phi[mask]) * scale
        truth[:, mask] = evaluate(model, params, *(a[mask] for a in at_ref)) * scale
    return _package(observed, truth, angles, wavelengths, rng, noise, reference_sza, classes=classes)


def _package(observed, truth, angles, wavelengths, rng, noise, reference_sza, **extra) -> dict:
    rows, columns = angles["sza"].shape
    shape = (len(wavelengths), rows, columns)
    noise_factor = 1.0 + noise * rng.standard_normal(shape)
    observed = observed.reshape(shape)
    coords = {"y": np.arange(rows), "x": np.arange(columns)}
    image = xr.DataArray((observed * noise_factor).astype(np.float32), dims=("band", "y", "x"), name="reflectance",
                         coords={**coords, "band": np.arange(1, len(wavelengths) + 1),
                                 "wavelength": ("band", wavelengths)})
    angle_set = xr.Dataset({k: (("y", "x"), v) for k, v in angles.items()}, coords=coords)
    return {"image": image, "angles": angle_set, "truth": truth.reshape(shape), "noise_factor": noise_factor,
            "reference_sza": reference_sza, "clean": observed, **extra}


# ------------------------------------------------------------------------------------ workflow
_SHOWN: set[str] = set()


def class_map(scene: dict, values: np.ndarray) -> xr.DataArray:
    image = scene["image"]
    return xr.DataArray(values, dims=("y", "x"), coords={"y": image["y"].values, "x": image["x"].values})


def fit(scene: dict, classes: xr.DataArray, models: ClassModels | str, pooled=(), levels: str = "auto"):
    """fit_classes on ``classes`` with ``models`` (and the ``pooled`` (scene, classes) of more lines
    in the same fit; ``levels``: whose brightness levels are free, :class:`Sampling`); its warnings
    are printed (not raised)."""
    lines = [(scene, classes), *pooled]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fit_classes([line["image"] for line, _ in lines], [layer for _, layer in lines],
                             [line["angles"] for line, _ in lines], models, sampling=Sampling(levels=levels))
    for message in dict.fromkeys(str(warning.message) for warning in caught):
        if message not in _SHOWN:  # once per run, not once per timed repeat
            _SHOWN.add(message)
            print(f"  warning: {message[:160]}")
    return result


def correct(scene: dict, classes: xr.DataArray, table) -> np.ndarray:
    """normalize to the scene's reference geometry (scene-mean sun, nadir view)."""
    angles = scene["angles"]
    reference = {"sza": scene["reference_sza"], "vza": 0.0, "raa": 0.0}
    corrected, _ = normalize(scene["image"], classes, angles, table, reference)
    return np.asarray(corrected.values)


def east_west(cube: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per band: mean over the class's pixels in the eastern third / western third - 1 (NaN if
    the class is missing from a third)."""
    third = mask.shape[1] // 3
    east, west = mask[:, -third:], mask[:, :third]
    if not (east.any() and west.any()):
        return np.full(cube.shape[0], np.nan)
    return cube[:, :, -third:][:, east].mean(axis=1) / cube[:, :, :third][:, west].mean(axis=1) - 1.0


def scores(scene: dict, corrected: np.ndarray, classes: np.ndarray, ids) -> dict[str, float]:
    """Median relative errors over the classed pixels and all bands (module docstring), and the
    worst |east/west| over classes and bands: after the correction, of the truth, and of after -
    truth (the residual)."""
    mask = classes > 0
    truth, raw = scene["truth"][:, mask], np.asarray(scene["image"].values)[:, mask]
    noisy_truth = truth * scene["noise_factor"][:, mask]
    result = {
        "raw": float(np.median(np.abs(raw / noisy_truth - 1))),
        "noise_free": float(np.median(np.abs(corrected[:, mask] / truth - 1))),
        "brdf": float(np.median(np.abs(corrected[:, mask] / noisy_truth - 1))),
        "after": 0.0, "truth": 0.0, "residual": 0.0,
    }
    for class_id in ids:
        after, truth = east_west(corrected, classes == class_id), east_west(scene["truth"], classes == class_id)
        if np.all(np.isnan(after)):
            continue  # a class missing from one third has no east/west difference
        for key, values in (("after", after), ("truth", truth), ("residual", after - truth)):
            result[key] = max(result[key], float(np.max(np.abs(values))))
    return result


def gradient_table(scene: dict, corrected: np.ndarray, classes: np.ndarray, names: dict[int, str]) -> None:
    """Per class: pixels; east/west before, after and of the truth at 860 nm; the worst band's
    |after| and |after - truth|."""
    raw = np.asarray(scene["image"].values)
    nir = int(np.argmin(np.abs(scene["image"]["wavelength"].values - 860.0)))
    print(f"  {'class':28s} {'pixels':>7s} | E/W at 860 nm: {'before':>8s} {'after':>7s} {'truth':>7s} "
          f"| worst band: {'|after|':>7s} {'|after-truth|':>13s}")
    for class_id, name in names.items():
        mask = classes == class_id
        before, after, truth = (east_west(cube, mask) for cube in (raw, corrected, scene["truth"]))
        print(f"  {name:28s} {int(mask.sum()):7d} | {'':14s} {before[nir]:+8.2%} {after[nir]:+7.2%} "
              f"{truth[nir]:+7.2%} | {'':11s} {np.max(np.abs(after)):7.2%} {np.max(np.abs(after - truth)):13.2%}")


def verdict(value: float, goal: float | None) -> str:
    """`` (goal <= x: met/MISSED)``, or `` (not held against a goal)`` when ``goal`` is None."""
    if goal is None:
        return " (not held against a goal)"
    return f" (goal <= {goal:.1%}: {'met' if value <= goal else 'MISSED'})"


def report(values: dict[str, float], error_goal: float, gradient_goal: float | None, noise: float,
           what: str, held: str = "after") -> None:
    """Print the median errors and the worst east/west; the goal is held against ``held``:
    ``after`` where the truth's own east/west is 0, else ``residual`` (after - truth)."""
    goals = {"after": None, "residual": None, held: gradient_goal}
    print(f"  median |error|: uncorrected {values['raw']:.2%}; corrected {values['brdf']:.3%}"
          f"{verdict(values['brdf'], error_goal)}; against the noise-free truth "
          f"{values['noise_free']:.2%} (noise floor {0.6745 * noise:.2%})")
    print(f"  worst {what} east/west after {values['after']:.2%}{verdict(values['after'], goals['after'])}; "
          f"the truth's own {values['truth']:.2%}; residual after - truth {values['residual']:.2%}"
          f"{verdict(values['residual'], goals['residual'])}")


def whole_scene(scene: dict, corrected: np.ndarray, mask: np.ndarray) -> None:
    """The scene's east/west difference over every classed pixel, worst band: the measure of the
    issue's comparison table (a stratum's own is biased by strata cut from the observed NDVI)."""
    raw = np.asarray(scene["image"].values)
    before, after, truth = (east_west(cube, mask) for cube in (raw, corrected, scene["truth"]))
    worst = int(np.argmax(np.abs(after)))
    print(f"  whole scene east/west, worst band: before {np.max(np.abs(before)):.2%}, after "
          f"{abs(after[worst]):.2%}; the truth's own {abs(truth[worst]):.2%}")


def best_of(repeat: int, function, *args, **kwargs):
    """(value of the fastest call, its wall time) over ``repeat`` calls: the machine is shared."""
    best, value = math.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function(*args, **kwargs)
        elapsed = time.perf_counter() - start
        if elapsed < best:
            best, value = elapsed, result
    return value, best


# ------------------------------------------------------------------------------------ the runs
def workflow_a(scene: dict, continuous: bool = False):
    """NDVI strata -> fit -> correct, with the strata's coefficients interpolated in NDVI when
    ``continuous`` (FlexBRDF; the table's ``ndvi_interpolation``, centres measured on the scene);
    (strata, fit result, corrected, seconds per phase)."""
    phases, start = {}, time.perf_counter()
    strata = ndvi_strata(scene["image"], percentiles=PERCENTILES).classes
    phases["strata"], start = time.perf_counter() - start, time.perf_counter()
    result = fit(scene, strata, "ross_thick_li_sparse")
    phases["fit"], start = time.perf_counter() - start, time.perf_counter()
    table = result.table
    if continuous:
        table = table.with_ndvi_interpolation({"classes": list(table.class_ids)})
    corrected = correct(scene, strata, table)
    phases["correct"] = time.perf_counter() - start
    return strata, result, corrected, phases


def phase_line(elapsed: float, phases: dict[str, float], baseline: float) -> str:
    parts = ", ".join(f"{name} {seconds:.2f} s ({seconds / baseline:.0f}x)" for name, seconds in phases.items())
    return (f"  {' + '.join(phases)}: {elapsed:.2f} s (goal < 6 s at 400 x 600 x 60), {elapsed / baseline:.0f}x "
            f"one cube * factor pass; {parts}")


def fraction_groups(scene: dict) -> np.ndarray:
    """Five groups of near-equal size by the true vegetation fraction v: each holds the same mixture
    east and west, so their east/west difference after the correction is the correction's own."""
    fraction = scene["fraction"]
    return np.digitize(fraction, np.percentile(fraction, PERCENTILES)).astype(np.uint8) + 1


def fraction_report(scene: dict, corrected: np.ndarray, goal: float | None) -> float:
    """Print, and return, the worst east/west after the correction over the true-fraction groups."""
    groups = fraction_groups(scene)
    values = scores(scene, corrected, groups, range(1, len(PERCENTILES) + 2))
    print(f"  worst east/west by true-fraction group after {values['after']:.2%}{verdict(values['after'], goal)}; "
          f"the truth's own {values['truth']:.2%}; residual after - truth {values['residual']:.2%}")
    return values["after"]


def run_vegetation_soil(args, baseline: float) -> None:
    scenes = [scene_vegetation_soil(args.rows, args.columns, args.bands, args.noise, mirror=m) for m in (False, True)]
    for mirror, scene in zip((False, True), scenes):
        for continuous in (False, True):
            run_vegetation_soil_case(args, baseline, scene, continuous, mirror)


def run_vegetation_soil_case(args, baseline: float, scene: dict, continuous: bool, mirror: bool) -> None:
    how = "coefficients interpolated in NDVI (ndvi_interpolation)" if continuous else "one model per stratum"
    which = "A' (fields mirrored: the truth's own east/west is 0)" if mirror else "A (as flown)"
    print(f"\n{which}. vegetation/soil mixture, {args.bands} bands x {args.rows} x {args.columns}, "
          f"noise {args.noise:.1%}: NDVI percentile strata {PERCENTILES} + ross_thick_li_sparse; {how}")
    (strata, result, corrected, phases), elapsed = best_of(args.repeat, workflow_a, scene, continuous)
    classes = np.asarray(strata.values)
    names = {}
    for entry in result.fits:
        low, high = np.percentile(scene["fraction"][classes == entry.class_id], [5, 95])
        names[entry.class_id] = f"stratum {entry.class_id} (v {low:.2f}-{high:.2f})"
    gradient_table(scene, corrected, classes, names)
    report(scores(scene, corrected, classes, names), 0.007, None, args.noise, "stratum")
    fraction_report(scene, corrected, 0.002 if mirror else None)  # the goal's measure: module docstring
    whole_scene(scene, corrected, classes > 0)
    print(phase_line(elapsed, phases, baseline))


def fit_urban(scene: dict, classes: xr.DataArray, n_fixed: float | None):
    """Per-class models in one fit_classes call, or (``n_fixed``) Torrance-Sparrow with n held
    fixed, which needs a call of its own (``fixed`` applies to every class of a call)."""
    if n_fixed is None:
        return fit(scene, classes, ClassModels("ross_thick_li_sparse", names=URBAN_NAMES,
                                               class_models={ROOF: "torrance_sparrow", CONCRETE: "torrance_sparrow"}))
    specular = fit(scene, classes, ClassModels("torrance_sparrow", class_ids=[ROOF, CONCRETE], names=URBAN_NAMES,
                                               fixed={"n": n_fixed}))
    kernels = fit(scene, classes, ClassModels("ross_thick_li_sparse", class_ids=[GRASS, SOIL], names=URBAN_NAMES))
    return specular.fits + kernels.fits, ParameterTable(classes=[*specular.table.classes, *kernels.table.classes])


def workflow_b(scene: dict, classes: xr.DataArray, n_fixed: float | None = None):
    """Fit -> correct; (fits, corrected, seconds per phase)."""
    start = time.perf_counter()
    fitted = fit_urban(scene, classes, n_fixed)
    fits, table = (fitted.fits, fitted.table) if n_fixed is None else fitted
    middle = time.perf_counter()
    corrected = correct(scene, classes, table)
    return fits, corrected, {"fit": middle - start, "correct": time.perf_counter() - middle}


def run_urban(args, baseline: float) -> None:
    """Scene B with default guard rails and with n held, then B' (mirrored) with default guard rails."""
    scenes = [scene_urban(args.rows, args.columns, args.bands, args.noise, mirror=m) for m in (False, True)]
    for scene, n_fixed in ((scenes[0], None), (scenes[0], N_GENERIC), (scenes[1], None)):
        run_urban_case(args, baseline, scene, n_fixed, mirror=scene is scenes[1])


def run_urban_case(args, baseline: float, scene: dict, n_fixed: float | None, mirror: bool) -> None:
    """Fit and correct one urban scene, print its fits and east/west table; the east/west goal is
    held against "after" on the ``mirror``ed scene, against the residual on B (module docstring)."""
    classes = class_map(scene, scene["classes"])
    truths = {ROOF: load_material("roof_tile").params, CONCRETE: load_material("red_concrete").params}
    how = "default guard rails" if n_fixed is None else f"TS refractive index n fixed at {n_fixed:g}"
    which = "B'. urban, mirrored (the truth's own east/west is 0)" if mirror else "B. urban"
    print(f"\n{which}, {args.bands} bands x {args.rows} x {args.columns}, noise {args.noise:.1%}: "
          f"torrance_sparrow (roof tile, red concrete) + ross_thick_li_sparse (grass, soil); {how}")
    repeat = args.repeat if n_fixed is None and not mirror else 1  # timed: the one-call workflow of the issue
    (fits, corrected, phases), elapsed = best_of(repeat, workflow_b, scene, classes, n_fixed)
    for entry in fits:
        shape = ", ".join(f"{k} {entry.params[k][0]:.3g} (truth {truths[entry.class_id][k]:g})"
                          for k in ("w", "n") if k in entry.params)
        shape = f"; {shape}" if shape else ""
        print(f"  fit {entry.name}: {entry.status}, median R^2 {entry.median_r2:.2f}{shape}")
    gradient_table(scene, corrected, scene["classes"], URBAN_NAMES)
    report(scores(scene, corrected, scene["classes"], URBAN_NAMES), 0.01, 0.01, args.noise, "class",
           "after" if mirror else "residual")
    if n_fixed is None and not mirror:
        print(phase_line(elapsed, phases, baseline))


def cube_pass(rows: int, columns: int, bands: int) -> float:
    """Best of 3: ``cube * factor`` (float32), one read and one write of the whole cube."""
    rng = np.random.default_rng(0)
    cube = rng.uniform(0.01, 0.5, (bands, rows, columns)).astype(np.float32)
    factor = rng.uniform(0.8, 1.2, (rows, columns)).astype(np.float32)
    return best_of(3, np.multiply, cube, factor)[1]


def scene_parser(description: str) -> argparse.ArgumentParser:
    """The options of the scenes' size and noise (shared with bench_ndvi_strata.py)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--rows", type=int, default=400)
    parser.add_argument("--columns", type=int, default=600)
    parser.add_argument("--bands", type=int, default=60)
    parser.add_argument("--noise", type=float, default=0.01, help="relative sensor noise (1 sigma)")
    return parser


def main() -> None:
    parser = scene_parser(__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true", help="120 x 180 x 20: a quick check")
    parser.add_argument("--repeat", type=int, default=2, help="timed runs, best kept (the machine is shared)")
    args = parser.parse_args()
    if args.small:
        args.rows, args.columns, args.bands = 120, 180, 20
    baseline = cube_pass(args.rows, args.columns, args.bands)
    print(f"baseline: cube * factor over {args.bands} x {args.rows} x {args.columns} float32: {baseline * 1e3:.1f} ms")
    run_vegetation_soil(args, baseline)
    run_urban(args, baseline)


if __name__ == "__main__":
    main()
