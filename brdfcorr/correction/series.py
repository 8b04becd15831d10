"""Cubes with a time dimension, (time, band, y, x) as STAC loaders (stackstac, odc-stac) give them:
each date normalized on its own (:func:`over_dates`), with its own angles and, where the class map
or the angles have the time dimension too, its own class map; lazily for dask input, one graph per
date joined along the time dimension.

A date is corrected exactly as the same image alone (``brdfcorr correct``, ``brdfcorr nbar``): a
``"mean"`` reference sun zenith is each date's own scene mean.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping

import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr.correction.checks import BAND_DIMS
from brdfcorr.errors import InputError

__all__ = ["dated_like", "is_series", "over_dates"]


def is_series(reflectance) -> bool:
    """Whether ``reflectance`` is a 4-D cube, (time, band, y, x)."""
    return np.ndim(reflectance) == 4


def over_dates(normalize_one: Callable, reflectance, classes, angles, params, reference=None, **options):
    """``normalize_one`` (:func:`brdfcorr.correction.normalize`) date by date over a (time, band, y,
    x) cube; returns its result type with the corrected cube (time, band, y, x) and the QA layer
    (time, y, x), or, for a function that returns one DataArray per date
    (:func:`~brdfcorr.correction.uncertainty.correction_uncertainty`), their cube.

    ``classes`` and each angle layer are (y, x), the same for every date, or have the cube's time
    dimension (a DataArray with that dim, or an array with one more axis than (y, x)).
    """
    cube = reflectance if isinstance(reflectance, xr.DataArray) else xr.DataArray(
        reflectance if isinstance(reflectance, da.Array) else np.asarray(reflectance),
        dims=("time", "band", "y", "x"), name="reflectance")
    _check_layout(cube)
    dim = cube.dims[0]
    classes = dated_like(classes, cube, "classes")
    angles = (dated_like(angles, cube, "angles") if isinstance(angles, xr.Dataset) else
              {name: dated_like(layer, cube, name) for name, layer in angles.items()} if isinstance(angles, Mapping)
              else angles)
    results = [
        normalize_one(cube.isel({dim: index}), _at_date(classes, dim, index, "classes"),
                      _angles_at_date(angles, dim, index), params, reference, **options)
        for index in range(cube.sizes[dim])
    ]
    if isinstance(results[0], xr.DataArray):  # one layer per date (the uncertainty's 1-sigma)
        return xr.concat(results, dim=dim).transpose(dim, *cube.dims[1:])
    corrected = xr.concat([result.reflectance for result in results], dim=dim)
    qa = xr.concat([result.qa for result in results], dim=dim)
    return type(results[0])(corrected.transpose(dim, *cube.dims[1:]), qa.transpose(dim, *cube.dims[2:]))


def _check_layout(cube: xr.DataArray) -> None:
    """Refuse a cube whose dims are named in another order than (time, band, y, x), naming the
    transpose that orders it (the band dim is one of :data:`BAND_DIMS`; y and x are the dims so
    named, else the last two of the others)."""
    band = next((dim for dim in cube.dims if dim in BAND_DIMS), None)
    if band is None:
        return  # unnamed dims: taken in the documented order
    others = [dim for dim in cube.dims if dim != band]
    spatial = ("y", "x") if {"y", "x"} <= set(others) else tuple(others[-2:])
    expected = (*(dim for dim in others if dim not in spatial), band, *spatial)
    if cube.dims != expected:
        order = ", ".join(map(repr, expected))
        raise InputError(f"reflectance has dims {cube.dims}; a 4-D cube is (time, band, y, x): "
                         f"transpose it, reflectance.transpose({order})")


def dated_like(layer, cube: xr.DataArray, name: str):
    """``layer`` with its dates those of ``cube`` (its first dimension), in the cube's order: picked
    by label where both label their time dimension (a layer may hold more dates than the cube),
    else one per date in the same order, an :class:`InputError` where the counts differ. A layer
    without the time dimension is the same for every date."""
    dim, count = cube.dims[0], cube.sizes[cube.dims[0]]
    if isinstance(layer, (xr.DataArray, xr.Dataset)):
        if dim not in layer.dims:
            _refuse_other_dates(layer, cube, name)
            return layer
        if dim in cube.coords and dim in layer.coords:
            labels, given = cube[dim].values, layer[dim].values
            if np.array_equal(labels, given):
                return layer  # the same dates in the same order (repeated labels included)
            repeated = [label for label in (labels, given) if np.unique(label).size < label.size]
            if repeated:
                values, counts = np.unique(repeated[0], return_counts=True)
                raise InputError(f"{'reflectance' if repeated[0] is labels else name} repeats {dim} "
                                 f"{', '.join(map(str, values[counts > 1][:3]))} and the dates of {name} differ "
                                 f"from the reflectance's: pair them by position (drop the {dim} labels of {name}) or "
                                 f"combine the repeated dates first (e.g. groupby('{dim}').first())")
            missing = np.setdiff1d(labels, given)
            if missing.size:
                raise InputError(f"{name} has no {dim} {', '.join(map(str, missing[:3]))}"
                                 f"{' ...' if missing.size > 3 else ''} of the reflectance: give it every date")
            return layer.sel({dim: labels})
        found = layer.sizes[dim]
    elif np.ndim(layer) == 3:
        found = np.shape(layer)[0]
    else:
        return layer
    if found != count:
        raise InputError(f"reflectance has {count} dates along {dim!r} and {name} {found}: give one per date, "
                         f"or one for every date")
    return layer


def _refuse_other_dates(layer: xr.DataArray | xr.Dataset, cube: xr.DataArray, name: str) -> None:
    """Refuse a layer with a dimension of more than one item beside (y, x) that the cube lacks: its
    dates named otherwise than the cube's (it was taken for one (y, x) layer of every date, and
    failed as "must be 2-D")."""
    other = [dim for dim in layer.dims if dim not in cube.dims and layer.sizes[dim] > 1]
    if other:
        raise InputError(f"{name} has a dimension {other[0]!r} ({layer.sizes[other[0]]} items) that the reflectance "
                         f"lacks, whose dates lie along {cube.dims[0]!r}: if these are the dates, name them alike, "
                         f"{name}.rename({other[0]}={cube.dims[0]!r})")


def _at_date(layer, dim: Hashable, index: int, name: str):
    """The (y, x) layer of date ``index``: the layer itself where it has no time dimension."""
    if layer is None:
        return None
    if isinstance(layer, xr.DataArray):
        return layer.isel({dim: index}) if dim in layer.dims else layer
    if np.ndim(layer) == 3:
        return layer[index]
    if np.ndim(layer) != 2:
        raise InputError(f"{name} must be (y, x) or ({dim}, y, x), got shape {np.shape(layer)}")
    return layer


def _angles_at_date(angles, dim: Hashable, index: int):
    """The angle layers of date ``index`` (a Dataset or a mapping, as :func:`normalize` takes)."""
    if isinstance(angles, xr.Dataset):
        return angles.isel({dim: index}) if dim in angles.dims else angles
    if isinstance(angles, Mapping):
        return {name: _at_date(layer, dim, index, name) for name, layer in angles.items()}
    return angles  # normalize says what is wrong with it
