"""The inputs of a per-pixel correction, checked against the reflectance's grid and resolved to
its bands once (:func:`prepare_inputs`), for :func:`brdfcorr.correction.normalize` and its
companions (the uncertainty, the topographic step)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr._validation import check_flags
from brdfcorr.correction.checks import (  # check_grid: the topographic step's as well
    angle_layers,
    as_dataarray,
    check_grid,  # noqa: F401
    check_layout,
    checked_layers,
)
from brdfcorr.correction.reference import fixed_sza, resolve_reference, scene_mean_sza, with_hls_sza
from brdfcorr.errors import InputError
from brdfcorr.io.reflectance import declared_nodata, reflectance_factors
from brdfcorr.io.wavelengths import with_wavelengths
from brdfcorr.params import ParameterTable, ReferenceGeometry, as_parameter_table


def one_class(reflectance: xr.DataArray) -> xr.DataArray:
    """The class map of ``classes=None``: class 1 everywhere on the reflectance's grid (lazily for
    dask), as the command line makes it without ``--classes`` (a table of one class, e.g. a
    built-in coefficient set, corrects every pixel)."""
    first = reflectance.isel({reflectance.dims[0]: 0}, drop=True)
    band_coords = [name for name in first.coords if name not in (*first.dims, "spatial_ref")]
    classes = xr.ones_like(first, dtype=np.uint8).drop_vars(band_coords).rename("classes")
    classes.attrs = {}
    return classes


@dataclass(frozen=True)
class BlockSettings:
    """What every block of a correction needs besides its arrays: the reference geometry, the
    factor limits, the class map's nodata, whether view azimuths are flipped, the output dtype."""

    reference: ReferenceGeometry
    limits: tuple[float, float] | None
    class_nodata: float | None
    flip_view_azimuth: bool
    out_dtype: np.dtype


@dataclass(frozen=True)
class CorrectionInputs:
    """The inputs of a per-pixel correction, checked and resolved once (:func:`prepare_inputs`).

    ``arrays`` holds the data of the reflectance (band, y, x), classes, sza, saa, vza and vaa
    (y, x) and, for a tilted surface, slope and aspect; ``resolved`` the table at the bands.

    A block function is called as ``block(reflectance, band_index, reference_sza, classes, sza,
    saa, vza, vaa[, slope, aspect], **kwargs)``.
    """

    reflectance: xr.DataArray
    arrays: list
    resolved: dict
    settings: BlockSettings

    @property
    def lazy(self) -> bool:
        return any(isinstance(a, da.Array) for a in self.arrays)

    def apply(self, block_function, kwargs: Mapping[str, Any]):
        """``block_function`` on the whole (numpy) inputs as one block."""
        reference = self.settings.reference
        reference_sza = scene_mean_sza(self.arrays[2], np) if reference.sza == "mean" else fixed_sza(reference)
        cube, *layers = self.arrays
        return block_function(cube, np.arange(cube.shape[0]), reference_sza, *layers, **kwargs)

    def blockwise(self, block_function, kwargs: Mapping[str, Any]) -> da.Array:
        """``block_function`` lazily, one task per reflectance chunk (with its chunks); every
        layer is rechunked to the reflectance's spatial chunks. Functions built on the same
        inputs share their dask keys, so computing them together reads each chunk once."""
        reflectance = self.arrays[0]
        if not isinstance(reflectance, da.Array):
            reflectance = da.from_array(reflectance, chunks="auto")
        spatial_chunks = reflectance.chunks[1:]
        layers = [da.asarray(a).rechunk(spatial_chunks) for a in self.arrays[1:]]
        band_index = da.arange(reflectance.shape[0], chunks=(reflectance.chunks[0],))
        reference = self.settings.reference
        if reference.sza == "mean":
            reference_sza = scene_mean_sza(layers[1], da)
        else:
            reference_sza = da.asarray(fixed_sza(reference))
        return da.blockwise(
            block_function, "byx",
            reflectance, "byx", band_index, "b", reference_sza, (),
            *(item for layer in layers for item in (layer, "yx")),
            meta=np.empty((0, 0, 0), dtype=self.settings.out_dtype),
            **kwargs,
        )


def prepare_inputs(
    reflectance, classes, angles, params: ParameterTable, reference=None, *,
    limits: tuple[float, float] | None, wavelengths: Sequence[float] | None, extrapolate: bool,
    flip_view_azimuth: bool = False,
) -> CorrectionInputs:
    """Check the inputs of :func:`~brdfcorr.correction.normalize` (and of its companions, e.g.
    :func:`~brdfcorr.correction.uncertainty.correction_uncertainty`) and resolve the table to the bands.

    Raises InputError, GridMismatchError or ParameterError as documented in
    :func:`~brdfcorr.correction.normalize`.
    """
    check_flags(extrapolate=extrapolate, flip_view_azimuth=flip_view_azimuth)
    params = as_parameter_table(params)
    if classes is None and params.class_ids != (1,):  # as the command line without --classes
        raise InputError(f"classes=None makes the whole image class 1, and the table holds classes "
                         f"{list(params.class_ids)}: give the class map")
    if limits is not None:
        limits = (float(limits[0]), float(limits[1]))
        if not (0 < limits[0] <= 1 <= limits[1] < np.inf):
            raise InputError(f"factor limits {limits} must satisfy 0 < lower <= 1 <= upper < inf")
    reference = resolve_reference(reference, params)
    reflectance = as_dataarray(reflectance, "reflectance", ("band", "y", "x"))
    if reflectance.ndim != 3:
        raise InputError(f"reflectance must be 3-D (band, y, x) or 4-D (time, band, y, x), got dims "
                         f"{reflectance.dims}")
    if reflectance.dims[0] == "time":  # (time, y, x): one band picked from a series
        raise InputError(f"reflectance has dims {reflectance.dims} and no band dimension (a band picked with "
                         ".sel(band=4) drops it): keep it, .sel(band=[4]), or add it, "
                         "reflectance.expand_dims('band', axis=1)")
    named = {"classes": one_class(reflectance) if classes is None else classes, **angle_layers(angles)}
    check_layout(reflectance, named.values())
    reflectance = with_wavelengths(reflectance_factors(reflectance))
    layers = checked_layers(reflectance, named)
    reference = with_hls_sza(reference, reflectance)
    if wavelengths is None and "wavelength" in reflectance.coords:
        wavelengths = np.atleast_1d(reflectance["wavelength"].values).tolist()  # a scalar: one band
    resolved = params.for_bands(wavelengths, n_bands=reflectance.shape[0], extrapolate=extrapolate)
    settings = BlockSettings(reference, limits, declared_nodata(layers["classes"]), flip_view_azimuth,
                             np.result_type(reflectance.dtype, np.float32))
    return CorrectionInputs(reflectance, [reflectance.data] + [layer.data for layer in layers.values()], resolved,
                            settings)
