"""Benchmark: brdfcorr on real imagery, a MODIS/Terra 8-day surface reflectance composite (issue 24).

The subset (``benchmarks/data/modis_mod09a1_h18v04/``, its README for the source and licence): 73 x 66
pixels (463 m) of MOD09A1 collection 6, tile h18v04, 12-19 July 2017, in the Bergamo Alps (about
46.0 N, 10.0 E), seven land bands with per-pixel sun zenith, view zenith (3-52 deg) and relative
azimuth; cloud, shadow and water masked. A composite takes each pixel from the best day of the
eight, so neighbouring pixels are seen from either side of nadir: the view-angle signal of a land
cover shows as a slope of its reflectance against the signed view zenith.

Three corrections of the subset, each to nadir view at the observed sun zenith (brdfcorr's
default reference) or, with ``--ref-sza``, at the subset's mean or a fixed sun zenith (the
subset's sun and view zenith are tied by its orbits, r = -0.99: a reference that follows the
observed sun keeps a slope against the view; the header line prints r):

- ``brdfcorr``: ``brdfcorr classes ndvi`` strata (quartiles of the raw NDVI,
  :func:`brdfcorr.tasks.classmaps.ndvi_class_file`), ``fit-classes`` on the subset itself
  (ross_thick_li_sparse, the default on NDVI strata, :func:`brdfcorr.tasks.fit.fit_class_files`),
  ``correct`` (:func:`brdfcorr.tasks.correct.correct_files`);
- ``brdfcorr interp``: the same table with an ``ndvi_interpolation`` block over the strata (the
  coefficients interpolated in each pixel's NDVI, FlexBRDF's way; ``docs/classmaps.md``);
- ``c-factor``: the fixed global RTLSR coefficients of Roy et al. (2016), RSE 176, 255-271,
  Table 1 (``correct --params roy2016``) for every pixel, with ``--extrapolate`` (MODIS band 3,
  469 nm, lies below the table's blue band, 477-492 nm: it takes the blue weights).

Measured (:func:`brdfcorr.analysis.assess.assess_view_angles`, signed by the sun: positive
towards forward scattering): per NDVI group (the same quartiles) and band, the least-squares slope
of reflectance against the signed view zenith relative to the group's mean [%/10 deg], raw and
after each correction, on the same pixels, with its 1-sigma from a block bootstrap (8-pixel
squares resampled whole: neighbouring pixels of a composite share their day, so they are not
independent). Goals (issue 24): the worst |slope| over NDVI groups x red/NIR <= 0.3 %/10 deg, and
at most half of what the c-factor leaves.

The fit and that assessment use the same pixels (the c-factor is fitted to none of them). A
two-fold cross-check follows: the strata fitted on one colour of a checkerboard of 8-pixel squares
and assessed on the other, the raw slope and the c-factor's on the same held-out pixels beside.

Run: ``python benchmarks/bench_real.py`` (about 10 s; ``--strata`` cuts the fit's strata at other
percentiles; ``--ref-sza 28`` corrects to a fixed sun zenith of 28 deg); ``--json FILE`` also
writes the numbers.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import rasterio
import rioxarray

from brdfcorr.analysis.assess import ViewAngleOptions, assess_view_angles, signed_view_zenith
from brdfcorr.fit import ClassModels, Sampling
from brdfcorr.fit.prior import ShapePrior
from brdfcorr.io.angles import open_angles
from brdfcorr.io.rasters import open_image
from brdfcorr.io.scene import SceneSources
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.params import ClassEntry, ParameterTable
from brdfcorr.tasks.classmaps import NdviBins, ndvi_class_file
from brdfcorr.tasks.correct import correct_files
from brdfcorr.tasks.fit import SceneFiles, fit_class_files
from brdfcorr.tasks.request import CorrectionRequest, OutputFiles

DATA = Path(__file__).resolve().parent / "data" / "modis_mod09a1_h18v04"
#: The NDVI groups: quartiles of the raw NDVI [%].
PERCENTILES = (25.0, 50.0, 75.0)
#: Bands reported: name -> wavelength range [nm] (MODIS band 1, 620-670 nm; band 2, 841-876 nm).
REPORTED = {"red": (620.0, 690.0), "nir": (780.0, 900.0)}
#: Issue 24's goals: worst |relative slope| [%/10 deg], and its ratio to the c-factor's.
GOAL_WORST = 0.3
GOAL_RATIO = 0.5
METHODS = ("brdfcorr", "brdfcorr interp", "c-factor")
#: Side of the checkerboard's squares of the two-fold cross-check [pixels] (3.7 km).
HOLDOUT_BLOCK = 8
#: Replicates and square side [pixels] of the block bootstrap of the slopes' standard errors.
BOOTSTRAP_REPLICATES, BOOTSTRAP_BLOCK = 400, 8
#: Side [pixels] of the patches of ``--levels patch``.
PATCH = 8


def roy2016_table() -> ParameterTable:
    """The c-factor's table: Roy et al. (2016) Table 1 as class 1 (``correct --params roy2016``)."""
    return ParameterTable(classes=[ClassEntry(**load_coefficients("roy2016").table_entry(1))])


def fit_table(data: Path, classes: Path, max_samples: int = 50_000,
              prior_spread: float | None = None, model: str | None = None,
              levels: str = "pooled") -> tuple[ParameterTable, list[dict]]:
    """``fit-classes`` on the subset with the class map ``classes`` (its classes' default model on
    NDVI strata, ross_thick_li_sparse), with ``--prior roy2016 --prior-spread prior_spread`` where
    given, or every class with ``model`` (``auto``: the held-out choice), and ``--levels levels``
    (``patch``: each 8-pixel square's own level, :data:`PATCH`): the table and the report entries
    of the classes the guard rails left out."""
    prior = None if prior_spread is None else ShapePrior("roy2016", prior_spread)
    fit = fit_class_files([SceneFiles(data / "reflectance.tif", classes, data / "angles.tif")],
                          ClassModels(model, prior=prior),
                          sampling=Sampling(max_samples=max_samples, levels=levels, patch_size=PATCH))
    return fit.table, [entry for entry in fit.report()["classes"] if entry.get("status") != "fitted"]


def correct(data: Path, classes: Path | None, table: ParameterTable, target: Path, extrapolate: bool = False,
            ref_sza: float | str = "observed") -> Path:
    """``correct`` the subset with ``table`` to nadir view at the sun zenith ``ref_sza`` [deg]:
    each pixel's observed one (the default), the scene's ``mean``, or a fixed value."""
    request = CorrectionRequest(SceneSources(data / "reflectance.tif", classes, data / "angles.tif"), table,
                                OutputFiles(target), extrapolate=extrapolate, reference={"sza": ref_sza, "vza": 0.0})
    correct_files(request)
    return target


def correct_subset(directory: Path, data: Path = DATA, strata_percentiles: Sequence[float] = PERCENTILES,
                   max_samples: int = 50_000, prior_spread: float | None = None,
                   model: str | None = None, levels: str = "pooled",
                   ref_sza: float | str = "observed") -> dict[str, object]:
    """Strata, fit and the three corrections of the subset in ``data``, written to ``directory``.

    The fit's strata are cut at ``strata_percentiles`` of the raw NDVI [%]. Returns the paths
    (``strata``, and one corrected image per method of :data:`METHODS` that ran: none of
    brdfcorr's where every stratum failed the guard rails, since ``correct`` refuses an empty
    table) and the classes the fit left out (``left_out``).
    """
    strata = directory / "strata.tif"
    ndvi_class_file(data / "reflectance.tif", strata, bins=NdviBins(percentiles=list(strata_percentiles)))
    table, left_out = fit_table(data, strata, max_samples, prior_spread, model, levels)
    outputs: dict[str, object] = {"strata": strata, "left_out": left_out}
    outputs["c-factor"] = correct(data, None, roy2016_table(), directory / "c-factor.tif", extrapolate=True,
                                  ref_sza=ref_sza)
    fitted = sorted(entry.id for entry in table.classes)
    if fitted:
        outputs["brdfcorr"] = correct(data, strata, table, directory / "brdfcorr.tif", ref_sza=ref_sza)
    if len(fitted) >= 2 and len({entry.model for entry in table.classes}) == 1:  # one model to interpolate
        interpolated = table.with_ndvi_interpolation({"classes": fitted})
        outputs["brdfcorr interp"] = correct(data, strata, interpolated, directory / "brdfcorr_interp.tif",
                                             ref_sza=ref_sza)
    return outputs


def band_index(wavelengths: np.ndarray, span: tuple[float, float]) -> int:
    """Index of the first band whose centre [nm] lies in ``span`` (ends included)."""
    inside = np.flatnonzero((wavelengths >= span[0]) & (wavelengths <= span[1]))
    if inside.size == 0:
        raise ValueError(f"no band centre in {span[0]:g}-{span[1]:g} nm")
    return int(inside[0])


def relative_slopes(data: Path, corrected: Path, groups: Path, names: dict[int, str]) -> dict[str, dict]:
    """Relative slopes [%/10 deg] of the raw subset and of ``corrected`` per NDVI group of ``groups``
    (:func:`assess_view_angles`, signed by the sun), of the bands of :data:`REPORTED`:
    ``{"raw": {band: [...]}, "after": {band: [...]}}``, and the groups' ``names`` and ``pixels``.

    The product gives the relative azimuth raa = vaa - saa only: saa = 0 and vaa = raa give the
    same relative azimuth (what the sign by the sun depends on), as brdfcorr's 3-band angle
    rasters do (:func:`brdfcorr.io.angles.from_relative_azimuth`).
    """
    before, after = open_image(data / "reflectance.tif").compute(), open_image(corrected).compute()
    geometry = {key: value.compute() for key, value in open_angles(data / "angles.tif").items()}
    classes = rioxarray.open_rasterio(groups).squeeze("band", drop=True).compute()
    assessed = assess_view_angles(before, after, classes, geometry["vza"], geometry["vaa"], geometry["saa"],
                                  options=ViewAngleOptions(by="sun", class_names=names))
    wavelengths = np.asarray(assessed["wavelength"].values, float)
    result: dict[str, dict] = {"raw": {}, "after": {}}
    for band, span in REPORTED.items():
        values = assessed["relative_slope"].isel(band=band_index(wavelengths, span))
        result["raw"][band] = [float(v) for v in values.sel(stage="before").values]
        result["after"][band] = [float(v) for v in values.sel(stage="after").values]
    result["names"] = [str(name) for name in assessed["class_name"].values]
    result["pixels"] = [int(n) for n in assessed["pixels"].values]
    return result


def bootstrap_error(theta: np.ndarray, values: np.ndarray, blocks: np.ndarray,
                    replicates: int = BOOTSTRAP_REPLICATES, seed: int = 0) -> float:
    """1-sigma of the relative slope 1000 b / mean [%/10 deg] of ``values`` against ``theta`` [deg]
    by a block bootstrap: whole squares of pixels (``blocks``, a label per pixel) drawn with
    replacement, so that the spatial correlation of a composite (neighbouring pixels taken on the
    same day) stays in the resamples (Kuensch 1989, Ann. Stat. 17, 1217-1241). Each replicate's
    slope is the least-squares slope weighted by how often its pixels were drawn."""
    labels, index = np.unique(blocks, return_inverse=True)
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, labels.size, size=(replicates, labels.size))
    weights = np.stack([np.bincount(row, minlength=labels.size) for row in draws])[:, index].astype(float)
    n = weights.sum(axis=1)
    mean_theta, mean_value = weights @ theta / n, weights @ values / n
    covariance = weights @ (theta * values) / n - mean_theta * mean_value
    variance = weights @ (theta * theta) / n - mean_theta**2
    return float(np.std(1000.0 * covariance / variance / mean_value, ddof=1))


def standard_errors(data: Path, corrected: Path, groups: Path, block: int = BOOTSTRAP_BLOCK) -> dict[str, list[float]]:
    """Block-bootstrap 1-sigma [%/10 deg] (:func:`bootstrap_error`) of the relative slope of
    ``corrected`` (the raw subset for the raw slopes) per NDVI group and band of :data:`REPORTED`,
    on the pixels :func:`assess_view_angles` uses (valid in every band of both images)."""
    raw, cube = open_image(data / "reflectance.tif").values, open_image(corrected)
    wavelengths, values = np.asarray(cube["wavelength"].values, float), cube.values
    angles = {key: value.values for key, value in open_angles(data / "angles.tif").items()}
    theta = signed_view_zenith(angles["vza"], angles["vaa"], angles["saa"], by="sun")
    with rasterio.open(groups) as source:
        classes = source.read(1)
    rows, columns = np.indices(classes.shape)
    blocks = (rows // block) * (classes.shape[1] // block + 1) + columns // block
    valid = np.isfinite(raw).all(axis=0) & np.isfinite(values).all(axis=0) & np.isfinite(theta)
    errors: dict[str, list[float]] = {}
    for band, span in REPORTED.items():
        layer = values[band_index(wavelengths, span)]
        errors[band] = [bootstrap_error(theta[pick], layer[pick], blocks[pick])
                        for pick in ((classes == k) & valid for k in np.unique(classes[classes > 0]))]
    return errors


def _nan_slopes(like: dict[str, list[float]]) -> dict[str, list[float]]:
    return {band: [float("nan")] * len(values) for band, values in like.items()}


def slope_table(directory: Path, data: Path = DATA, strata_percentiles: Sequence[float] = PERCENTILES,
                max_samples: int = 50_000, prior_spread: float | None = None,
                model: str | None = None, levels: str = "pooled",
                ref_sza: float | str = "observed") -> dict[str, object]:
    """Relative slopes [%/10 deg] per method (``raw`` and :data:`METHODS`; NaN for a method that did
    not run), band (:data:`REPORTED`) and NDVI group (quartiles of the raw NDVI,
    :data:`PERCENTILES`), the groups' names and pixels, the fit's classes left out; the corrected
    files in ``outputs``."""
    groups = directory / "groups.tif"
    names = ndvi_class_file(data / "reflectance.tif", groups, bins=NdviBins(percentiles=list(PERCENTILES))).names
    outputs = correct_subset(directory, data, strata_percentiles, max_samples, prior_spread, model, levels, ref_sza)
    slopes: dict[str, dict[str, list[float]]] = {}
    errors = {"raw": standard_errors(data, data / "reflectance.tif", groups)}
    for method in METHODS:
        if method in outputs:
            measured = relative_slopes(data, outputs[method], groups, names)
            slopes["raw"], slopes[method] = measured["raw"], measured["after"]
            errors[method] = standard_errors(data, outputs[method], groups)
    for method in METHODS:
        slopes.setdefault(method, _nan_slopes(slopes["raw"]))
        errors.setdefault(method, _nan_slopes(slopes["raw"]))
    return {"slopes": slopes, "errors": errors, "groups": measured["names"], "pixels": measured["pixels"],
            "names": names, "groups_file": groups, "outputs": outputs, "left_out": outputs["left_out"]}


def masked_copy(classes: Path, keep: np.ndarray, target: Path) -> Path:
    """A copy of the class map ``classes`` with class 0 (no class) where ``keep`` is False, its tags
    (the strata's names and edges) kept."""
    with rasterio.open(classes) as source:
        profile, tags, values = source.profile, source.tags(), source.read(1)
    with rasterio.open(target, "w", **profile) as sink:
        sink.write(np.where(keep, values, 0).astype(values.dtype), 1)
        sink.update_tags(**tags)
    return target


def holdout(directory: Path, result: dict[str, object], data: Path = DATA, block: int = HOLDOUT_BLOCK,
            prior_spread: float | None = None, model: str | None = None, levels: str = "pooled",
            ref_sza: float | str = "observed") -> list[dict]:
    """Two-fold cross-check on a checkerboard of ``block`` x ``block`` pixel squares: fit the
    strata on the pixels of one colour, correct the subset, assess on the NDVI groups' pixels of
    the other colour; the raw slopes and the c-factor's on the same pixels beside. Per fold:
    ``{"raw", "brdfcorr", "c-factor": {band: [...]}, "pixels": [...], "left_out": [...]}``."""
    outputs = result["outputs"]
    with rasterio.open(outputs["strata"]) as source:
        rows, columns = np.indices(source.shape)
    black = (rows // block + columns // block) % 2 == 0
    folds = []
    for fold, fit_on in enumerate((black, ~black)):
        fit_map = masked_copy(outputs["strata"], fit_on, directory / f"fold{fold}_strata.tif")
        groups = masked_copy(result["groups_file"], ~fit_on, directory / f"fold{fold}_groups.tif")
        table, left_out = fit_table(data, fit_map, prior_spread=prior_spread, model=model, levels=levels)
        cfactor = relative_slopes(data, outputs["c-factor"], groups, result["names"])
        entry = {"left_out": left_out, "raw": cfactor["raw"], "c-factor": cfactor["after"], "pixels": cfactor["pixels"],
                 "errors": {"raw": standard_errors(data, data / "reflectance.tif", groups),
                            "c-factor": standard_errors(data, outputs["c-factor"], groups)}}
        entry["brdfcorr"] = entry["errors"]["brdfcorr"] = _nan_slopes(cfactor["raw"])
        if table.classes:
            corrected = correct(data, outputs["strata"], table, directory / f"fold{fold}_brdfcorr.tif", ref_sza=ref_sza)
            entry["brdfcorr"] = relative_slopes(data, corrected, groups, result["names"])["after"]
            entry["errors"]["brdfcorr"] = standard_errors(data, corrected, groups)
        folds.append(entry)
    return folds


def sun_and_view(data: Path = DATA) -> dict[str, float]:
    """The subset's sun zenith [deg]: its range and mean over the pixels valid in every band, and
    its correlation with the signed view zenith there (a composite's orbits tie the two: a slope
    against the view is then also one against the sun, and a reference that follows the observed
    sun keeps part of it)."""
    raw = open_image(data / "reflectance.tif").values
    angles = {key: value.values for key, value in open_angles(data / "angles.tif").items()}
    theta = signed_view_zenith(angles["vza"], angles["vaa"], angles["saa"], by="sun")
    valid = np.isfinite(raw).all(axis=0) & np.isfinite(theta) & np.isfinite(angles["sza"])
    sza = angles["sza"][valid]
    return {"min": float(sza.min()), "max": float(sza.max()), "mean": float(sza.mean()),
            "r_signed_vza": float(np.corrcoef(sza, theta[valid])[0, 1])}


def _reference(text: str) -> float | str:
    """``--ref-sza``: ``observed``, ``mean`` or a sun zenith [deg] in [0, 90)."""
    if text in ("observed", "mean"):
        return text
    value = float(text)
    if not 0.0 <= value < 90.0:
        raise argparse.ArgumentTypeError(f"{text}: give observed, mean or a sun zenith in [0, 90) deg")
    return value


def worst(slopes: dict[str, list[float]]) -> float:
    """The largest |slope| over the bands and groups (NaN left out; NaN if none)."""
    values = np.abs(np.concatenate([np.asarray(v, float) for v in slopes.values()]))
    values = values[np.isfinite(values)]
    return float(values.max()) if values.size else float("nan")


def _rows(slopes: dict, methods: Sequence[str], groups: Sequence[str], pixels: Sequence[int],
          errors: dict | None = None) -> None:
    print(f"{'NDVI group':<16}{'pixels':>7}{'band':>6}" + "".join(f"{m:>17}" for m in methods))
    for g, (group, n) in enumerate(zip(groups, pixels)):
        for band in REPORTED:
            cells = [f"{slopes[m][band][g]:.2f}" + (f"±{errors[m][band][g]:.2f}" if errors else "") for m in methods]
            print(f"{group:<16}{n:>7}{band:>6}" + "".join(f"{cell:>17}" for cell in cells))
    print("worst |slope| over groups x red/NIR: " + ", ".join(f"{m} {worst(slopes[m]):.2f}" for m in methods))
    if errors:
        print("within 2 sigma of 0 (of groups x red/NIR): " + ", ".join(
            f"{m} {within_two_sigma(slopes[m], errors[m])}" for m in methods))


def within_two_sigma(slopes: dict[str, list[float]], errors: dict[str, list[float]]) -> str:
    """``k/n``: how many of the n slopes with a 1-sigma lie within 2 sigma of 0."""
    values, sigmas = (np.concatenate([np.asarray(d[band], float) for band in REPORTED]) for d in (slopes, errors))
    measured = np.isfinite(values) & np.isfinite(sigmas)
    return f"{int(np.sum(np.abs(values[measured]) <= 2 * sigmas[measured]))}/{int(measured.sum())}"


def print_report(result: dict[str, object], folds: Sequence[dict] = ()) -> None:
    """The tables of slopes per NDVI group and band (all pixels; each fold's held-out pixels) and
    the goals."""
    slopes = result["slopes"]
    print("relative slope of reflectance against signed view zenith [%/10 deg] (positive: brighter forward)")
    print(f"fitted on and assessed on every pixel (± block-bootstrap 1-sigma, {BOOTSTRAP_BLOCK}-pixel squares):")
    _rows(slopes, ["raw", *METHODS], result["groups"], result["pixels"], result["errors"])
    cfactor = worst(slopes["c-factor"])
    for method in METHODS[:2]:
        value = worst(slopes[method])
        print(f"goal {method}: worst {value:.2f} <= {GOAL_WORST}: {'met' if value <= GOAL_WORST else 'MISSED'}; "
              f"<= half the c-factor's ({cfactor / 2:.2f}): {'met' if value <= GOAL_RATIO * cfactor else 'MISSED'}")
    for entry in result["left_out"]:
        print(f"class {entry.get('class_id')} {entry.get('name')}: {entry.get('status')} (left uncorrected)")
    for fold, entry in enumerate(folds):
        print(f"fold {fold}: fitted on one colour of a checkerboard of {HOLDOUT_BLOCK}-pixel squares, assessed on "
              "the other:")
        _rows(entry, ["raw", "brdfcorr", "c-factor"], result["groups"], entry["pixels"], entry["errors"])
        for left in entry["left_out"]:
            print(f"  class {left.get('class_id')} {left.get('name')}: {left.get('status')} (left uncorrected)")


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="subset directory (reflectance.tif, angles.tif)")
    parser.add_argument("--strata", default=",".join(f"{p:g}" for p in PERCENTILES),
                        help="percentiles of the raw NDVI [%%] cutting the fit's strata (default: quartiles)")
    parser.add_argument("--prior-spread", type=float, help="fit with the kernel shape of roy2016 as a prior of "
                                                           "this spread (fit-classes --prior roy2016 --prior-spread)")
    parser.add_argument("--model", help="fit every stratum with this model (auto: the held-out choice) "
                                        "[default: ross_thick_li_sparse, the strata's]")
    parser.add_argument("--levels", choices=("pooled", "patch"), default="pooled",
                        help=f"fit-classes --levels: pooled, or each {PATCH}-pixel square's own level")
    parser.add_argument("--ref-sza", type=_reference, default="observed",
                        help="reference sun zenith of every correction: observed (each pixel's, the default), mean "
                             "(the subset's) or a fixed value [deg]; the view is nadir")
    parser.add_argument("--json", type=Path, help="also write the numbers to this JSON file")
    args = parser.parse_args(argv)
    sun = sun_and_view(args.data)
    print(f"sun zenith {sun['min']:.1f}-{sun['max']:.1f} deg (mean {sun['mean']:.2f}), correlation with the signed "
          f"view zenith r = {sun['r_signed_vza']:.2f}; reference: nadir view, sun zenith "
          + (f"{args.ref_sza:g} deg" if isinstance(args.ref_sza, float) else args.ref_sza))
    with tempfile.TemporaryDirectory() as scratch:
        result = slope_table(Path(scratch), args.data, [float(p) for p in args.strata.split(",")],
                             prior_spread=args.prior_spread, model=args.model, levels=args.levels,
                             ref_sza=args.ref_sza)
        folds = holdout(Path(scratch), result, args.data, prior_spread=args.prior_spread, model=args.model,
                        levels=args.levels, ref_sza=args.ref_sza)
    print_report(result, folds)
    if args.json:
        numbers = {key: result[key] for key in ("slopes", "errors", "groups", "pixels", "left_out")}
        args.json.write_text(json.dumps({**numbers, "holdout": folds, "ref_sza": args.ref_sza, "sun": sun}, indent=1,
                                        default=str))


if __name__ == "__main__":
    main()
