"""Coefficients that vary continuously with NDVI over a group of classes (FlexBRDF), internal to
:mod:`brdfcorr.correction`.

A table's ``ndvi_interpolation:`` block (:class:`brdfcorr.params.NdviInterpolation`) names NDVI
strata fitted one by one and their NDVI centres c_1 < ... < c_m. A pixel of any class of the
group with NDVI x between c_k and c_k+1 gets, band by band, the linear coefficients

    p(x) = (1 - t) p_k + t p_k+1,    t = (x - c_k) / (c_k+1 - c_k)

(Queally et al. 2022, FlexBRDF, JGR Biogeosciences 127, e2021JG006622, sect. 2.3: kernel weights
fitted per NDVI bin, interpolated between the bins' centres). A pixel at a centre gets that
class's coefficients exactly; below c_1 or above c_m the coefficients are held at the end class's
(clamped; FlexBRDF extrapolates linearly, which can turn a weight negative at extreme NDVI); a
pixel whose NDVI is undefined (red + NIR = 0) keeps its own class's coefficients. The model is
linear in the interpolated parameters, so f(x) = (1 - t) f_k + t f_k+1 at any geometry and the
factor is f(x; ref) / f(x; obs). The NDVI is that of the observed (uncorrected) reflectance, as
the strata's. Only the linear parameters are interpolated: the classes share one model and, band
by band, their shape parameters (:func:`ndvi_group` checks it).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import dask
import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr._entry import option
from brdfcorr.correction.blocks import PixelGeometry, band_shapes
from brdfcorr.correction.inputs import CorrectionInputs
from brdfcorr.errors import ParameterError
from brdfcorr.io.writer import local_scheduler
from brdfcorr.models import Model
from brdfcorr.params import NdviInterpolation, ParameterTable, ReferenceGeometry
from brdfcorr.params.bands import BandParameters
from brdfcorr.strata import ndvi

__all__ = ["NdviGroup", "interpolation_weights", "interpolated_coefficients", "ndvi_group", "with_ndvi_layer"]

#: The key of the group's pixels in the correction's per-class bookkeeping (class ids are >= 1).
GROUP_ID = -1


def interpolation_weights(index: np.ndarray, centres: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each NDVI value lies between the centres: the lower centre's position k and the weight
    t in [0, 1] of the next one (module docstring; clamped outside [c_1, c_m]).

    Parameters
    ----------
    index : ndarray
        NDVI [1] per pixel; NaN is not allowed here (the caller replaces it).
    centres : sequence of float
        Strictly increasing NDVI centres [1], at least two.

    Returns
    -------
    (ndarray of intp, ndarray of float64)
        ``k`` in 0..m-2 and ``t``: the coefficients are ``(1 - t) p[k] + t p[k + 1]``.
    """
    c = np.asarray(centres, dtype=np.float64)
    x = np.clip(np.asarray(index, dtype=np.float64), c[0], c[-1])
    lower = np.clip(np.searchsorted(c, x, side="right") - 1, 0, c.size - 2)
    return lower, (x - c[lower]) / (c[lower + 1] - c[lower])


def interpolated_coefficients(coefficients: np.ndarray, index: np.ndarray,
                              centres: Sequence[float] | np.ndarray) -> np.ndarray:
    """Per-pixel coefficients interpolated linearly in NDVI between the classes' (module docstring).

    Parameters
    ----------
    coefficients : ndarray (m, ...)
        One row of coefficients per class, in the order of ``centres``.
    index : ndarray (n,)
        NDVI [1] per pixel (finite).
    centres : sequence of float
        The classes' NDVI centres [1], strictly increasing.

    Returns
    -------
    ndarray (n, ...)
        ``(1 - t) coefficients[k] + t coefficients[k + 1]`` per pixel.
    """
    coefficients = np.asarray(coefficients, dtype=np.float64)
    lower, t = interpolation_weights(index, centres)
    t = t.reshape(t.shape + (1,) * (coefficients.ndim - 1))
    return (1.0 - t) * coefficients[lower] + t * coefficients[lower + 1]


@dataclass(frozen=True, eq=False)
class NdviGroup:
    """The classes of an NDVI interpolation resolved to the bands (:func:`ndvi_group`).

    ``ids`` in increasing NDVI, ``centres`` [1] (None until measured on the scene,
    :func:`with_ndvi_layer`), the shared ``model``, ``shapes`` and ``shape_of_band`` as in
    :class:`~brdfcorr.correction.blocks.ClassPlan`, ``coefficients`` (m, n_bands, n_linear) and
    ``row_of_band``, equal for bands whose coefficients are equal in every class.
    """

    ids: np.ndarray
    centres: np.ndarray | None
    model: Model
    shapes: tuple[dict[str, float], ...]
    shape_of_band: np.ndarray
    coefficients: np.ndarray
    row_of_band: np.ndarray
    red: tuple[float, float]
    nir: tuple[float, float]

    def holds(self, class_id) -> bool:
        """Whether pixels of ``class_id`` are corrected by the group."""
        return bool(np.any(self.ids == class_id))

    def __dask_tokenize__(self) -> str:
        digest = hashlib.sha256(f"{self.model.name}|{self.shapes!r}|{self.red}|{self.nir}".encode())
        for array in (self.ids, self.centres, self.shape_of_band, self.coefficients):
            digest.update(b"none" if array is None else np.ascontiguousarray(array).tobytes())
        return digest.hexdigest()


def _shape_matrix(model: Model, entry: BandParameters) -> np.ndarray:
    n_bands = len(next(iter(entry.params.values())))
    return np.stack([entry.params[name] for name in model.shape_names], axis=1) \
        if model.shape_names else np.zeros((n_bands, 0))


def ndvi_group(table: ParameterTable, resolved: Mapping[int, BandParameters]) -> NdviGroup | None:
    """The table's NDVI interpolation at the bands (``resolved``: ``table.for_bands(...)``), or
    None when it has none. Raises :class:`ParameterError` when the classes' shape parameters differ
    in a band: only linear coefficients can be interpolated."""
    interpolation: NdviInterpolation | None = table.ndvi_interpolation
    if interpolation is None:
        return None
    try:  # checked when the table was built; again here, as model_copy (with_class) does not validate
        interpolation.check_classes(table)
    except ValueError as error:
        raise ParameterError(str(error)) from None
    entries = [resolved[class_id] for class_id in interpolation.classes]
    model = entries[0].model
    first = _shape_matrix(model, entries[0])
    for entry in entries[1:]:
        if not np.array_equal(_shape_matrix(model, entry), first, equal_nan=True):  # NaN: bad bands
            raise ParameterError(
                f"ndvi_interpolation: class {entry.id} ({entry.name}) has other shape parameters "
                f"({', '.join(model.shape_names)}) than class {entries[0].id}; only linear coefficients are "
                "interpolated: fit the classes with those parameters fixed (fit-classes --fix) or use a "
                "kernel-driven model")
    shapes, shape_of_band, _ = band_shapes(model, entries[0].params)
    coefficients = np.stack([band_shapes(model, entry.params)[2] for entry in entries])  # (m, n_bands, n_linear)
    rows = np.column_stack([shape_of_band, np.concatenate(list(coefficients), axis=1)])
    _, row_of_band = np.unique(rows, axis=0, return_inverse=True)
    centres = None if interpolation.centres is None else np.asarray(interpolation.centres, dtype=np.float64)
    return NdviGroup(np.asarray(interpolation.classes, dtype=np.int64), centres, model, shapes, shape_of_band,
                     coefficients, row_of_band.reshape(-1), interpolation.red, interpolation.nir)


def _class_means(index, classes, ids: np.ndarray) -> np.ndarray:
    """Mean finite NDVI of each class's pixels (NaN for a class without any), in one pass."""
    xp = da if isinstance(index, da.Array) or isinstance(classes, da.Array) else np
    finite = xp.isfinite(index)
    sums, counts = [], []
    for class_id in ids:
        selected = (classes == class_id) & finite
        sums.append(xp.where(selected, index, 0.0).sum(dtype=np.float64))
        counts.append(selected.sum())
    sums, counts = dask.compute(sums, counts, scheduler=local_scheduler(None))  # without dask.distributed
    with np.errstate(invalid="ignore", divide="ignore"):  # 0 / 0: a class not in the scene is NaN
        return np.asarray(sums, dtype=np.float64) / np.asarray(counts, dtype=np.float64)


def _measured(group: NdviGroup, index, classes) -> NdviGroup | None:
    """The group with the mean NDVI of its classes in this scene as centres; classes absent from the
    scene are left out (None when fewer than two remain: the classes are then corrected one by one)."""
    centres = _class_means(index, classes, group.ids)
    present = np.isfinite(centres)
    if present.sum() < 2:
        return None
    if np.any(np.diff(centres[present]) <= 0):
        raise ParameterError(
            f"ndvi_interpolation: the mean NDVI of classes {group.ids[present].tolist()} in this scene, "
            f"{np.round(centres[present], 4).tolist()}, does not increase in the order listed; list the "
            "classes in increasing NDVI or give their centres")
    return replace(group, ids=group.ids[present], centres=centres[present], coefficients=group.coefficients[present])


def with_ndvi_layer(inputs: CorrectionInputs, group: NdviGroup,
                    wavelengths: Sequence[float] | None) -> tuple[CorrectionInputs, NdviGroup | None]:
    """The inputs with the NDVI of the observed reflectance appended as the last layer (lazy on dask
    input) and the group with its centres (measured on the scene when the table gives none: one
    read of the red and NIR bands and the class map). A group of fewer than two classes present
    comes back as None, and the inputs unchanged."""
    reflectance = inputs.reflectance
    if wavelengths is None and "wavelength" in reflectance.coords:
        wavelengths = reflectance["wavelength"].values.tolist()
    if wavelengths is None:
        raise ParameterError("ndvi_interpolation needs the image's band wavelengths (band descriptions, "
                             f"a 'wavelength' tag, or {option('wavelengths')}) to compute the NDVI")
    image = xr.DataArray(inputs.arrays[0], dims=("band", "y", "x"),
                         coords={"wavelength": ("band", np.asarray(wavelengths, dtype=float))})
    index = ndvi(image, group.red, group.nir).data
    nodata = inputs.settings.class_nodata
    if group.holds(nodata):  # the map's nodata is no class: its pixels were interpolated and measured
        kept = group.ids != nodata
        group = replace(group, ids=group.ids[kept], coefficients=group.coefficients[kept],
                        centres=None if group.centres is None else group.centres[kept])
        if kept.sum() < 2:
            return inputs, None
    if group.centres is None:
        measured = _measured(group, index, inputs.arrays[1])
        if measured is None:
            return inputs, None
        group = measured
    return replace(inputs, arrays=[*inputs.arrays, index]), group


@dataclass(frozen=True)
class _PixelPlan:
    """The group at one block's pixels: the plan interface the correction's band loop uses
    (``id``, ``row_of_band``, ``shape_of_band``, :meth:`band_coefficients`). The pixels are sorted
    by their interval between centres, ``starts`` (m) bounding each interval's run of pixels, so a
    band's coefficients are ``(1 - t) p_k + t p_k+1`` per interval (exact at the centres), without
    gathers."""

    id: int
    row_of_band: np.ndarray
    shape_of_band: np.ndarray
    coefficients: np.ndarray  # (m, n_bands, n_linear)
    starts: np.ndarray
    weight: np.ndarray
    complement: np.ndarray  # 1 - weight
    dtype: np.dtype

    def band_coefficients(self, band: int) -> np.ndarray:
        """The linear coefficients of ``band`` at each pixel, shape (n_linear, pixels):
        ``(1 - t) p_k + t p_k+1`` on the pixels of interval k."""
        rows = self.coefficients[:, band, :]  # (m, n_linear)
        out = np.empty((rows.shape[1], self.weight.size), dtype=self.dtype)
        for k in range(rows.shape[0] - 1):
            run = slice(self.starts[k], self.starts[k + 1])
            if run.start == run.stop:
                continue
            low, high = rows[k].astype(self.dtype), rows[k + 1].astype(self.dtype)
            np.multiply(low[:, None], self.complement[None, run], out=out[:, run])
            out[:, run] += high[:, None] * self.weight[None, run]
        return out


def group_states(group: NdviGroup, pixels: PixelGeometry, index_layer: np.ndarray, reference: ReferenceGeometry,
                 reference_sza, out_dtype) -> list[tuple]:
    """The group's pixels of a block as one state of the correction's band loop, ``[(plan, pixel
    indices, terms)]``, or ``[]`` when the block holds none."""
    members = pixels.usable & ~pixels.no_class & np.isin(pixels.classes, group.ids)  # as per class
    index = np.flatnonzero(members)
    if index.size == 0:
        return []
    assert group.centres is not None  # measured by with_ndvi_layer
    values = np.asarray(index_layer, dtype=np.float64).reshape(-1)[index]
    order = np.argsort(group.ids)  # the ids are in NDVI order, not necessarily sorted
    own = group.centres[order][np.searchsorted(group.ids[order], pixels.classes[index])]
    values = np.where(np.isfinite(values), values, own)  # undefined NDVI: the pixel's own class
    lower, weight = interpolation_weights(values, group.centres)
    order = np.argsort(lower, kind="stable")  # each interval's pixels in one run (_PixelPlan)
    index, lower, weight = index[order], lower[order], weight[order]
    starts = np.searchsorted(lower, np.arange(group.centres.size))
    observed, ref = pixels.geometries(index, reference, reference_sza)
    with np.errstate(over="ignore"):  # as the per-class path: a term beyond the output precision is inf
        terms = [
            tuple(tuple(np.broadcast_to(np.asarray(t, dtype=out_dtype), index.shape)
                        for t in group.model.terms(where, shape)) for where in (observed, ref))
            for shape in group.shapes
        ]
    plan = _PixelPlan(GROUP_ID, group.row_of_band, group.shape_of_band, group.coefficients, starts,
                      weight.astype(out_dtype), (1.0 - weight).astype(out_dtype), np.dtype(out_dtype))
    return [(plan, index, terms)]
