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

QA layer (uint8 bit flags, CF ``flag_masks``/``flag_meanings`` in its attrs):

==== ================ ========================================================================
bit  name             meaning
==== ================ ========================================================================
1    nodata           nodata (NaN or +-inf) in some band or an angle, or no valid factor in some
                      band (below); output is nodata (in those bands)
2    no_class         class 0 or the class map's nodata ("no class"): not corrected (factor 1,
                      or NaN on request)
4    unknown_class    class id absent from the parameter table: not corrected (1, or NaN)
8    limited          the factor was clipped to the limits in at least one band
16   invalid_geometry a zenith outside [0, 90) deg, or a slope outside [0, 90] deg: output is nodata
32   facing_away      with slope and aspect: the sun or the sensor is at or below the tilted
                      surface's horizon (local zenith >= 90 deg): output is nodata
64   topography_      with a topographic step before the correction
     uncorrected      (:func:`brdfcorr.workflow.correction.correct_files`): the C fit of the pixel's
                      class was rejected in some band, which was not corrected for illumination
==== ================ ========================================================================

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

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any, Literal, NamedTuple

import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import GridMismatchError, InputError
from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.models import Model
from brdfcorr.params import ParameterTable, ReferenceGeometry
from brdfcorr.terrain import local_angles

__all__ = [
    "normalize",
    "Normalized",
    "ReferenceGeometry",
    "QA_NODATA",
    "QA_NO_CLASS",
    "QA_UNKNOWN_CLASS",
    "QA_LIMITED",
    "QA_INVALID_GEOMETRY",
    "QA_FACING_AWAY",
    "QA_TOPOGRAPHY_UNCORRECTED",
    "QA_FLAGS",
    "qa_counts",
]

QA_NODATA = np.uint8(1)
QA_NO_CLASS = np.uint8(2)
QA_UNKNOWN_CLASS = np.uint8(4)
QA_LIMITED = np.uint8(8)
QA_INVALID_GEOMETRY = np.uint8(16)
QA_FACING_AWAY = np.uint8(32)
QA_TOPOGRAPHY_UNCORRECTED = np.uint8(64)
QA_FLAGS = {
    "nodata": QA_NODATA,
    "no_class": QA_NO_CLASS,
    "unknown_class": QA_UNKNOWN_CLASS,
    "limited": QA_LIMITED,
    "invalid_geometry": QA_INVALID_GEOMETRY,
    "facing_away": QA_FACING_AWAY,
    "topography_uncorrected": QA_TOPOGRAPHY_UNCORRECTED,
}

class Normalized(NamedTuple):
    """Result of :func:`normalize`: the corrected cube and its QA layer (both DataArrays)."""

    reflectance: xr.DataArray
    qa: xr.DataArray


@dataclass(frozen=True)
class _ClassPlan:
    """One class's model and band parameters, arranged for evaluation in blocks.

    The model is ``f = sum_j c_j B_j(geometry; shape)`` over its linear parameters
    (:attr:`Model.linear`). ``shapes`` are the distinct sets of shape parameters; band ``b`` uses the
    basis of ``shapes[shape_of_band[b]]`` with the coefficients ``coefficients[b]``.
    ``row_of_band[b]`` numbers the distinct (shape, coefficients) rows, so bands with equal rows
    share one factor.
    """

    id: int
    model: Model
    shapes: tuple[dict[str, float], ...]
    shape_of_band: np.ndarray
    coefficients: np.ndarray
    row_of_band: np.ndarray


def band_shapes(model: Model, params: Mapping[str, np.ndarray]):
    """A class's per-band parameters split for evaluation: the distinct sets of shape parameters
    (``shapes``), which of them each band uses (``shape_of_band``) and the linear coefficients
    (n_bands, n_linear), in :attr:`Model.linear` order."""
    n_bands = len(next(iter(params.values())))
    coefficients = np.stack([params[name] for name in model.linear], axis=1)
    shape_names = model.shape_names
    shape_matrix = np.stack([params[name] for name in shape_names], axis=1) if shape_names else np.zeros((n_bands, 0))
    unique_shapes, shape_of_band = np.unique(shape_matrix, axis=0, return_inverse=True)
    shapes = tuple(dict(zip(shape_names, map(float, row))) for row in unique_shapes)
    return shapes, shape_of_band.reshape(-1), coefficients


def _plan(class_id: int, model: Model, params: dict[str, np.ndarray]) -> _ClassPlan:
    shapes, shape_of_band, coefficients = band_shapes(model, params)
    _, row_of_band = np.unique(np.column_stack([shape_of_band, coefficients]), axis=0, return_inverse=True)
    return _ClassPlan(class_id, model, shapes, shape_of_band, coefficients, row_of_band.reshape(-1))


class Plans:
    """Per-class plans (dataclasses; None for a class with nothing to do) as one opaque block
    argument: dask would otherwise walk and hash every plan to build the graph (20 000 classes:
    20 s). Its token is a digest of the plans' fields."""

    def __init__(self, plans: Mapping[int, Any]):
        self._plans = dict(plans)
        digest = hashlib.sha256()
        for class_id, plan in self._plans.items():
            digest.update(f"{class_id}|".encode())
            for item in fields(plan) if plan is not None else ():
                value = getattr(plan, item.name)
                if isinstance(value, np.ndarray):
                    digest.update(f"{value.dtype}{value.shape}".encode())
                    digest.update(np.ascontiguousarray(value).tobytes())
                else:
                    digest.update(f"{value.name if isinstance(value, Model) else value!r}|".encode())
        self._token = digest.hexdigest()

    def get(self, class_id: int):
        return self._plans.get(class_id)

    def __dask_tokenize__(self) -> str:
        return self._token


def _normalize_block(
    reflectance, band_index, classes, sza, saa, vza, vaa, reference_sza, slope=None, aspect=None, *,
    plans: Plans, reference: ReferenceGeometry, limits, unknown_nan: bool,
    class_nodata, flip_view_azimuth: bool, out_dtype,
):
    """Normalize one (band, y, x) block; returns (corrected block, QA block of shape (1, y, x))."""
    n_bands, ny, nx = reflectance.shape
    cube = reflectance.reshape(n_bands, ny * nx)
    pixels = PixelGeometry.of_block(classes, sza, saa, vza, vaa, slope, aspect, class_nodata=class_nodata,
                                    flip_view_azimuth=flip_view_azimuth)
    classes, qa, usable, no_class = pixels.classes, pixels.qa, pixels.usable, pixels.no_class
    candidates, infinite = _cube_masks(cube, qa)
    base = np.ones(ny * nx, dtype=out_dtype)  # factor of pixels no class corrects
    base[~usable] = np.nan
    unclassified = usable & no_class
    qa[unclassified] |= QA_NO_CLASS
    if unknown_nan:
        base[unclassified] = np.nan
    states = []
    for class_id in _present_classes(classes[usable & ~no_class]):
        members = usable & (classes == class_id)
        plan = plans.get(int(class_id)) if float(class_id).is_integer() else None
        if plan is None:
            qa[members] |= QA_UNKNOWN_CLASS
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

    out, flags = _apply_factors(cube, band_index, base, states, limits, out_dtype)
    if infinite is not None and infinite.any():  # +-inf is nodata like NaN: NaN in the output
        corrected = out[:, candidates]
        corrected[infinite] = np.nan
        out[:, candidates] = corrected
    for index, limited, invalid in flags:
        qa[index[limited]] |= QA_LIMITED
        qa[index[invalid]] |= QA_NODATA
    return out.reshape(n_bands, ny, nx), qa.reshape(1, ny, nx)


def no_class_mask(classes: np.ndarray, class_nodata) -> np.ndarray:
    """Where a class map says "no class": 0, NaN or its nodata value (docs/conventions.md)."""
    no_class = classes == 0
    if classes.dtype.kind == "f":
        no_class |= np.isnan(classes)
    if class_nodata is not None:
        no_class |= classes == class_nodata
    return no_class


@dataclass(frozen=True)
class PixelGeometry:
    """A block's pixels (flattened) as the correction and its uncertainty see them.

    ``qa`` holds the geometry's flags (nodata angles, invalid geometry, a surface facing away),
    ``usable`` the pixels with a valid geometry, ``no_class`` those of class 0, NaN or the class
    map's nodata, ``angles`` (sza, saa, vza, vaa) the observed geometry: in each tilted surface's
    frame where slope and aspect are given, else horizontal; ``theta_i`` the horizontal sun zenith.
    """

    classes: np.ndarray
    qa: np.ndarray
    usable: np.ndarray
    no_class: np.ndarray
    theta_i: np.ndarray
    angles: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]

    @classmethod
    def of_block(cls, classes, sza, saa, vza, vaa, slope=None, aspect=None, *, class_nodata,
                 flip_view_azimuth: bool) -> PixelGeometry:
        classes = np.asarray(classes).reshape(-1)
        theta_i, theta_r, saa, vaa = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (sza, vza, saa, vaa))
        if flip_view_azimuth:
            vaa = vaa + 180.0
        angles_finite = np.isfinite(theta_i) & np.isfinite(theta_r) & np.isfinite(saa) & np.isfinite(vaa)
        no_class = no_class_mask(classes, class_nodata)
        with np.errstate(invalid="ignore"):
            in_domain = (theta_i >= 0) & (theta_i < 90) & (theta_r >= 0) & (theta_r < 90)
        invalid_geometry = angles_finite & ~in_domain
        qa = np.zeros(classes.size, dtype=np.uint8)
        qa[~angles_finite] |= QA_NODATA
        qa[invalid_geometry] |= QA_INVALID_GEOMETRY
        usable = angles_finite & ~invalid_geometry
        angles = (theta_i, saa, theta_r, vaa)
        if slope is not None:
            angles, usable = _local_frame(qa, usable, angles, slope, aspect)
        return cls(classes, qa, usable, no_class, theta_i, angles)

    def geometries(self, index: np.ndarray, reference: ReferenceGeometry, reference_sza):
        """The observed and the reference geometry of the pixels ``index``. The reference is
        horizontal: ``"observed"`` is each pixel's horizontal sun zenith."""
        sza, saa, vza, vaa = (angle[index] for angle in self.angles)
        observed = ScatteringGeometry(sza, vza, relative_azimuth(saa, vaa))
        ref_sza = self.theta_i[index] if reference.sza == "observed" else np.asarray(reference_sza, dtype=np.float64)
        return observed, ScatteringGeometry(ref_sza, np.float64(reference.vza), np.float64(reference.raa))


def _local_frame(qa, usable, angles, slope, aspect):
    """Sun and view angles in the tilted surfaces' frames (1-D, per pixel) and the usable pixels:
    a slope outside [0, 90] is invalid geometry, non-finite slope or aspect nodata, and a sun or
    sensor at or below the surface's horizon (local zenith >= 90 deg) facing away."""
    slope, aspect = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (slope, aspect))
    finite = np.isfinite(slope) & np.isfinite(aspect)
    with np.errstate(invalid="ignore"):
        bad_slope = finite & ~((slope >= 0) & (slope <= 90))
    qa[~finite] |= QA_NODATA
    qa[bad_slope] |= QA_INVALID_GEOMETRY
    usable = usable & finite & ~bad_slope
    local = local_angles(*angles, np.where(usable, slope, 0.0), np.where(usable, aspect, 0.0))
    with np.errstate(invalid="ignore"):
        away = usable & ((local.sza >= 90) | (local.vza >= 90))
    qa[away] |= QA_FACING_AWAY
    return (local.sza, local.saa, local.vza, local.vaa), usable & ~away


def _cube_masks(cube, qa):
    """Flag pixels with non-finite reflectance in some band (``qa`` in place); returns the few
    pixels with a non-finite band sum (indices) and where in them a value is +-inf."""
    candidates = infinite = None
    if cube.dtype.kind == "f":
        # NaN or +-inf in some band makes the band sum non-finite (one pass, no mask cube); those
        # few pixels are then checked band by band (a sum of finite values may overflow).
        with np.errstate(over="ignore", invalid="ignore"):
            candidates = np.flatnonzero(~np.isfinite(np.add.reduce(cube, axis=0)))
        if candidates.size:
            values = cube[:, candidates]
            qa[candidates[~np.isfinite(values).all(axis=0)]] |= QA_NODATA
            infinite = np.isinf(values)
    return candidates, infinite


def _apply_factors(cube, band_index, base, states, limits, out_dtype):
    """Multiply each band by its factor map; returns the output and, per class, its pixel indices,
    which of them were limited in some band and which had no valid factor (NaN) in some band.

    One factor map serves the block, updated band by band only where a class's parameters change:
    with band-independent parameters every band costs one multiplication.
    """
    factor = base
    current_row = {plan.id: -1 for plan, _, _ in states}
    limited = {plan.id: np.zeros(index.size, dtype=bool) for plan, index, _ in states}
    invalid = {plan.id: np.zeros(index.size, dtype=bool) for plan, index, _ in states}
    out = np.empty(cube.shape, dtype=out_dtype)
    for position, band in enumerate(np.asarray(band_index).reshape(-1)):
        for plan, index, terms in states:
            if plan.row_of_band[band] == current_row[plan.id]:
                continue
            current_row[plan.id] = plan.row_of_band[band]
            ratio = _ratio(plan, band, *terms[plan.shape_of_band[band]])
            invalid[plan.id] |= np.isnan(ratio)
            if limits is not None:
                # NaN compares False: a pixel without a valid factor is nodata, not limited.
                limited[plan.id] |= (ratio < limits[0]) | (ratio > limits[1])
                ratio = np.clip(ratio, *limits)
            factor[index] = ratio
        np.multiply(cube[position], factor, out=out[position], casting="unsafe")
    return out, [(index, limited[plan.id], invalid[plan.id]) for plan, index, _ in states]


def _present_classes(values: np.ndarray) -> list:
    """Distinct class ids in a block (a histogram for small integers, faster than sorting)."""
    if values.size == 0:
        return []
    if values.dtype.kind in "iu" and values.dtype.itemsize <= 2:
        lowest = int(values.min())
        return (np.flatnonzero(np.bincount(values.astype(np.intp) - lowest)) + lowest).tolist()
    return np.unique(values).tolist()


def _ratio(plan: _ClassPlan, band: int, terms_observed: tuple, terms_reference: tuple) -> np.ndarray:
    """f(ref) / f(obs) at a class's pixels for one band (a new array in the terms' precision).

    Only a finite positive ratio with f(obs) > 0 is a factor; anything else is NaN (the pixel is
    nodata in that band and flagged ``nodata``, module docstring): no signal or a negative one
    at a geometry (a kernel-driven model with negative coefficients can predict that), a peak
    underflowing to 0, a value or ratio beyond the terms' precision. Where the model predicts no
    signal at either geometry (0 / 0) the pixel is left unchanged (ratio 1).
    """
    coefficients = [float(c) for c in plan.coefficients[band]]  # Python floats keep the terms' dtype
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        f_observed = sum(c * term for c, term in zip(coefficients, terms_observed))
        f_reference = sum(c * term for c, term in zip(coefficients, terms_reference))
        ratio = f_reference / f_observed
    # NaN compares False, so NaN, +-inf, 0 and negative ratios and f(obs) <= 0 are all invalid.
    invalid = ~((f_observed > 0) & (ratio > 0) & (ratio < np.inf))
    if invalid.any():
        ratio[invalid] = np.where((f_observed[invalid] == 0) & (f_reference[invalid] == 0), 1.0, np.nan)
    return ratio


def _as_dataarray(value, name: str, dims: Sequence[str]) -> xr.DataArray:
    if isinstance(value, xr.DataArray):
        return value
    array = value if isinstance(value, da.Array) else np.asarray(value)
    if array.ndim != len(dims):
        raise InputError(f"{name} must have {len(dims)} dimensions {tuple(dims)}, got shape {array.shape}")
    return xr.DataArray(array, dims=tuple(dims), name=name)


def _check_grid(reflectance: xr.DataArray, name: str, layer: xr.DataArray) -> xr.DataArray:
    """The layer as (y, x) on the reflectance's grid; GridMismatchError naming what differs."""
    spatial = reflectance.dims[1:]
    if layer.ndim == 3 and layer.shape[0] == 1:
        layer = layer.isel({layer.dims[0]: 0}, drop=True)
    if layer.ndim != 2:
        raise InputError(f"{name} must be 2-D (y, x), got dims {layer.dims}")
    if layer.dims != spatial:
        layer = layer.rename(dict(zip(layer.dims, spatial)))
    if layer.shape != reflectance.shape[1:]:
        raise GridMismatchError(
            f"{name} has shape {layer.shape} but the reflectance grid is {reflectance.shape[1:]}"
        )
    for dim in spatial:
        if dim in layer.coords and dim in reflectance.coords:
            if not np.allclose(layer[dim].values, reflectance[dim].values, rtol=0, atol=1e-9 * (
                    1 + np.abs(reflectance[dim].values).max())):
                raise GridMismatchError(f"{name} has other {dim} coordinates than the reflectance")
    layer_crs, grid_crs = _rio_crs(layer), _rio_crs(reflectance)
    if layer_crs is not None and grid_crs is not None and layer_crs != grid_crs:
        raise GridMismatchError(f"{name} has CRS {layer_crs} but the reflectance has {grid_crs}")
    return layer


def _rio_crs(array: xr.DataArray):
    try:
        import rioxarray  # noqa: F401  (registers the .rio accessor)

        return array.rio.crs
    except Exception:  # no readable georeference: nothing to compare
        return None


def resolve_reference(reference, params: ParameterTable) -> ReferenceGeometry:
    """The reference geometry to use: the given one (a dict is validated), else the table's, else
    the default (observed sun zenith, nadir view)."""
    if reference is None:
        return params.reference or ReferenceGeometry()
    if isinstance(reference, ReferenceGeometry):
        return reference
    validated = ParameterTable.from_dict({"reference": dict(reference)}, source="reference geometry").reference
    return validated if validated is not None else ReferenceGeometry()


@dataclass(frozen=True)
class CorrectionInputs:
    """The inputs of a per-pixel correction, checked and resolved once (:func:`prepare_inputs`).

    ``arrays`` holds the data of the reflectance (band, y, x), classes, sza, saa, vza and vaa
    (y, x), ``terrain`` that of slope and aspect (or nothing); ``resolved`` the table at the bands.
    """

    reflectance: xr.DataArray
    arrays: list
    terrain: list
    resolved: dict
    reference: ReferenceGeometry
    limits: tuple[float, float] | None
    class_nodata: float | None
    out_dtype: np.dtype

    @property
    def lazy(self) -> bool:
        return any(isinstance(a, da.Array) for a in self.arrays + self.terrain)

    def apply(self, block_function, kwargs: Mapping[str, Any]):
        """``block_function`` on the whole (numpy) inputs as one block."""
        reference_sza = (
            _scene_mean(self.arrays[2], np) if self.reference.sza == "mean" else _fixed_sza(self.reference)
        )
        cube, *layers = self.arrays
        return block_function(
            cube, np.arange(cube.shape[0]), *layers, reference_sza, *self.terrain, **kwargs
        )

    def blockwise(self, block_function, kwargs: Mapping[str, Any]) -> da.Array:
        """``block_function`` lazily, one task per reflectance chunk (with its chunks); every
        layer is rechunked to the reflectance's spatial chunks. Functions built on the same
        inputs share their dask keys, so computing them together reads each chunk once."""
        reflectance = self.arrays[0]
        if not isinstance(reflectance, da.Array):
            reflectance = da.from_array(reflectance, chunks="auto")
        spatial_chunks = reflectance.chunks[1:]
        layers = [da.asarray(a).rechunk(spatial_chunks) for a in self.arrays[1:]]
        terrain = [da.asarray(a).rechunk(spatial_chunks) for a in self.terrain]
        band_index = da.arange(reflectance.shape[0], chunks=(reflectance.chunks[0],))
        if self.reference.sza == "mean":
            reference_sza = _scene_mean(layers[1], da)
        else:
            reference_sza = da.asarray(_fixed_sza(self.reference))
        return da.blockwise(
            block_function, "byx",
            reflectance, "byx", band_index, "b",
            *(item for layer in layers for item in (layer, "yx")),
            reference_sza, (),
            *(item for layer in terrain for item in (layer, "yx")),
            meta=np.empty((0, 0, 0), dtype=kwargs["out_dtype"]),
            **kwargs,
        )


def prepare_inputs(
    reflectance, classes, sza, saa, vza, vaa, params: ParameterTable, reference=None, *,
    limits: tuple[float, float] | None, wavelengths: Sequence[float] | None, extrapolate: bool,
    class_nodata: float | None, slope=None, aspect=None,
) -> CorrectionInputs:
    """Check the inputs of :func:`normalize` (and of its companions, e.g.
    :func:`brdfcorr.uncertainty.correction_uncertainty`) and resolve the table to the bands.

    Raises InputError, GridMismatchError or ParameterError as documented in :func:`normalize`.
    """
    if not isinstance(params, ParameterTable):
        raise InputError(f"params must be a ParameterTable, got {type(params).__name__}")
    if limits is not None:
        limits = (float(limits[0]), float(limits[1]))
        if not (0 < limits[0] <= 1 <= limits[1] < np.inf):
            raise InputError(f"factor limits {limits} must satisfy 0 < lower <= 1 <= upper < inf")
    reference = resolve_reference(reference, params)
    reflectance = _as_dataarray(reflectance, "reflectance", ("band", "y", "x"))
    if reflectance.ndim != 3:
        raise InputError(f"reflectance must be 3-D (band, y, x), got dims {reflectance.dims}")
    if (slope is None) != (aspect is None):
        raise InputError("slope and aspect go together: give both or neither")
    named = {"classes": classes, "sza": sza, "saa": saa, "vza": vza, "vaa": vaa}
    if slope is not None:
        named.update(slope=slope, aspect=aspect)
    layers = {
        name: _check_grid(reflectance, name, _as_dataarray(layer, name, reflectance.dims[1:]))
        for name, layer in named.items()
    }
    if layers["classes"].dtype.kind not in "iuf":
        raise InputError(f"classes must hold numbers, got dtype {layers['classes'].dtype}")
    if class_nodata is None:
        class_nodata = _rio_nodata(layers["classes"])
    if wavelengths is None and "wavelength" in reflectance.coords:
        wavelengths = reflectance["wavelength"].values.tolist()
    resolved = params.for_bands(wavelengths, n_bands=reflectance.shape[0], extrapolate=extrapolate)
    return CorrectionInputs(
        reflectance=reflectance,
        arrays=[reflectance.data] + [layers[name].data for name in ("classes", "sza", "saa", "vza", "vaa")],
        terrain=[layers[name].data for name in ("slope", "aspect") if name in layers],
        resolved=resolved,
        reference=reference,
        limits=limits,
        class_nodata=class_nodata,
        out_dtype=np.result_type(reflectance.dtype, np.float32),
    )


def normalize(
    reflectance,
    classes,
    sza,
    saa,
    vza,
    vaa,
    params: ParameterTable,
    reference: ReferenceGeometry | dict | None = None,
    *,
    limits: tuple[float, float] | None = DEFAULT_LIMITS,
    wavelengths: Sequence[float] | None = None,
    extrapolate: bool = False,
    unknown: Literal["keep", "nan"] = "keep",
    class_nodata: float | None = None,
    flip_view_azimuth: bool = False,
    slope=None,
    aspect=None,
) -> Normalized:
    """Normalize a reflectance cube to a reference sun/view geometry with per-class BRDF models.

    Parameters
    ----------
    reflectance : xarray.DataArray (band, y, x)
        Reflectance (any units; they are kept). NaN and +-inf are nodata (NaN in the output).
        numpy or dask backed.
    classes : xarray.DataArray (y, x)
        Class map: ids of ``params``; 0, NaN and ``class_nodata`` mean "no class".
    sza, saa, vza, vaa : xarray.DataArray (y, x)
        Solar zenith, solar azimuth, view zenith, view azimuth per pixel [deg] (``docs/conventions.md``
        conventions: azimuths of the directions from the pixel towards the sun and the sensor).
    params : ParameterTable
        Model and parameters per class.
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
    class_nodata : number, optional
        Nodata value of the class map; by default its rioxarray nodata (``classes.rio.nodata``).
    flip_view_azimuth : bool, default False
        Add 180 deg to ``vaa``, for products storing the azimuth of the view direction as seen from
        the sensor.
    slope, aspect : xarray.DataArray (y, x), optional
        Surface slope [deg] in [0, 90] and the azimuth the surface faces (downslope, clockwise from
        north) [deg], both or neither (:func:`brdfcorr.terrain.slope_aspect` from a DEM, or
        :func:`brdfcorr.io.sensors.envi.read_envi_obs_terrain`). The observed geometry is then
        evaluated in each surface's own frame, the reference in the horizontal frame (module
        docstring, "Tilted surfaces"); pixels whose sun or sensor is behind the surface are nodata,
        flagged ``facing_away``. Slope 0 gives exactly the result without them.

    Returns
    -------
    Normalized
        ``(reflectance, qa)``: the corrected cube with the input's dims, coords (including the
        ``spatial_ref`` georeference), attrs and chunks, and the QA layer (y, x) of uint8 flags
        (module docstring). Lazy if any input is dask-backed.

    Raises
    ------
    ParameterError
        The table cannot be resolved to the bands (names the class and parameter).
    GridMismatchError, InputError
        A layer is not on the reflectance's grid, or has the wrong dimensions.

    Notes
    -----
    ``corrected = observed * f(ref) / f(obs)`` (``docs/conventions.md``, "The correction"), the factor evaluated
    with the model of the pixel's class (paper 003 eq. 1, paper 000 eq. 5) at the pixel's geometry.
    """
    if unknown not in ("keep", "nan"):
        raise InputError(f"unknown must be 'keep' or 'nan', got {unknown!r}")
    inputs = prepare_inputs(
        reflectance, classes, sza, saa, vza, vaa, params, reference, limits=limits, wavelengths=wavelengths,
        extrapolate=extrapolate, class_nodata=class_nodata, slope=slope, aspect=aspect,
    )
    reflectance, reference, limits = inputs.reflectance, inputs.reference, inputs.limits
    band_dim = reflectance.dims[0]
    plans = Plans({cid: _plan(cid, entry.model, entry.params) for cid, entry in inputs.resolved.items()})
    kwargs: dict[str, Any] = dict(
        plans=plans, reference=reference, limits=limits, unknown_nan=unknown == "nan",
        class_nodata=inputs.class_nodata, flip_view_azimuth=flip_view_azimuth, out_dtype=inputs.out_dtype,
    )
    if inputs.lazy:
        pairs = inputs.blockwise(_normalize_block, kwargs)
        corrected, qa = split_pairs(pairs, inputs.reflectance.data.chunks, kwargs["out_dtype"])
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
        attrs={
            "long_name": "BRDF normalization quality flags",
            "units": "1",
            "flag_masks": np.array(list(QA_FLAGS.values()), dtype=np.uint8),
            "flag_meanings": " ".join(QA_FLAGS),
        },
    )
    return Normalized(corrected, qa)


def split_pairs(pairs, chunks, out_dtype):
    """The corrected cube and the QA layer from the blockwise (corrected, QA) pairs."""
    corrected = pairs.map_blocks(_first, dtype=out_dtype, meta=np.empty((0, 0, 0), out_dtype))
    per_band_chunk = pairs.map_blocks(
        _second, dtype=np.uint8, chunks=((1,) * len(chunks[0]),) + tuple(chunks[1:]),
        meta=np.empty((0, 0, 0), np.uint8),
    )
    # Combine the flags of all band chunks of a pixel (limited / NaN in any band).
    qa = da.reduction(
        per_band_chunk, chunk=_bitwise_or, aggregate=_bitwise_or, axis=0, dtype=np.uint8,
        concatenate=True, meta=np.empty((0, 0), np.uint8),
    )
    return corrected, qa


def _first(pair):
    return pair[0]


def _second(pair):
    return pair[1]


def _bitwise_or(block, axis, keepdims):
    return np.bitwise_or.reduce(block, axis=axis, keepdims=keepdims)


def _scene_mean(sza, xp):
    """Mean of the valid solar zeniths (finite, in [0, 90)) [deg]; lazy for dask."""
    valid = (sza >= 0) & (sza < 90)
    return xp.nanmean(xp.where(valid, sza.astype(np.float64), np.nan))


def _fixed_sza(reference: ReferenceGeometry) -> float:
    # "observed" takes the per-pixel sza inside the block; the scalar is then unused.
    return float(reference.sza) if not isinstance(reference.sza, str) else np.nan


def describe_limits(limits) -> str:
    return "none" if limits is None else f"{limits[0]:g},{limits[1]:g}"


def _rio_nodata(layer: xr.DataArray):
    try:
        import rioxarray  # noqa: F401  (registers the .rio accessor)

        return layer.rio.nodata
    except Exception:  # a layer rioxarray cannot describe has no declared nodata
        return layer.attrs.get("_FillValue")


def qa_counts(qa) -> dict[str, object]:
    """Pixel counts per QA outcome (lazy 0-d arrays for dask input; compute them together).

    ``corrected``: pixels with a class of the table, valid data and a valid factor in every band
    (limited ones included); ``limited``, ``unknown_class``, ``no_class``, ``nodata`` (nodata, no
    valid factor, invalid geometry, or a tilted surface facing away from the sun or the sensor).
    """
    data = qa.data if isinstance(qa, xr.DataArray) else qa
    xp = da if isinstance(data, da.Array) else np
    skipped = QA_NODATA | QA_NO_CLASS | QA_UNKNOWN_CLASS | QA_INVALID_GEOMETRY | QA_FACING_AWAY
    return {
        "corrected": xp.count_nonzero((data & skipped) == 0),
        "limited": xp.count_nonzero(data & QA_LIMITED),
        "unknown_class": xp.count_nonzero(data & QA_UNKNOWN_CLASS),
        "no_class": xp.count_nonzero(data & QA_NO_CLASS),
        "nodata": xp.count_nonzero(data & (QA_NODATA | QA_INVALID_GEOMETRY | QA_FACING_AWAY)),
    }

