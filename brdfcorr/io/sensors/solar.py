"""Solar zenith and azimuth from the acquisition time and the pixel coordinates (pvlib's NREL SPA).

For products that deliver no solar angles. The sun position comes from :mod:`pvlib.spa` (the NREL
Solar Position Algorithm, Reda & Andreas 2004, about 0.0003 deg), evaluated per pixel, block by
block on dask, so a full-resolution grid is never held in memory. The zenith is the geometric
(topocentric, refraction-free) one by default, as sensor products give it.

References
----------
.. [1] I. Reda, A. Andreas (2004): Solar position algorithm for solar radiation applications.
   Solar Energy 76(5), 577-589. Implemented by pvlib (W. F. Holmgren et al., JOSS 3(29), 884, 2018).
"""

from __future__ import annotations

import dask.array as da
import numpy as np
import pandas as pd
import xarray as xr
from pyproj import CRS, Transformer

from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors.grids import GRID_CHUNK, _grid_of, pixel_centres

__all__ = ["solar_angles", "solar_position"]

# pvlib's defaults: standard pressure [hPa], a mild temperature [degC], Delta T = TT - UT1 [s].
_PRESSURE_HPA = 1013.25
_TEMPERATURE_C = 12.0
_DELTA_T_S = 67.0
_REFRACTION_AT_HORIZON_DEG = 0.5667


def _unix_seconds(time) -> float:
    """UTC seconds since 1970 of a timezone-aware time (naive times are refused, not guessed)."""
    stamp = pd.Timestamp(time)
    if stamp.tzinfo is None:
        raise SensorInputError(f"acquisition time {time!s} has no time zone; give it in UTC ('...Z')")
    return stamp.tz_convert("UTC").value / 1e9


def solar_position(time, latitude, longitude, altitude=0.0, refraction: bool = False):
    """Solar zenith and azimuth [deg] at one time for arrays of positions (numpy).

    Parameters
    ----------
    time : str, datetime or pandas.Timestamp
        Acquisition time, timezone-aware (UTC or any zone).
    latitude, longitude : array-like
        Geodetic latitude and longitude (WGS 84) [deg].
    altitude : float or array-like
        Height above the ellipsoid [m].
    refraction : bool
        False (default): geometric zenith. True: apparent zenith, refracted by a standard
        atmosphere.

    Returns
    -------
    zenith, azimuth : numpy.ndarray
        Solar zenith [deg] and azimuth of the direction towards the sun [deg], clockwise from
        north in [0, 360), shaped like the broadcast inputs.
    """
    latitude, longitude, altitude = np.broadcast_arrays(
        np.asarray(latitude, dtype="float64"), np.asarray(longitude, dtype="float64"),
        np.asarray(altitude, dtype="float64"),
    )
    shape = latitude.shape
    from pvlib import spa  # at first use: pvlib and what it imports (requests, h5py) take 0.3 s

    result = spa.solar_position(
        np.array([_unix_seconds(time)]), latitude.ravel(), longitude.ravel(), altitude.ravel(),
        _PRESSURE_HPA, _TEMPERATURE_C, _DELTA_T_S, _REFRACTION_AT_HORIZON_DEG,
    )
    apparent_zenith, geometric_zenith, azimuth = result[0], result[1], result[4]
    zenith = apparent_zenith if refraction else geometric_zenith
    return np.reshape(zenith, shape), np.reshape(np.mod(azimuth, 360.0), shape)


def _solar_block(block_info, *, time, transform, transformer, altitude, refraction):
    (row0, row1), (col0, col1) = block_info[None]["array-location"][1:]  # skip the (2,) axis
    x, y = pixel_centres(transform, row0, col0, (row1 - row0, col1 - col0))
    longitude, latitude = transformer.transform(x, y)
    return np.stack(solar_position(time, latitude, longitude, altitude, refraction))


def solar_angles(time, like: xr.DataArray, *, altitude=0.0, refraction: bool = False,
                 chunks=None) -> xr.Dataset:
    """Solar zenith and azimuth for every pixel of a georeferenced grid, lazily.

    Parameters
    ----------
    time : str, datetime or pandas.Timestamp
        Acquisition time, timezone-aware. One time for the whole scene: a push-broom or
        whisk-broom scene takes seconds to a minute, in which the sun moves by less than 0.25 deg.
    like : xarray.DataArray
        Image or template with dims (y, x) (others ignored), a CRS and a transform.
    altitude : float
        Height above the ellipsoid [m] (effect below 0.001 deg for terrestrial heights).
    refraction : bool
        See :func:`solar_position`.
    chunks :
        Output chunks; default ``like``'s, else 2048.

    Returns
    -------
    xarray.Dataset
        ``sza`` and ``saa`` [deg] on (y, x), dask-backed.
    """
    plane = like.isel({dim: 0 for dim in like.dims if dim not in ("y", "x")}).transpose("y", "x")
    transform, crs, shape = _grid_of(plane, "the image grid (like)")
    if crs is None:
        raise SensorInputError("solar angles need pixel coordinates: the image grid has no CRS")
    transformer = Transformer.from_crs(crs, CRS.from_epsg(4326), always_xy=True)
    _unix_seconds(time)  # refuse a naive time now rather than inside a dask task
    if chunks is None:
        chunks = plane.data.chunks if isinstance(plane.data, da.Array) else GRID_CHUNK
    template = da.empty(shape, chunks=chunks)
    both = da.map_blocks(
        _solar_block, dtype="float64", chunks=((2,),) + template.chunks,
        meta=np.empty((0, 0, 0)), time=time, transform=transform, transformer=transformer,
        altitude=altitude, refraction=refraction,
    )
    coords = {"y": plane["y"], "x": plane["x"]}
    angles = xr.Dataset(
        {
            "sza": xr.DataArray(both[0], dims=("y", "x"), coords=coords,
                                attrs={"units": "degree", "long_name": "solar zenith angle"}),
            "saa": xr.DataArray(both[1], dims=("y", "x"), coords=coords, attrs={
                "units": "degree",
                "long_name": "solar azimuth angle (pixel to sun, clockwise from north)"}),
        },
        attrs={"source_kind": "solar", "time": str(pd.Timestamp(time)),
               "algorithm": "NREL SPA (pvlib.spa)"},
    )
    return angles.rio.write_crs(crs).rio.write_transform(transform)
