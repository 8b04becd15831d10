"""BRDF normalization of reflectance cubes to a reference sun/view geometry (lazy, chunked).

For a pixel of class c observed at sun zenith theta_i, view zenith theta_r and relative azimuth phi,
with the class's model f_c and per-band parameters p_c(lambda) (``docs/conventions.md``, "The correction")::

    corrected(lambda) = observed(lambda) * clip(f_c(ref; p_c(lambda)) / f_c(obs; p_c(lambda)), limits)

The geometry of each pixel (relative azimuth, facet inclination, local incidence, cosines) is
computed once and shared by all bands; each class's model is evaluated only at that class's pixels.
Bands whose parameters are equal share one factor map, so with band-independent parameters the
per-band cost is the bare multiplication; with spectral tables the basis functions are evaluated once
per shape and only their linear combination (``t0 + t1 g``; ``f_iso + f_vol K_vol + f_geo K_geo``)
is re-evaluated per band.

With dask-backed inputs the result is lazy (one task per reflectance chunk, no computation until
asked) and its chunks are those of the reflectance.

The QA layer: :mod:`brdfcorr.correction.qa`.

Bad bands: a class without parameters in some bands (``bad_bands`` of its table entry, written by
``fit-classes`` for the water-vapour bands and those the ENVI header's ``bbl`` marks bad;
:attr:`brdfcorr.params.BandParameters.no_parameters`) gets the factor 1 there: those bands of its
pixels are the input, bit for bit, and the pixels are flagged ``band_uncorrected``.

Tilted surfaces (``slope``/``aspect`` given, :mod:`brdfcorr.terrain`): the observed geometry is
evaluated in the frame of the tilted surface (:func:`brdfcorr.terrain.local_angles`), the reference
geometry in the horizontal frame (reference sza ``"observed"`` is the pixel's horizontal sza), so
a tilted surface is normalized to how a horizontal one of the same material would look. The factor
is the BRDF ratio only; the illumination term cos i / cos sza is the topographic step's
(:func:`brdfcorr.topographic.topographic_correction` with ``method="cosine"``; ``docs/terrain.md``).
A slope of 0 gives bit for bit the result without slope and aspect.

A factor is valid when it is a finite positive number: the model predicts a positive finite signal
at both geometries and their ratio neither overflows nor underflows. Otherwise (a kernel-driven
model with negative coefficients predicting none or a negative one, a peak underflowing to 0 at
the reference, extreme parameters overflowing the output precision) the pixel is nodata (NaN) in
that band and flagged ``nodata``, never ``limited`` and never counted as corrected: a wrong number
delivered silently is worse than none. The one exception is a model predicting no signal at either
geometry (0 / 0): the pixel is left unchanged (factor 1). The registry's parameter bounds
(:data:`brdfcorr.models._base.MAX_INTENSITY`) keep every model itself finite.
"""
from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any, Literal, NamedTuple

import numpy as np
import xarray as xr

from brdfcorr.correction.blocks import (
    NO_PARAMETERS,
    ClassPlan,
    PixelGeometry,
    Plans,
    class_plan,
    cube_masks,
    present_classes,
    split_pairs,
)
from brdfcorr.correction.continuous import group_states, ndvi_group, with_ndvi_layer
from brdfcorr.correction.inputs import BlockSettings, prepare_inputs
from brdfcorr.correction.qa import QA, qa_attrs, set_flags
from brdfcorr.correction.reference import describe_limits
from brdfcorr.correction.series import is_series, over_dates
from brdfcorr.defaults import DEFAULT_LIMITS, UNKNOWN_PIXELS
from brdfcorr.errors import BrdfcorrWarning, InputError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.params import ParameterTable, ReferenceGeometry, as_parameter_table

__all__ = ["normalize", "Normalized"]


class Normalized(NamedTuple):
    """Result of :func:`normalize`: the corrected cube and its QA layer (both DataArrays)."""

    reflectance: xr.DataArray
    qa: xr.DataArray


def normalize(
    reflectance,
    classes,
    angles,
    params: ParameterTable | str | os.PathLike,
    reference: ReferenceGeometry | dict | None = None,
    *,
    limits: tuple[float, float] | None = DEFAULT_LIMITS,
    wavelengths: Sequence[float] | None = None,
    extrapolate: bool = False,
    unknown: Literal["keep", "nan"] = "keep",
    flip_view_azimuth: bool = False,
) -> Normalized:
    """Normalize a reflectance cube to a reference sun/view geometry with per-class BRDF models.

    Parameters
    ----------
    reflectance : xarray.DataArray (band, y, x) or (time, band, y, x)
        Reflectance (floats in any units; they are kept). NaN and +-inf are nodata (NaN in the
        output). numpy or dask backed. Integer counts need their ``scale_factor`` (and
        ``add_offset``) in attrs or encoding, as rioxarray reads them without ``mask_and_scale``:
        they are corrected as ``counts * scale_factor + add_offset`` (refused without). A cube with
        a time dimension first is normalized date by date (:mod:`brdfcorr.correction.series`),
        lazily for dask; its class map and angle layers are (y, x) or (time, y, x). Bands last,
        (y, x, band), is refused with the transpose that fixes it.
    classes : xarray.DataArray (y, x), or None
        Class map: ids of ``params``; 0, NaN and the map's nodata (``classes.rio.nodata``, else its
        ``_FillValue``) mean "no class". None: class 1 everywhere (for a one-class table, e.g. a
        built-in coefficient set). A map on another grid is refused
        (:func:`brdfcorr.strata.align_class_map` brings it onto the reflectance's).
    angles : xarray.Dataset or mapping of str to xarray.DataArray (y, x)
        ``sza``, ``saa``, ``vza``, ``vaa``: solar zenith, solar azimuth, view zenith, view azimuth
        per pixel [deg] (``docs/conventions.md`` conventions: azimuths of the directions from the
        pixel towards the sun and the sensor). For tilted surfaces also ``slope`` [deg] in [0, 90]
        and ``aspect``, the azimuth the surface faces (downslope, clockwise from north) [deg], both
        or neither (:func:`brdfcorr.correction.terrain.slope_aspect` from a DEM, or
        :func:`brdfcorr.io.sensors.envi.read_envi_obs_terrain`): the observed geometry is then
        evaluated in each surface's own frame, the reference in the horizontal frame (module
        docstring, "Tilted surfaces"); pixels whose sun or sensor is behind the surface are nodata,
        flagged ``facing_away``. Slope 0 gives exactly the result without them. Layers that can
        only be radians (every zenith below 1.6, every azimuth below 6.3) are refused (for dask
        input when the chunks are computed).
    params : ParameterTable, path-like or str
        Model and parameters per class: a table, a YAML file of one, or the name of a built-in
        coefficient set (``"roy2017"``, :mod:`brdfcorr.models.coefficients`) as class 1.
    reference : ReferenceGeometry or dict, optional
        Target geometry: ``sza`` [deg] or ``"mean"`` (scene mean of the valid ``sza``) or
        ``"observed"``, ``vza`` [deg] and ``raa`` [deg]. Defaults to the table's reference, else
        ``ReferenceGeometry()`` (observed sun, nadir view).
    limits : (float, float) or None, default (0.2, 5)
        The factor f(ref)/f(obs) is clipped to this range [-]; clipped pixels are flagged.
    wavelengths : sequence of float, optional
        Band centres [nm]; by default the reflectance's ``wavelength`` coordinate, if any.
    extrapolate : bool, default False
        Let band centres outside a class's table wavelengths take the edge values.
    unknown : {"keep", "nan"}, default "keep"
        What to do with pixels of no class or of ids absent from the table: keep them unchanged
        (factor 1) or set them to NaN. They are flagged in the QA layer either way.
    flip_view_azimuth : bool, default False
        Add 180 deg to ``vaa``, for products storing the azimuth of the view direction as seen from
        the sensor.

    Returns
    -------
    Normalized
        ``(reflectance, qa)``: the corrected cube with the input's dims, coords (including the
        ``spatial_ref`` georeference), attrs and chunks, and the QA layer (y, x) of uint8 flags
        ((time, y, x) for a cube with time)
        (module docstring). Lazy if any input is dask-backed.

    Raises
    ------
    ParameterError
        The table cannot be resolved to the bands (names the class and parameter).
    GridMismatchError, InputError
        A layer is not on the reflectance's grid, or has the wrong dimensions; the reflectance has
        its bands last or holds integer counts without a scale; the angles look like radians.

    Notes
    -----
    ``corrected = observed * f(ref) / f(obs)`` (``docs/conventions.md``, "The correction"), the factor evaluated
    with the model of the pixel's class (paper 003 eq. 1, paper 000 eq. 5) at the pixel's geometry.
    """
    if unknown not in UNKNOWN_PIXELS:
        raise InputError(f"unknown must be 'keep' or 'nan', got {unknown!r}")
    params = as_parameter_table(params)
    if is_series(reflectance):  # (time, band, y, x): date by date (correction.series)
        return over_dates(normalize, reflectance, classes, angles, params, reference,
                          limits=limits, wavelengths=wavelengths, extrapolate=extrapolate, unknown=unknown,
                          flip_view_azimuth=flip_view_azimuth)
    inputs = prepare_inputs(reflectance, classes, angles, params, reference, limits=limits, wavelengths=wavelengths,
                            extrapolate=extrapolate, flip_view_azimuth=flip_view_azimuth)
    group = ndvi_group(params, inputs.resolved)  # coefficients continuous in NDVI (correction.continuous)
    if group is not None:
        inputs, group = with_ndvi_layer(inputs, group, wavelengths)
        group = _passing_bad_bands(group, inputs.resolved)
    reflectance, reference, limits = inputs.reflectance, inputs.settings.reference, inputs.settings.limits
    band_dim = reflectance.dims[0]
    class_plans = {cid: class_plan(cid, entry.model, entry.params, entry.no_parameters)
                   for cid, entry in inputs.resolved.items()}
    plans = Plans(class_plans)
    if group is None:  # coefficients continuous in NDVI: the reference value depends on the pixel
        check_reference_signal(class_plans, reference)
    kwargs: dict[str, Any] = dict(plans=plans, settings=inputs.settings, unknown_nan=unknown == "nan", group=group)
    if inputs.lazy:
        pairs = inputs.blockwise(_normalize_block, kwargs)
        corrected, qa = split_pairs(pairs, inputs.settings.out_dtype)
    else:
        corrected, qa = inputs.apply(_normalize_block, kwargs)
        qa = qa[0]

    attrs = dict(reflectance.attrs)
    attrs.update(brdf_reference=reference.describe(), brdf_limits=describe_limits(limits))
    corrected = xr.DataArray(
        corrected, dims=reflectance.dims, coords=reflectance.coords, attrs=attrs, name=reflectance.name
    )
    spatial_coords = {k: v for k, v in reflectance.coords.items() if band_dim not in v.dims}
    qa = xr.DataArray(
        qa, dims=reflectance.dims[1:], coords=spatial_coords, name="qa",
        attrs=qa_attrs("BRDF normalization quality flags"),
    )
    return Normalized(corrected, qa)


def check_reference_signal(plans: Mapping[int, ClassPlan | None], reference: ReferenceGeometry) -> None:
    """Refuse a fixed reference geometry at which no class's model predicts a positive reflectance
    in any band: every factor f(ref) / f(obs) would be invalid and every pixel nodata (an all-NaN
    output with exit 0 before; a kernel model at a sun zenith near 90 deg goes negative). One class
    and band with a positive value ends the search (the first, as a rule): cheap for any table.
    A table whose ``bad_bands`` leave no band with parameters in any class corrects nothing: a
    :class:`~brdfcorr.errors.BrdfcorrWarning` says so (the output is the input).

    Raises
    ------
    InputError
        Naming the reference geometry and the value of the first class and band.
    """
    if all(plan is None or (plan.row_of_band == NO_PARAMETERS).all() for plan in plans.values()):
        if plans:  # a table that corrects no band: the image passes through as it is
            warnings.warn(f"the bad_bands of every class ({', '.join(map(str, list(plans)[:5]))}"
                          f"{', ...' if len(plans) > 5 else ''}) cover every band of the image: no band is "
                          "corrected, the output is the input", BrdfcorrWarning, stacklevel=3)
        return
    if isinstance(reference.sza, str):  # "observed": the reference is each pixel's own sun
        return
    where = ScatteringGeometry(np.float64(reference.sza), np.float64(reference.vza), np.float64(reference.raa))
    first = None
    for class_id, plan in plans.items():
        values = [] if plan is None else _reference_values(plan, where)
        if not values or any(np.isfinite(value) and value > 0 for value in values):
            return
        first = first or (class_id, values[0])
    if first is not None:
        raise InputError(f"reference geometry {reference.describe()}: no class's model predicts a positive reflectance "
                         f"there in any band (class {first[0]}: f = {first[1]:.4g} sr^-1), so no pixel could be "
                         "corrected; choose a reference geometry nearer the observations")


def _reference_values(plan: ClassPlan, where: ScatteringGeometry) -> list[float]:
    """f at ``where`` [sr^-1] in each band in which ``plan``'s class has parameters."""
    with np.errstate(all="ignore"):
        terms = [np.array([float(np.asarray(term)) for term in plan.model.terms(where, shape)])
                 for shape in plan.shapes]
        return [float(np.dot(plan.coefficients[band], terms[plan.shape_of_band[band]]))
                for band in range(len(plan.row_of_band)) if plan.row_of_band[band] != NO_PARAMETERS]


def _passing_bad_bands(group, resolved):
    """The NDVI group with the bands in which one of its classes has no parameters (``bad_bands``)
    passed through (:data:`NO_PARAMETERS`), as each class alone would be."""
    if group is None:
        return None
    masks = [resolved[int(class_id)].no_parameters for class_id in group.ids]
    masks = [mask for mask in masks if mask is not None]
    if not masks:
        return group
    return dataclasses.replace(group, row_of_band=np.where(np.logical_or.reduce(masks), NO_PARAMETERS,
                                                           group.row_of_band))


def _normalize_block(reflectance, band_index, reference_sza, *layers, plans: Plans, settings: BlockSettings,
                     unknown_nan: bool, group=None):
    """Normalize one (band, y, x) block; returns (corrected block, QA block of shape (1, y, x))."""
    n_bands, ny, nx = reflectance.shape
    if group is not None:  # the NDVI layer comes last (correction.continuous.with_ndvi_layer)
        layers, index_layer = layers[:-1], layers[-1]
    cube = reflectance.reshape(n_bands, ny * nx)
    reference, limits, out_dtype = settings.reference, settings.limits, settings.out_dtype
    pixels = PixelGeometry.of_block(layers, settings)
    classes, qa, usable, no_class = pixels.classes, pixels.qa, pixels.usable, pixels.no_class
    cube_masks(cube, qa)
    base = np.ones(ny * nx, dtype=out_dtype)  # factor of pixels no class corrects
    base[~usable] = np.nan
    unclassified = usable & no_class
    set_flags(qa, unclassified, QA.NO_CLASS)
    if unknown_nan:
        base[unclassified] = np.nan
    states = []
    for class_id in present_classes(classes[usable & ~no_class]):
        if group is not None and group.holds(class_id):
            continue  # corrected with coefficients continuous in NDVI, below
        members = usable & (classes == class_id)
        plan = plans.get(int(class_id)) if float(class_id).is_integer() else None
        if plan is None:
            set_flags(qa, members, QA.UNKNOWN_CLASS)
            if unknown_nan:
                base[members] = np.nan
            continue
        index = np.flatnonzero(members)
        observed, ref = pixels.geometries(index, reference, reference_sza)
        # The basis functions in float64; the per-band linear combination in the output precision.
        # Parameters were validated when the table was resolved to the bands. A term beyond the
        # output precision becomes inf, and its pixels nodata (_ratio).
        with np.errstate(over="ignore"):
            terms = [
                tuple(
                    tuple(np.broadcast_to(np.asarray(t, dtype=out_dtype), index.shape)
                          for t in plan.model.terms(where, shape))
                    for where in (observed, ref)
                )
                for shape in plan.shapes
            ]
        states.append((plan, index, terms))
    if group is not None:
        states += group_states(group, pixels, index_layer, reference, reference_sza, out_dtype)

    out, flags = _apply_factors(cube, band_index, base, states, limits, out_dtype)
    _infinite_as_nodata(out, qa)
    for index, limited, invalid, passed in flags:
        set_flags(qa, index[limited], QA.LIMITED)
        set_flags(qa, index[invalid], QA.NODATA)
        if passed:  # a band of this block without parameters for the class: passed through
            set_flags(qa, index, QA.BAND_UNCORRECTED)
    return out.reshape(n_bands, ny, nx), qa.reshape(1, ny, nx)


def _infinite_as_nodata(out: np.ndarray, qa: np.ndarray) -> None:
    """+-inf in the corrected values (band, pixel) as NaN and the pixel flagged ``nodata``, in
    place: +-inf reflectance is nodata like NaN, and so is a product beyond the output's precision
    (3.3e38 x 1.04). The few pixels whose band sum is not finite are looked at (one pass)."""
    with np.errstate(over="ignore", invalid="ignore"):
        suspect = np.flatnonzero(~np.isfinite(np.add.reduce(out, axis=0)))
    if suspect.size:
        values = out[:, suspect]
        infinite = np.isinf(values)
        out[:, suspect] = np.where(infinite, np.nan, values)
        set_flags(qa, suspect[infinite.any(axis=0)], QA.NODATA)


def _apply_factors(cube, band_index, base, states, limits, out_dtype):
    """Multiply each band by its factor map; returns the output and, per class, its pixel indices,
    which of them were limited in some band, which had no valid factor (NaN) in some band, and
    whether a band without parameters for the class (:data:`NO_PARAMETERS`) was passed through.

    One factor map serves the block, updated band by band only where a class's parameters change:
    with band-independent parameters every band costs one multiplication. A band without
    parameters gets the factor 1: the output is the input, bit for bit.
    """
    factor = base
    current_row = {plan.id: -1 for plan, _, _ in states}
    limited = {plan.id: np.zeros(index.size, dtype=bool) for plan, index, _ in states}
    invalid = {plan.id: np.zeros(index.size, dtype=bool) for plan, index, _ in states}
    passed = dict.fromkeys(current_row, False)
    out = np.empty(cube.shape, dtype=out_dtype)
    for position, band in enumerate(np.asarray(band_index).reshape(-1)):
        for plan, index, terms in states:
            if plan.row_of_band[band] == current_row[plan.id]:
                continue
            current_row[plan.id] = plan.row_of_band[band]
            if current_row[plan.id] == NO_PARAMETERS:
                factor[index], passed[plan.id] = 1.0, True
                continue
            ratio = _ratio(plan, band, *terms[plan.shape_of_band[band]])
            invalid[plan.id] |= np.isnan(ratio)
            if limits is not None:
                # NaN compares False: a pixel without a valid factor is nodata, not limited.
                limited[plan.id] |= (ratio < limits[0]) | (ratio > limits[1])
                ratio = np.clip(ratio, *limits)
            factor[index] = ratio
        with np.errstate(over="ignore"):  # a product beyond the precision: inf, made nodata by the caller
            np.multiply(cube[position], factor, out=out[position], casting="unsafe")
    return out, [(index, limited[plan.id], invalid[plan.id], passed[plan.id]) for plan, index, _ in states]


def _ratio(plan: ClassPlan, band: int, terms_observed: tuple, terms_reference: tuple) -> np.ndarray:
    """f(ref) / f(obs) at a class's pixels for one band (a new array in the terms' precision).

    Only a finite positive ratio with f(obs) > 0 is a factor; anything else is NaN (the pixel is
    nodata in that band and flagged ``nodata``, module docstring): no signal or a negative one
    at a geometry (a kernel-driven model with negative coefficients can predict that), a peak
    underflowing to 0, a value or ratio beyond the terms' precision. Where the model predicts no
    signal at either geometry (0 / 0) the pixel is left unchanged (ratio 1).
    """
    coefficients = plan.band_coefficients(band)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        f_observed = sum(c * term for c, term in zip(coefficients, terms_observed))
        f_reference = sum(c * term for c, term in zip(coefficients, terms_reference))
        ratio = f_reference / f_observed
    # NaN compares False, so NaN, +-inf, 0 and negative ratios and f(obs) <= 0 are all invalid.
    invalid = ~((f_observed > 0) & (ratio > 0) & (ratio < np.inf))
    if invalid.any():
        ratio[invalid] = np.where((f_observed[invalid] == 0) & (f_reference[invalid] == 0), 1.0, np.nan)
    return ratio


