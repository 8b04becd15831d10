"""Per-pixel 1-sigma of the BRDF-corrected reflectance, propagated from the fit's parameter covariance.

The correction (:func:`brdfcorr.correction.normalize`, ``docs/conventions.md``, "The correction")
multiplies each pixel by the factor

    F(p) = f(ref; p) / f(obs; p)                                                            (1)

of its class's model f and parameters p (one set per band). A fit that reports the covariance
Sigma of its parameters (the ``fit:`` block of a parameter table: the fitted parameters, in
covariance order, and one p x p matrix per table wavelength or one for all) gives, to first order
(the Gauss "law of propagation of uncertainty", JCGM 100:2008 (GUM) eq. 13)

    sigma_F^2 = J Sigma J^T,     J_a = dF/dp_a over the covariance's parameters              (2)
    sigma     = |observed| * sigma_F                                                        (3)

``sigma`` is the 1-sigma of the corrected reflectance, in the reflectance's units. Parameters the
fit held fixed are not in Sigma: they contribute no variance. The observed reflectance is taken as
exact (only the model's uncertainty is propagated), and so is the reference geometry (a scene-mean
sun zenith included).

The Jacobian (``docs/uncertainty.md``):

- linear (intensity) parameters, ``f = sum_j c_j B_j(geometry; shape)`` (:attr:`Model.linear`,
  :meth:`Model.terms`): exactly,

      dF/dc_j = (B_j(ref) - F B_j(obs)) / f(obs)                                            (4)

- shape parameters s (``w``, ``n``, ``k`` of Torrance-Sparrow; ``b``, ``c`` of the empirical model;
  ``k``, ``theta``, ``rho_c`` of RPV): by a central difference of (1) with the same coefficients,

      dF/ds = (F(s + h) - F(s - h)) / (2 h),   h = eps^(1/3) max(|s|, |s_typical|)         (5)

  (eps = 2.2e-16 the float64 resolution, ``s_typical`` the registry default: the step that balances
  truncation, O(h^2), against rounding, O(eps / h)). Where ``s - h`` or ``s + h`` would leave the
  parameter's physical range (``k = 0`` of Torrance-Sparrow, ``rho_c = 1`` of RPV), the one-sided
  second-order difference ``(-3 F(s) + 4 F(s + h) - F(s + 2 h)) / (2 h)`` (or its mirror) is used
  instead, so the model is never evaluated outside its range.

A class taken from the built-in material library (``material:`` in the table, no ``fit:`` block)
gets the diagonal covariance of the material's published 1-sigma errors (paper 003, Table 1, fits
at 550 nm; the parameter the authors held fixed, k, is left out): the source gives no correlations,
and its errors belong to a goniometer fit of one sample at 550 nm, not to the class in the image.
A :class:`~brdfcorr.errors.BrdfcorrWarning` says so for every such class (:func:`material_covariance`).

A pixel is nodata (NaN) in a band where there is nothing to propagate: its class has no covariance,
it has no class or one absent from the table, its data or geometry is invalid (a non-finite value,
a zenith outside [0, 90) deg), its factor is invalid (no finite positive F, including the 0 / 0 that
``normalize`` leaves unchanged), or its factor was clipped to the limits: a clipped factor is a
bound chosen by the user, not the model's prediction, so the covariance says nothing about it.
A band in which the pixel's class has no parameters (its ``bad_bands``) is passed through
uncorrected by :func:`normalize`: the correction adds no uncertainty there (sigma 0).

With ``slope`` and ``aspect`` (tilted surfaces, ``docs/terrain.md``) the observed geometry is taken in
each surface's own frame and the reference in the horizontal one, as :func:`normalize` does; a
pixel whose sun or sensor is behind its surface is nodata.

With dask-backed inputs the result is lazy, one task per reflectance chunk with the chunks of the
reflectance, built from the same input arrays (same dask keys) as :func:`normalize`: computing the
corrected image and its uncertainty together (``dask.compute(corrected, sigma)``) reads each input
chunk once.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from brdfcorr.correction.blocks import NO_PARAMETERS, PixelGeometry, Plans, class_plan, present_classes
from brdfcorr.correction.inputs import BlockSettings, prepare_inputs
from brdfcorr.correction.reference import describe_limits
from brdfcorr.correction.series import is_series, over_dates
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import BrdfcorrWarning, ParameterError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import Model
from brdfcorr.models.materials import load_material
from brdfcorr.params import BandParameters, ParameterTable, ReferenceGeometry, as_parameter_table

__all__ = ["correction_uncertainty", "factor_jacobian", "difference_step", "material_covariance"]

#: Parameters the source of the material library held fixed (paper 003 fixes k = 0.25; the "error"
#: it prints for k is no uncertainty of a fitted value): they get no variance.
MATERIAL_FIXED = ("k",)

#: Relative step of the central differences, eps^(1/3) (eq. 5).
RELATIVE_STEP = float(np.finfo(np.float64).eps) ** (1.0 / 3.0)

#: How the shape derivatives are computed, for the output's attrs and the docs.
METHOD = (
    "first-order propagation of the fit's parameter covariance, sigma = |observed| * sqrt(J Sigma J^T), "
    "J = d(f(ref)/f(obs))/dp: exact for the linear (intensity) parameters, central differences with "
    "step eps^(1/3) * max(|s|, |default|) for shape parameters (one-sided at a range bound); NaN where "
    "the class has no covariance (a library material gets its published errors, uncorrelated), no class or "
    "an unknown one, invalid data or geometry (a surface "
    "facing away included), no valid factor, or a factor clipped to the limits"
)


# --------------------------------------------------------------------------------------- the core
def difference_step(model: Model, name: str, value: float) -> tuple[tuple[float, float], ...]:
    """The finite-difference stencil of a shape parameter: ``((offset, weight), ...)`` with
    ``dF/ds ~ sum weight * F(s + offset)`` (eq. 5 of the module docstring).

    Central, ``((h, 1/2h), (-h, -1/2h))`` with ``h = eps^(1/3) max(|s|, |default|)``, unless a
    point would leave the parameter's physical range; then the one-sided second-order difference
    ``((0, -3/2h), (h, 4/2h), (2h, -1/2h))`` or its mirror (negative offsets).

    Parameters
    ----------
    model : Model
        The registry model.
    name : str
        A shape parameter of it (not in :attr:`Model.linear`).
    value : float
        The parameter's value [its registry units].
    """
    parameter = model.parameter(name)
    scale = max(abs(value), abs(parameter.default))
    h = RELATIVE_STEP * (scale if scale > 0 else 1.0)

    def inside(x: float) -> bool:
        above = x > parameter.lower if parameter.lower_open else x >= parameter.lower
        return above and x <= parameter.upper

    if inside(value - h) and inside(value + h):
        return ((h, 0.5 / h), (-h, -0.5 / h))
    sign = 1.0 if inside(value + 2.0 * h) else -1.0
    return ((0.0, -1.5 * sign / h), (sign * h, 2.0 * sign / h), (2.0 * sign * h, -0.5 * sign / h))


@dataclass(frozen=True)
class _ShapeTerms:
    """The basis functions B_j of a model at one shape, at the observed and reference geometries
    (float64, one row per pixel), and those of each differentiated shape parameter's stencil."""

    observed: np.ndarray  # (n_linear, n_pixels)
    reference: np.ndarray  # (n_linear, n_pixels), or (n_linear,) at a reference geometry of one value
    stencils: tuple[tuple[tuple[float, np.ndarray, np.ndarray], ...], ...]  # per shape name: (weight, obs, ref)


def _terms(model: Model, geometry: ScatteringGeometry, shape: Mapping[str, float], n: int | None) -> np.ndarray:
    """The basis functions as rows (n_linear, n); with ``n`` None, as they broadcast (a scalar
    reference geometry gives one value per term, not n copies)."""
    # A constant basis is a Python scalar (Model.basis). A term beyond float64 becomes inf and
    # its pixels NaN (_factor_and_jacobian).
    with np.errstate(over="ignore"):
        terms = [np.asarray(t, dtype=np.float64) for t in model.terms(geometry, shape)]
    return np.stack(np.broadcast_arrays(*terms) if n is None else [np.broadcast_to(t, (n,)) for t in terms])


def _shape_terms(
    model: Model, observed: ScatteringGeometry, reference: ScatteringGeometry, shape: Mapping[str, float],
    differentiated: Sequence[str], n: int,
) -> _ShapeTerms:
    stencils = []
    for name in differentiated:
        points = []
        for offset, weight in difference_step(model, name, shape[name]):
            moved = {**shape, name: shape[name] + offset}
            points.append((weight, _terms(model, observed, moved, n), _terms(model, reference, moved, None)))
        stencils.append(tuple(points))
    return _ShapeTerms(_terms(model, observed, shape, n), _terms(model, reference, shape, None), tuple(stencils))


def _factor_and_jacobian(
    terms: _ShapeTerms, coefficients: np.ndarray, linear_columns: Sequence[int], shape_columns: Sequence[int],
    n_columns: int,
) -> tuple[np.ndarray, np.ndarray]:
    """F (eq. 1) and J = dF/dp (eqs. 4, 5) at a class's pixels for one band.

    ``coefficients`` are the linear parameters (in :attr:`Model.linear` order); ``linear_columns[j]``
    is the Jacobian column of linear parameter j (-1: not in the covariance), ``shape_columns[m]``
    that of the m-th stencil of ``terms``. F is NaN where it is no valid factor (not finite and
    positive with f(obs) > 0, the rule of :func:`brdfcorr.correction.normalize`, 0 / 0 included).
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        f_observed = coefficients @ terms.observed
        factor = (coefficients @ terms.reference) / f_observed
        factor[~((f_observed > 0) & (factor > 0) & (factor < np.inf))] = np.nan  # NaN compares False
        jacobian = np.zeros((factor.size, n_columns))
        for j, column in enumerate(linear_columns):
            if column >= 0:
                jacobian[:, column] = (terms.reference[j] - factor * terms.observed[j]) / f_observed
        for column, stencil in zip(shape_columns, terms.stencils):
            jacobian[:, column] = sum(
                weight * (coefficients @ reference) / (coefficients @ observed)
                for weight, observed, reference in stencil
            )
    return factor, jacobian


def _propagate(jacobian: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """sqrt(J Sigma J^T) per pixel (eq. 2)."""
    variance = np.sum((jacobian @ covariance) * jacobian, axis=1)
    # Sigma is positive semi-definite (_checked_covariance): a negative variance is rounding.
    return np.sqrt(np.maximum(variance, 0.0))


def factor_jacobian(
    model: Model,
    observed: ScatteringGeometry,
    reference: ScatteringGeometry,
    params: Mapping[str, float],
    names: Sequence[str],
) -> tuple[np.ndarray, np.ndarray]:
    """The correction factor F = f(ref)/f(obs) and its Jacobian dF/dp at an array of geometries.

    Parameters
    ----------
    model : Model
        A registry model with linear parameters (every surface model).
    observed, reference : ScatteringGeometry
        The observed and reference geometries [deg]: angles that broadcast against each other
        (scalars or arrays); the results are over their broadcast shape, flattened.
    params : mapping of str to float
        Every parameter of the model (one band) [registry units].
    names : sequence of str
        The parameters to differentiate by, in the order of the Jacobian's columns (e.g. a
        covariance's parameters).

    Returns
    -------
    factor : ndarray (n,)
        F [-] (n the size of the broadcast geometry); NaN where it is no valid factor (not finite
        and positive).
    jacobian : ndarray (n, len(names))
        dF/dp_a [1 / units of p_a]: eq. 4 (exact) for linear parameters, eq. 5 (central differences,
        one-sided at a range bound) for shape parameters (module docstring).
    """
    model.validate(params)
    if not model.linear:
        raise ParameterError(f"{model.name}: a model without linear parameters has no correction factor")
    unknown = [name for name in names if name not in model.parameter_names]
    if unknown:
        raise ParameterError(f"{model.name}: unknown parameter(s) {', '.join(unknown)}")
    angles = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for g in (observed, reference)
                                   for a in (g.theta_i, g.theta_r, g.phi)))
    observed, reference = (ScatteringGeometry(*(a.ravel() for a in angles[i:i + 3])) for i in (0, 3))
    n = angles[0].size
    shape = {name: float(params[name]) for name in model.shape_names}
    differentiated = [name for name in names if name in model.shape_names]
    terms = _shape_terms(model, observed, reference, shape, differentiated, n)
    coefficients = np.array([float(params[name]) for name in model.linear])
    columns = _columns(model, names)
    return _factor_and_jacobian(terms, coefficients, columns[0], columns[1], len(names))


def _columns(model: Model, names: Sequence[str]) -> tuple[list[int], list[int]]:
    """Jacobian columns of the linear parameters (-1 where absent) and of the differentiated shape
    parameters (in ``names`` order)."""
    position = {name: column for column, name in enumerate(names)}
    linear = [position.get(name, -1) for name in model.linear]
    shape = [position[name] for name in names if name in model.shape_names]
    return linear, shape


# ------------------------------------------------------------------------------------ materials
def material_covariance(entry: BandParameters, material: str) -> BandParameters:
    """A library material's class with the diagonal covariance of its published 1-sigma errors.

    ``Sigma = diag(sigma_a^2)`` over the material's parameters with a published error, except those
    the source held fixed (:data:`MATERIAL_FIXED`), the same at every band (paper 003, Table 1:
    fits at 550 nm). The source gives no correlations (its fits' n and t1 trade off strongly), so
    the propagated sigma is that of uncorrelated parameters: an approximation, said by a
    :class:`BrdfcorrWarning`.

    Parameters
    ----------
    entry : BandParameters
        The class resolved to the image's bands, without a covariance.
    material : str
        Its library key (``ClassEntry.material``).
    """
    published = load_material(material)
    names = tuple(name for name in entry.model.parameter_names
                  if published.errors.get(name, 0.0) > 0 and name not in MATERIAL_FIXED)
    n_bands = len(next(iter(entry.params.values())))
    diagonal = np.diag([float(published.errors[name]) ** 2 for name in names])
    warnings.warn(
        f"class {entry.id} ({entry.name}): uncertainty from the published 1-sigma errors of material "
        f"{published.name} ({', '.join(names)}; {published.wavelength:g} nm, uncorrelated: the source "
        "gives no covariance), not from a fit to this image",
        BrdfcorrWarning, stacklevel=3,
    )
    return dataclasses.replace(entry, covariance=np.repeat(diagonal[None], n_bands, axis=0), covariance_names=names)


def _warn_unreliable(table: ParameterTable) -> None:
    """A :class:`BrdfcorrWarning` naming the fitted classes whose fit flagged its own errors
    unreliable (the ``fit:`` block's ``errors_reliable: false``; ``docs/uncertainty.md``): their
    1-sigma is propagated all the same, and is rough."""
    flagged = [entry for entry in table.classes if entry.fit is not None and entry.fit.errors_reliable is False]
    if flagged:
        warnings.warn(
            f"the fit flagged the errors of {', '.join(entry.label for entry in flagged)} unreliable (the reason is "
            "the fit: block's errors_reason): their uncertainty is rough",
            BrdfcorrWarning, stacklevel=3,
        )


def _with_materials(resolved: Mapping[int, BandParameters], table: ParameterTable) -> dict[int, BandParameters]:
    """The resolved classes, library materials without a fit given their published errors."""
    materials = {entry.id: entry.material for entry in table.classes if entry.material and entry.fit is None}
    return {class_id: material_covariance(entry, materials[class_id])
            if entry.covariance is None and class_id in materials else entry
            for class_id, entry in resolved.items()}


# ---------------------------------------------------------------------------------- class plans
@dataclass(frozen=True)
class _ClassPlan:
    """One class's model, band parameters and covariance, arranged for evaluation in blocks.

    ``shapes`` are the distinct sets of shape parameters; band ``b`` uses ``shapes[shape_of_band[b]]``
    with the coefficients ``coefficients[b]`` and the covariance ``covariance[b]`` (over ``names``).
    ``row_of_band[b]`` numbers the distinct (shape, coefficients, covariance) rows, so bands with
    equal rows share one sigma_F.
    """

    id: int
    model: Model
    names: tuple[str, ...]
    shapes: tuple[dict[str, float], ...]
    shape_of_band: np.ndarray
    coefficients: np.ndarray
    covariance: np.ndarray
    row_of_band: np.ndarray


def _plan(entry: BandParameters) -> _ClassPlan | None:
    """The class's plan, or None where it has no covariance (its pixels are nodata)."""
    covariance = entry.covariance
    if covariance is None:
        return None
    model, params = entry.model, entry.params
    names = tuple(entry.covariance_names)
    n_bands = len(next(iter(params.values())))
    unknown = [name for name in names if name not in model.parameter_names]
    if unknown or len(set(names)) != len(names):
        raise ParameterError(
            f"class {entry.id} ({entry.name}): covariance parameters {', '.join(names)} must be distinct "
            f"parameters of {model.name} ({', '.join(model.parameter_names)})"
        )
    bad = entry.no_parameters  # bands passed through uncorrected (NaN parameters): sigma 0 there
    if bad is not None:
        covariance = np.where(bad[:, None, None], 0.0, covariance)
    covariance = _checked_covariance(entry, covariance, names, n_bands)
    plan = class_plan(entry.id, model, params, bad)  # the shapes and coefficients, NaN-free
    rows = np.column_stack([plan.shape_of_band, plan.coefficients, covariance.reshape(n_bands, -1)])
    _, row_of_band = np.unique(rows, axis=0, return_inverse=True)
    row_of_band = row_of_band.reshape(-1) if bad is None else np.where(bad, NO_PARAMETERS, row_of_band.reshape(-1))
    return _ClassPlan(entry.id, model, names, plan.shapes, plan.shape_of_band, plan.coefficients, covariance,
                      row_of_band)


def _checked_covariance(entry: BandParameters, covariance, names: tuple[str, ...], n_bands: int) -> np.ndarray:
    """The covariance as float64 (n_bands, p, p); ParameterError unless each band's is positive
    semi-definite (the table checks that it is finite and symmetric, not this)."""
    covariance = np.asarray(covariance, dtype=np.float64)
    label = f"class {entry.id} ({entry.name})"
    if covariance.shape != (n_bands, len(names), len(names)):
        raise ParameterError(
            f"{label}: covariance has shape {covariance.shape}, expected "
            f"{(n_bands, len(names), len(names))} (bands, parameters, parameters)"
        )
    eigenvalues = np.linalg.eigvalsh(0.5 * (covariance + np.swapaxes(covariance, 1, 2)))  # (n_bands, p)
    scale = np.maximum(np.abs(eigenvalues).max(axis=1), np.finfo(np.float64).tiny)
    # Tolerance: the rounding of a covariance computed as (A^T A)^-1 in float64 and written as text.
    negative = eigenvalues.min(axis=1) < -1e-9 * scale
    if negative.any():
        band = int(np.flatnonzero(negative)[0])
        raise ParameterError(
            f"{label}: fit.covariance at band {band + 1} is not positive semi-definite (eigenvalue "
            f"{eigenvalues[band].min():g}): no covariance matrix; the fit that wrote it is wrong"
        )
    return covariance


# ------------------------------------------------------------------------------------- blocks
def _uncertainty_block(reflectance, band_index, reference_sza, *layers, plans: Plans, settings: BlockSettings):
    """The 1-sigma of the corrected reflectance of one (band, y, x) block (module docstring)."""
    n_bands, ny, nx = reflectance.shape
    cube = reflectance.reshape(n_bands, ny * nx)
    pixels = PixelGeometry.of_block(layers, settings)
    out = np.full(cube.shape, np.nan, dtype=settings.out_dtype)
    usable = pixels.usable & ~pixels.no_class
    bands = np.asarray(band_index).reshape(-1)
    for class_id in present_classes(pixels.classes[usable]):
        plan = plans.get(int(class_id)) if float(class_id).is_integer() else None
        if plan is None:  # unknown class, or no covariance: nodata
            continue
        index = np.flatnonzero(usable & (pixels.classes == class_id))
        observed, ref = pixels.geometries(index, settings.reference, reference_sza)
        sigma = _class_sigma(plan, observed, ref, bands, index.size, settings.limits)
        with np.errstate(invalid="ignore", over="ignore"):
            values = cube[:, index].astype(np.float64)
            values[~np.isfinite(values)] = np.nan  # +-inf reflectance is nodata, like NaN
            out[:, index] = np.abs(values) * sigma  # eq. 3: a negative reflectance (dark water) too
    return out.reshape(n_bands, ny, nx)


def _class_sigma(plan: _ClassPlan, observed, reference, bands, n: int, limits) -> np.ndarray:
    """sigma_F (band, pixel) of one class's pixels for the block's bands; NaN where no valid
    factor or a clipped one."""
    differentiated = [name for name in plan.names if name in plan.model.shape_names]
    linear_columns, shape_columns = _columns(plan.model, plan.names)
    terms: dict[int, _ShapeTerms] = {}
    by_row: dict[int, np.ndarray] = {}
    sigma = np.empty((bands.size, n))
    for position, band in enumerate(bands):
        row = int(plan.row_of_band[band])
        if row == NO_PARAMETERS:  # passed through uncorrected: no uncertainty added
            sigma[position] = 0.0
            continue
        if row not in by_row:
            shape = int(plan.shape_of_band[band])
            if shape not in terms:
                terms[shape] = _shape_terms(plan.model, observed, reference, plan.shapes[shape], differentiated, n)
            factor, jacobian = _factor_and_jacobian(
                terms[shape], plan.coefficients[band], linear_columns, shape_columns, len(plan.names)
            )
            with np.errstate(invalid="ignore"):
                by_row[row] = _propagate(jacobian, plan.covariance[band])
                if limits is not None:  # NaN compares False: an invalid factor stays NaN below
                    by_row[row][(factor < limits[0]) | (factor > limits[1])] = np.nan
                by_row[row][np.isnan(factor)] = np.nan
        sigma[position] = by_row[row]
    return sigma


# ---------------------------------------------------------------------------------- public API
def correction_uncertainty(
    reflectance,
    classes,
    angles,
    params: ParameterTable | str | os.PathLike,
    reference: ReferenceGeometry | dict | None = None,
    *,
    wavelengths: Sequence[float] | None = None,
    extrapolate: bool = False,
    flip_view_azimuth: bool = False,
    limits: tuple[float, float] | None = DEFAULT_LIMITS,
) -> xr.DataArray:
    """The per-pixel 1-sigma of the BRDF-corrected reflectance from the fit's parameter covariance.

    ``sigma = |observed| * sqrt(J Sigma J^T)`` with ``J = dF/dp`` of the correction factor
    ``F = f(ref; p) / f(obs; p)`` over the parameters of the class's covariance Sigma (module
    docstring, eqs. 1-5; ``docs/uncertainty.md``). Takes the arguments of
    :func:`brdfcorr.correction.normalize` (give the same ones) and is its companion: lazy and chunked
    the same way, so both can be computed in one pass.

    Parameters
    ----------
    reflectance : xarray.DataArray (band, y, x) or (time, band, y, x)
        Observed reflectance (any units; the result has them). numpy or dask backed. A cube with
        a time dimension first gives one 1-sigma per date, as :func:`normalize` corrects it.
    classes : xarray.DataArray (y, x)
        Class map: ids of ``params``; 0, NaN and the map's nodata mean "no class".
    angles : xarray.Dataset or mapping of str to xarray.DataArray (y, x)
        ``sza``, ``saa``, ``vza``, ``vaa`` per pixel [deg] (``docs/conventions.md``) and, for tilted
        surfaces, ``slope`` and ``aspect`` [deg], as for :func:`normalize`: the observed geometry is
        then taken in each surface's own frame (:func:`brdfcorr.correction.terrain.local_angles`),
        the reference in the horizontal frame; pixels whose sun or sensor is behind the surface (or
        with an invalid slope) are NaN.
    params : ParameterTable, path-like or str
        Model, parameters and (per class, optionally) the fit's covariance (its ``fit:`` block): a
        table, a YAML file of one, or a built-in coefficient set's name, as for :func:`normalize`.
    reference : ReferenceGeometry or dict, optional
        Target geometry as for :func:`normalize`: ``sza`` [deg], ``"mean"`` or ``"observed"``,
        ``vza`` [deg], ``raa`` [deg]; defaults to the table's, else observed sun and nadir view.
    wavelengths : sequence of float, optional
        Band centres [nm]; by default the reflectance's ``wavelength`` coordinate, if any.
    extrapolate : bool, default False
        Let band centres outside a class's table wavelengths take the edge values.
    flip_view_azimuth : bool, default False
        Add 180 deg to ``vaa`` (view azimuth stored as seen from the sensor).
    limits : (float, float) or None, default (0.2, 5)
        The factor limits [-] of the correction: where the factor is clipped, the result is NaN.

    Returns
    -------
    xarray.DataArray (band, y, x)
        The 1-sigma [units of the reflectance] with the reflectance's dims, coords (``spatial_ref``
        included) and chunks; NaN where the class has no covariance (a library material has its
        published errors, :func:`material_covariance`), the pixel has no class or an
        unknown one, invalid data or geometry, no valid factor, or a clipped one. Lazy if any input
        is dask-backed (one task per reflectance chunk). attrs: ``long_name``, ``units``,
        ``description`` (the method), ``brdf_reference``, ``brdf_limits``.

    Raises
    ------
    ParameterError
        The table cannot be resolved to the bands, or a covariance does not fit its class's model.
    GridMismatchError, InputError
        A layer is not on the reflectance's grid, has the wrong dimensions, or an option is invalid.
    """
    if is_series(reflectance):  # (time, band, y, x): date by date, as normalize (correction.series)
        return over_dates(correction_uncertainty, reflectance, classes, angles, params, reference,
                          wavelengths=wavelengths, extrapolate=extrapolate, flip_view_azimuth=flip_view_azimuth,
                          limits=limits)
    params = as_parameter_table(params)
    inputs = prepare_inputs(reflectance, classes, angles, params, reference, limits=limits, wavelengths=wavelengths,
                            extrapolate=extrapolate, flip_view_azimuth=flip_view_azimuth)
    reflectance, reference, limits = inputs.reflectance, inputs.settings.reference, inputs.settings.limits
    resolved = _with_materials(inputs.resolved, params)
    _warn_unreliable(params)
    plans = Plans({class_id: _plan(entry) for class_id, entry in resolved.items()})
    kwargs: dict[str, Any] = dict(plans=plans, settings=inputs.settings)
    sigma = inputs.blockwise(_uncertainty_block, kwargs) if inputs.lazy else inputs.apply(_uncertainty_block, kwargs)
    attrs = {
        "long_name": "1-sigma uncertainty of the BRDF-corrected reflectance",
        "units": str(reflectance.attrs.get("units", "1")),
        "description": METHOD,
        "brdf_reference": reference.describe(),
        "brdf_limits": describe_limits(limits),
    }
    name = f"{reflectance.name}_uncertainty" if reflectance.name else "uncertainty"
    return xr.DataArray(sigma, dims=reflectance.dims, coords=reflectance.coords, attrs=attrs, name=name)
