"""The block machinery that the correction and its uncertainty share (internal to
:mod:`brdfcorr.correction`): per-class plans of the band parameters, a block's pixel geometry
(flags, usable pixels, the surface frame, observed and reference geometries), its non-finite
reflectance (:func:`cube_masks`) and the split of blockwise (values, QA) pairs."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import dask.array as da
import numpy as np

from brdfcorr.correction.qa import QA, set_flags
from brdfcorr.correction.terrain import local_angles
from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.models import Model
from brdfcorr.params import ReferenceGeometry

if TYPE_CHECKING:
    from brdfcorr.correction.inputs import BlockSettings


@dataclass(frozen=True)
class ClassPlan:
    """One class's model and band parameters, arranged for evaluation in blocks.

    The model is ``f = sum_j c_j B_j(geometry; shape)`` over its linear parameters
    (:attr:`Model.linear`). ``shapes`` are the distinct sets of shape parameters; band ``b`` uses the
    basis of ``shapes[shape_of_band[b]]`` with the coefficients ``coefficients[b]``.
    ``row_of_band[b]`` numbers the distinct (shape, coefficients) rows, so bands with equal rows
    share one factor; it is :data:`NO_PARAMETERS` for a band in which the class has no parameters
    (its ``bad_bands``, :attr:`brdfcorr.params.BandParameters.no_parameters`): the correction passes
    that band through uncorrected (factor 1) and flags ``band_uncorrected``.
    """

    id: int
    model: Model
    shapes: tuple[dict[str, float], ...]
    shape_of_band: np.ndarray
    coefficients: np.ndarray
    row_of_band: np.ndarray

    def band_coefficients(self, band: int) -> list[float]:
        """The linear coefficients of ``band``, as Python floats (they keep the terms' dtype)."""
        return [float(c) for c in self.coefficients[band]]


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


#: :attr:`ClassPlan.row_of_band` of a band without parameters (passed through, factor 1).
NO_PARAMETERS = -2


def class_plan(class_id: int, model: Model, params: dict[str, np.ndarray],
               no_parameters: np.ndarray | None = None) -> ClassPlan:
    """The :class:`ClassPlan` of a class's per-band ``params``; the bands ``no_parameters`` (NaN
    there) get the row :data:`NO_PARAMETERS` and the shape of a band with parameters (or the
    model's defaults), so that no basis is ever evaluated with NaN."""
    if no_parameters is not None:
        good = np.flatnonzero(~no_parameters)
        params = {name: np.where(no_parameters, values[good[0]] if good.size else model.defaults[name], values)
                  for name, values in params.items()}
    shapes, shape_of_band, coefficients = band_shapes(model, params)
    _, row_of_band = np.unique(np.column_stack([shape_of_band, coefficients]), axis=0, return_inverse=True)
    row_of_band = row_of_band.reshape(-1)
    if no_parameters is not None:
        row_of_band = np.where(no_parameters, NO_PARAMETERS, row_of_band)
    return ClassPlan(class_id, model, shapes, shape_of_band, coefficients, row_of_band)


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
    def of_block(cls, layers: Sequence[np.ndarray], settings: BlockSettings) -> PixelGeometry:
        """The pixels of a block's layers: classes, sza, saa, vza, vaa and, for a tilted surface,
        slope and aspect (:class:`brdfcorr.correction.inputs.CorrectionInputs`)."""
        classes, sza, saa, vza, vaa, *terrain = layers
        classes = np.asarray(classes).reshape(-1)
        theta_i, theta_r, saa, vaa = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (sza, vza, saa, vaa))
        if settings.flip_view_azimuth:
            vaa = vaa + 180.0
        angles_finite = np.isfinite(theta_i) & np.isfinite(theta_r) & np.isfinite(saa) & np.isfinite(vaa)
        no_class = no_class_mask(classes, settings.class_nodata)
        with np.errstate(invalid="ignore"):
            in_domain = (theta_i >= 0) & (theta_i < 90) & (theta_r >= 0) & (theta_r < 90)
        invalid_geometry = angles_finite & ~in_domain
        qa = np.zeros(classes.size, dtype=np.uint8)
        set_flags(qa, ~angles_finite, QA.NODATA)
        set_flags(qa, invalid_geometry, QA.INVALID_GEOMETRY)
        usable = angles_finite & ~invalid_geometry
        angles = (theta_i, saa, theta_r, vaa)
        if terrain:
            angles, usable = local_frame(qa, usable, angles, *terrain)
        return cls(classes, qa, usable, no_class, theta_i, angles)

    def geometries(self, index: np.ndarray, reference: ReferenceGeometry, reference_sza):
        """The observed and the reference geometry of the pixels ``index``. The reference is
        horizontal: ``"observed"`` is each pixel's horizontal sun zenith."""
        sza, saa, vza, vaa = (angle[index] for angle in self.angles)
        observed = ScatteringGeometry(sza, vza, relative_azimuth(saa, vaa))
        ref_sza = self.theta_i[index] if reference.sza == "observed" else np.asarray(reference_sza, dtype=np.float64)
        return observed, ScatteringGeometry(ref_sza, np.float64(reference.vza), np.float64(reference.raa))


def local_frame(qa, usable, angles, slope, aspect):
    """Sun and view angles in the tilted surfaces' frames (1-D, per pixel) and the usable pixels:
    a slope outside [0, 90] is invalid geometry, non-finite slope or aspect nodata, and a sun or
    sensor at or below the surface's horizon (local zenith >= 90 deg) facing away."""
    slope, aspect = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (slope, aspect))
    finite = np.isfinite(slope) & np.isfinite(aspect)
    with np.errstate(invalid="ignore"):
        bad_slope = finite & ~((slope >= 0) & (slope <= 90))
    set_flags(qa, ~finite, QA.NODATA)
    set_flags(qa, bad_slope, QA.INVALID_GEOMETRY)
    usable = usable & finite & ~bad_slope
    local = local_angles(*angles, np.where(usable, slope, 0.0), np.where(usable, aspect, 0.0))
    with np.errstate(invalid="ignore"):
        away = usable & ((local.sza >= 90) | (local.vza >= 90))
    set_flags(qa, away, QA.FACING_AWAY)
    return (local.sza, local.saa, local.vza, local.vaa), usable & ~away


def cube_masks(cube, qa) -> None:
    """Flag pixels with non-finite reflectance in some band (``qa`` in place)."""
    if cube.dtype.kind == "f":
        # NaN or +-inf in some band makes the band sum non-finite (one pass, no mask cube); those
        # few pixels are then checked band by band (a sum of finite values may overflow).
        with np.errstate(over="ignore", invalid="ignore"):
            candidates = np.flatnonzero(~np.isfinite(np.add.reduce(cube, axis=0)))
        if candidates.size:
            set_flags(qa, candidates[~np.isfinite(cube[:, candidates]).all(axis=0)], QA.NODATA)


def present_classes(values: np.ndarray) -> list:
    """Distinct class ids in a block (a histogram for small integers, faster than sorting)."""
    if values.size == 0:
        return []
    if values.dtype.kind in "iu" and values.dtype.itemsize <= 2:
        lowest = int(values.min())
        return (np.flatnonzero(np.bincount(values.astype(np.intp) - lowest)) + lowest).tolist()
    return np.unique(values).tolist()


def split_pairs(pairs, out_dtype):
    """The corrected cube and the QA layer from the blockwise (corrected, QA) pairs (one per chunk
    of the cube: their chunks are the cube's, whether it was dask or numpy given with dask layers)."""
    chunks = pairs.chunks
    corrected = pairs.map_blocks(first_of_pair, dtype=out_dtype, meta=np.empty((0, 0, 0), out_dtype))
    per_band_chunk = pairs.map_blocks(
        second_of_pair, dtype=np.uint8, chunks=((1,) * len(chunks[0]),) + tuple(chunks[1:]),
        meta=np.empty((0, 0, 0), np.uint8),
    )
    # Combine the flags of all band chunks of a pixel (limited / NaN in any band).
    qa = da.reduction(
        per_band_chunk, chunk=bitwise_or, aggregate=bitwise_or, axis=0, dtype=np.uint8,
        concatenate=True, meta=np.empty((0, 0), np.uint8),
    )
    return corrected, qa


def first_of_pair(pair):
    return pair[0]


def second_of_pair(pair):
    return pair[1]


def bitwise_or(block, axis, keepdims):
    return np.bitwise_or.reduce(block, axis=axis, keepdims=keepdims)


