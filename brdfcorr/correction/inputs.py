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

from brdfcorr.correction.reference import fixed_sza, resolve_reference, scene_mean_sza
from brdfcorr.errors import InputError
from brdfcorr.io.grid import check_same_grid
from brdfcorr.params import ParameterTable, ReferenceGeometry


def as_dataarray(value, name: str, dims: Sequence[str]) -> xr.DataArray:
    if isinstance(value, xr.DataArray):
        return value
    array = value if isinstance(value, da.Array) else np.asarray(value)
    if array.ndim != len(dims):
        raise InputError(f"{name} must have {len(dims)} dimensions {tuple(dims)}, got shape {array.shape}")
    return xr.DataArray(array, dims=tuple(dims), name=name)


def check_grid(reflectance: xr.DataArray, name: str, layer: xr.DataArray) -> xr.DataArray:
    """The layer as (y, x) on the reflectance's grid (:func:`brdfcorr.io.grid.check_same_grid`)."""
    spatial = reflectance.dims[1:]
    if layer.ndim == 3 and layer.shape[0] == 1:
        layer = layer.isel({layer.dims[0]: 0}, drop=True)
    if layer.ndim != 2:
        raise InputError(f"{name} must be 2-D (y, x), got dims {layer.dims}")
    if layer.dims != spatial:
        layer = layer.rename(dict(zip(layer.dims, spatial)))
    check_same_grid({"reflectance": reflectance, name: layer})
    return layer


def _rio_nodata(layer: xr.DataArray):
    try:
        import rioxarray  # noqa: F401  (registers the .rio accessor)

        return layer.rio.nodata
    except Exception:  # a layer rioxarray cannot describe has no declared nodata
        return layer.attrs.get("_FillValue")


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
            scene_mean_sza(self.arrays[2], np) if self.reference.sza == "mean" else fixed_sza(self.reference)
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
            reference_sza = scene_mean_sza(layers[1], da)
        else:
            reference_sza = da.asarray(fixed_sza(self.reference))
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
    reflectance = as_dataarray(reflectance, "reflectance", ("band", "y", "x"))
    if reflectance.ndim != 3:
        raise InputError(f"reflectance must be 3-D (band, y, x), got dims {reflectance.dims}")
    if (slope is None) != (aspect is None):
        raise InputError("slope and aspect go together: give both or neither")
    named = {"classes": classes, "sza": sza, "saa": saa, "vza": vza, "vaa": vaa}
    if slope is not None:
        named.update(slope=slope, aspect=aspect)
    layers = {
        name: check_grid(reflectance, name, as_dataarray(layer, name, reflectance.dims[1:]))
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
