"""The checks the command line makes on its files, made on the arrays a Python caller gives
(:func:`brdfcorr.correction.normalize`, the ``.brdf`` accessor), so that no entry point takes an
input the others refuse (issue 38):

- :func:`check_layout`: a cube with its bands last, (y, x, band), is refused with the transpose
  that fixes it, instead of a grid error between its spatial and band axes;
- :func:`brdfcorr.io.reflectance.reflectance_factors` (in :func:`~brdfcorr.correction.inputs.prepare_inputs`):
  integer counts are scaled with the scale and offset they carry (rioxarray's
  ``scale_factor``/``add_offset``, as :func:`brdfcorr.io.rasters.open_image` applies a file's),
  and refused without them or with a scale that is a divisor: an offset (Sentinel-2 L2A from
  baseline 04.00: -0.1) left out changes the corrected values, not only their units;
- :func:`checked_layers`: the class map and angle layers as (y, x) arrays on the reflectance's
  grid (:func:`check_grid`), real numbers, the angles guarded (:func:`guard_angles`);
- :func:`guard_angles`: angle layers that can only be radians
  (:func:`brdfcorr.io.angles.looks_like_radians`, the rule the command line applies to its angle
  files) are refused, lazily for dask input: the check runs with each chunk's correction.

Messages name the fix in the caller's words (:mod:`brdfcorr._entry`).
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Mapping, Sequence

import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr.correction.terrain import SlopeAspect, check_slope_aspect
from brdfcorr.errors import InputError
from brdfcorr.io.angles import check_angle_values
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.reflectance import unpacked
from brdfcorr.io.scene import check_class_grid

__all__ = ["angle_layers", "ANGLE_LAYERS", "TERRAIN_LAYERS", "check_layout", "checked_layers", "check_grid",
           "as_dataarray", "guard_angles", "angle_statistics", "BAND_DIMS"]

#: Dimension names that hold bands (a cube whose last dimension has one of them is (y, x, band)).
BAND_DIMS = ("band", "bands", "wavelength", "channel", "spectral")


#: The layers of ``angles`` every correction needs, and the two a tilted surface adds [deg].
ANGLE_LAYERS = ("sza", "saa", "vza", "vaa")
TERRAIN_LAYERS = ("slope", "aspect")


def angle_layers(angles, names: Sequence[str] = ANGLE_LAYERS) -> dict:
    """The layers ``names`` of ``angles`` (an xarray Dataset, or a mapping of name to array),
    plus ``slope`` and ``aspect`` where it holds them (both or neither)."""
    if not isinstance(angles, (Mapping, xr.Dataset)):
        raise InputError(f"angles must be a Dataset or mapping with {', '.join(names)}, got {type(angles).__name__}")
    missing = [name for name in names if name not in angles]
    if missing:
        raise InputError(f"angles has no {', '.join(missing)} (it needs {', '.join(names)})")
    terrain = [name for name in TERRAIN_LAYERS if name in angles and name not in names]
    if len(terrain) == 1:
        raise InputError("slope and aspect go together: give both or neither")
    return {name: angles[name] for name in (*names, *terrain)}


def check_layout(reflectance: xr.DataArray, layers: Iterable) -> None:
    """Refuse a (y, x, band) cube: its last dimension is named like bands, or the (y, x) ``layers``
    (class map, angles: numpy, dask or xarray) have the shape of its first two axes and not of its
    last two."""
    if reflectance.ndim != 3:
        return
    named_last = reflectance.dims[-1] in BAND_DIMS and reflectance.dims[0] not in BAND_DIMS
    shapes = {np.shape(layer) for layer in layers if np.ndim(layer) == 2}
    leading = bool(shapes) and all(shape == reflectance.shape[:2] != reflectance.shape[1:] for shape in shapes)
    if named_last or leading:
        numbered = all(str(dim).startswith("dim_") or dim in ("band", "y", "x") for dim in reflectance.dims)
        first, second, last = reflectance.dims
        fix = ("np.moveaxis(reflectance, -1, 0)" if numbered and not named_last
               else f"reflectance.transpose({last!r}, {first!r}, {second!r})")
        raise InputError(f"reflectance of shape {reflectance.shape} (dims {reflectance.dims}) has its bands last, "
                         f"(y, x, band); transpose to (band, y, x): {fix}")


def as_dataarray(value, name: str, dims: Sequence[Hashable]) -> xr.DataArray:
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
    if set(layer.dims) == set(spatial):  # the reflectance's own names, perhaps in another order
        layer = layer.transpose(*spatial)
    elif set(layer.dims) & set(spatial):
        raise InputError(f"{name} has dims {layer.dims} and the reflectance {reflectance.dims}: name the "
                         f"layer's dims as the reflectance's spatial ones, {spatial}")
    elif layer.dims != spatial:  # other names (a numpy array's): in the reflectance's order
        layer = layer.rename(dict(zip(layer.dims, spatial)))
    if name == "classes":  # a land-cover map on another grid: the message names the alignment
        check_class_grid(reflectance, layer, "reflectance")
    check_same_grid({"reflectance": reflectance, name: layer})
    return layer


def checked_layers(reflectance: xr.DataArray, named: Mapping[str, object]) -> dict[str, xr.DataArray]:
    """The class map and the angle layers ``named`` (numpy, dask or xarray; ``classes``, ``sza`` ...
    ``vaa``, and ``slope``, ``aspect`` for a tilted surface) as (y, x) DataArrays on the
    reflectance's grid (:func:`check_grid`), the angles' packed values unpacked
    (:func:`brdfcorr.io.reflectance.unpacked`: int16 hundredths of a degree with a ``scale_factor``
    of 0.01 are degrees), refused where they (or the reflectance) hold complex values, the angles
    guarded (:func:`guard_angles`), the class map refused where it holds no numbers, and slope and
    aspect held in memory checked for degrees as the command line checks its files
    (:func:`brdfcorr.correction.terrain.check_slope_aspect`: radians, or no value in the domain;
    lazy (dask) layers are not read for it: the correction stays lazy)."""
    layers = {name: check_grid(reflectance, name, as_dataarray(layer, name, reflectance.dims[1:]))
              for name, layer in named.items()}
    layers = {name: layer if name == "classes" else unpacked(layer, name) for name, layer in layers.items()}
    complex_layers = [f"{name} ({layer.dtype})" for name, layer in {"reflectance": reflectance, **layers}.items()
                      if layer.dtype.kind == "c"]
    if complex_layers:  # the imaginary part would be lost, or carried into a complex "reflectance"
        raise InputError(f"complex values in {', '.join(complex_layers)}; real numbers are expected")
    layers = guard_angles(layers)
    if "slope" in layers and not any(isinstance(layers[name].data, da.Array) for name in TERRAIN_LAYERS):
        check_slope_aspect(SlopeAspect(layers["slope"], layers["aspect"]), "terrain layers")
    if layers["classes"].dtype.kind not in "iuf":
        raise InputError(f"classes must hold numbers, got dtype {layers['classes'].dtype}")
    return layers


def guard_angles(layers: Mapping[str, xr.DataArray]) -> dict[str, xr.DataArray]:
    """The angle layers, refused where they cannot be degrees. Numpy layers at once, by the rules
    of the command line's angle files (:func:`brdfcorr.io.angles.check_angle_values`: radians, no
    zenith in [0, 90) at all as for hundredths of a degree, a layer without a finite value); dask
    layers by each chunk, by the same rules but the last (:func:`_refuse_units`: the ``sza``
    layer's chunks carry the check, so it runs with the correction and costs no pass of its own; a
    layer without a finite value needs the whole layer: :func:`brdfcorr.io.angles.check_angles`
    makes that pass)."""
    arrays = [layers[name].data for name in ANGLE_LAYERS]
    if not any(isinstance(array, da.Array) for array in arrays):
        _check_units(arrays, "angles", empty_allowed=False)
        return dict(layers)
    first = next(array for array in arrays if isinstance(array, da.Array))
    chunked = [da.asarray(array).rechunk(first.chunks) for array in arrays]
    checked = da.map_blocks(_refuse_units, *chunked, dtype=first.dtype, meta=np.empty((0, 0), first.dtype))
    return {**layers, "sza": layers["sza"].copy(data=checked)}


def angle_statistics(values: np.ndarray) -> tuple[tuple[float, float], tuple[int, int]]:
    """The (min, max) [deg] of a layer's finite values, and how many are finite and in [0, 90)."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return (np.nan, np.nan), (0, 0)
    return (float(finite.min()), float(finite.max())), (finite.size, int(((finite >= 0) & (finite < 90)).sum()))


def _refuse_units(sza, saa, vza, vaa) -> np.ndarray:
    """``sza`` unchanged, or an :class:`InputError` where the chunk's layers cannot be degrees
    (:func:`_check_units`). A chunk without a finite value in a layer is nodata there, not an
    error: its neighbours may have them."""
    _check_units((sza, saa, vza, vaa), "angles (a chunk)", empty_allowed=True)
    return sza


def _check_units(arrays, where: str, *, empty_allowed: bool) -> None:
    """The rules of :func:`brdfcorr.io.angles.check_angle_values` (radians; no zenith in [0, 90),
    as for hundredths of a degree; a layer without a finite value, unless ``empty_allowed``: then
    such a layer is left out) on the sza, saa, vza and vaa ``arrays``, named ``where``."""
    statistics = {name: angle_statistics(np.asarray(values)) for name, values in zip(ANGLE_LAYERS, arrays)}
    if empty_allowed:
        statistics = {name: found for name, found in statistics.items() if found[1][0]}
    check_angle_values({name: found[0] for name, found in statistics.items()},
                       {name: found[1] for name, found in statistics.items()}, lambda name: where,
                       whole=not empty_allowed)
