"""Surface orientation: slope and aspect from a DEM, sun and view angles in a tilted surface's frame.

Conventions (``docs/conventions.md``, "Tilted surfaces"): all angles in degrees. ``slope`` is the
angle between the surface normal and the vertical, in [0, 90]; ``aspect`` is the azimuth, clockwise
from north, of the direction the surface faces (its downslope direction, the horizontal part of its
normal), the convention documented for the AVIRIS-NG/-3 ``obs_ort`` "Slope" and "Aspect" bands.
What was checked against real files (``docs/terrain.md``, ``tests/correction/test_terrain.py``): the
"Cosine(i)" band of ang20170323t202244 equals :func:`cos_incidence` to 2.2e-16, but its Slope and
Aspect are placeholders (90 deg, 0 deg) that cannot tell an aspect from its mirror; on the
topoflux line the band matches no aspect convention (the file is inconsistent in itself). In the
east-north-up frame the unit vectors are::

    normal       n = (sin s sin A,  sin s cos A,  cos s)          (slope s, aspect A)
    to the sun   i = (sin ti sin saa, sin ti cos saa, cos ti)
    to sensor    r = (sin tr sin vaa, sin tr cos vaa, cos tr)

The local frame of a tilted surface is the east-north-up frame rotated about the horizontal axis
``z x n`` by the slope, so that ``n`` becomes the local vertical. Local zeniths are the angles of
``i`` and ``r`` from ``n``; local azimuths are measured in the tilted plane from the image of north
(for a horizontal surface the local frame is the horizontal one). BRDF models depend only on the
two local zeniths and the local relative azimuth, which do not depend on that choice.

References
----------
.. [1] B. K. P. Horn (1981): Hill shading and the reflectance map. Proc. IEEE 69(1), 14-47.
.. [2] P. M. Teillet, B. Guindon, D. G. Goodenough (1982): On the slope-aspect correction of
   multispectral scanner data. Can. J. Remote Sens. 8(2), 84-106.
"""

from __future__ import annotations

from typing import NamedTuple

import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr._arrays import array_function, cosd, sind
from brdfcorr.errors import InputError
from brdfcorr.io.grid import refuse_gcps
from brdfcorr.io.writer import local_scheduler

__all__ = [
    "LocalAngles",
    "SlopeAspect",
    "check_slope_aspect",
    "check_dem_slope",
    "cos_incidence",
    "local_angles",
    "slope_aspect",
    "slope_aspect_layers",
]


class SlopeAspect(NamedTuple):
    """Surface orientation per pixel: ``slope`` [deg] in [0, 90] and ``aspect`` [deg] in [0, 360)."""

    slope: xr.DataArray
    aspect: xr.DataArray


class LocalAngles(NamedTuple):
    """Sun and view angles in a tilted surface's frame [deg] (module docstring)."""

    sza: object
    saa: object
    vza: object
    vaa: object


def _unit(zenith, azimuth):
    """East, north, up components of the unit vector at (zenith, azimuth) [deg]."""
    sin_z = sind(zenith)
    return sin_z * sind(azimuth), sin_z * cosd(azimuth), cosd(zenith)


def _angles_of(east, north, up):
    """Zenith [deg] in [0, 180] and azimuth [deg] in [0, 360) of a vector."""
    zenith = np.degrees(np.arctan2(np.hypot(east, north), up))
    azimuth = np.degrees(np.arctan2(east, north)) % 360.0
    return zenith, azimuth


def _rotation(slope, aspect):
    """The rotation taking the surface normal to the vertical, as (k_east, k_north, cos, sin): the
    rotation about the horizontal unit axis ``k = z x n / |z x n| = (-cos A, sin A, 0)`` (perpendicular
    to the aspect) by ``-slope``."""
    return -cosd(aspect), sind(aspect), cosd(slope), -sind(slope)


def _to_local(zenith, azimuth, rotation):
    """One direction rotated into the surface frame (Rodrigues' rotation formula)."""
    k_east, k_north, cos_s, sin_s = rotation
    east, north, up = _unit(zenith, azimuth)
    k_dot_v = k_east * east + k_north * north
    # v cos s + (k x v) sin s + k (k.v)(1 - cos s); k x v = (k_n up, -k_e up, k_e north - k_n east)
    new_east = east * cos_s + k_north * up * sin_s + k_east * k_dot_v * (1.0 - cos_s)
    new_north = north * cos_s - k_east * up * sin_s + k_north * k_dot_v * (1.0 - cos_s)
    new_up = up * cos_s + (k_east * north - k_north * east) * sin_s
    return _angles_of(new_east, new_north, new_up)


def _local_angles(sza, saa, vza, vaa, slope, aspect):
    rotation = _rotation(slope, aspect)
    local_sza, local_saa = _to_local(sza, saa, rotation)
    local_vza, local_vaa = _to_local(vza, vaa, rotation)
    # A horizontal surface's frame is the horizontal one: its angles are returned exactly as given,
    # so that slope 0 reproduces the horizontal correction bit for bit.
    flat = slope == 0
    angles = (np.where(flat, sza, local_sza), np.where(flat, saa, local_saa),
              np.where(flat, vza, local_vza), np.where(flat, vaa, local_vaa))
    return LocalAngles(*np.broadcast_arrays(*angles))


def local_angles(sza, saa, vza, vaa, slope, aspect) -> LocalAngles:
    """Sun and view angles in the frame of a tilted surface.

    Parameters
    ----------
    sza, saa : array-like
        Solar zenith and azimuth (pixel towards the sun, clockwise from north) [deg].
    vza, vaa : array-like
        View zenith and azimuth (pixel towards the sensor, clockwise from north) [deg].
    slope : array-like
        Surface slope [deg], in [0, 90].
    aspect : array-like
        Azimuth of the direction the surface faces (downslope), clockwise from north [deg].

    Returns
    -------
    LocalAngles
        ``(sza, saa, vza, vaa)`` in the surface's frame [deg]; zeniths in [0, 180] (>= 90: the sun
        or the sensor is behind the surface), azimuths in [0, 360) from the image of north in the
        tilted plane (module docstring). Where ``slope == 0`` the inputs are returned unchanged.
        numpy, dask (lazy) or xarray like the inputs.

    Notes
    -----
    Each direction is rotated by Rodrigues' formula about the horizontal axis perpendicular to the
    aspect by the slope, the rotation that takes the surface normal to the vertical. The local sun
    zenith is the incidence angle of Teillet et al. 1982 [2]_, eq. 1 (:func:`cos_incidence`).
    Examples: a roof of slope 20 deg facing the sun (aspect = saa) under a sun at 40 deg has the
    sun at 20 deg in its frame, and a nadir sensor at 20 deg on the other side (relative azimuth
    180): the specular geometry.
    """
    arguments = {"sza": sza, "saa": saa, "vza": vza, "vaa": vaa, "slope": slope, "aspect": aspect}
    labelled = [key for key, value in arguments.items() if isinstance(value, xr.DataArray)]
    if not labelled:
        return _local_angles(**arguments)
    results = xr.apply_ufunc(
        lambda *values: tuple(_local_angles(**{**arguments, **dict(zip(labelled, values))})),
        *(arguments[key] for key in labelled), dask="allowed", keep_attrs=False, output_core_dims=[[]] * 4,
    )
    names = ("sza", "saa", "vza", "vaa")
    long_names = ("local solar zenith angle", "local solar azimuth angle", "local view zenith angle",
                  "local view azimuth angle")
    out = []
    for result, name, long_name in zip(results, names, long_names):
        result.name = f"local_{name}"
        result.attrs = {"units": "degree", "long_name": long_name}
        out.append(result)
    return LocalAngles(*out)


@array_function("cos_i", "1", "cosine of the local solar incidence angle")
def cos_incidence(sza, saa, slope, aspect):
    """Cosine of the solar incidence angle on a tilted surface (cos i).

    Parameters
    ----------
    sza, saa : array-like
        Solar zenith and azimuth (pixel towards the sun, clockwise from north) [deg].
    slope, aspect : array-like
        Surface slope [deg] and the azimuth it faces (downslope, clockwise from north) [deg].

    Returns
    -------
    cos_i : array-like
        ``cos i`` [-], in [-1, 1]; <= 0 where the surface is self-shadowed.

    Notes
    -----
    Teillet et al. 1982 [2]_, eq. 1::

        cos i = cos sza cos s + sin sza sin s cos(saa - A)
    """
    return cosd(sza) * cosd(slope) + sind(sza) * sind(slope) * cosd(saa - aspect)


def _pixel_size(dem: xr.DataArray, pixel_size) -> tuple[float, float]:
    """(dx, dy) [m]: east per column and north per row (dy < 0 when rows go south); from the
    transform in the CRS's linear unit, converted to metres."""
    if pixel_size is not None:
        if np.ndim(pixel_size) == 0:
            return float(pixel_size), -float(pixel_size)
        dx, dy = (float(v) for v in pixel_size)
        return dx, dy
    try:
        import rioxarray  # noqa: F401  (registers the .rio accessor)

        transform = dem.rio.transform()
        crs = dem.rio.crs
    except Exception as error:  # no georeference rioxarray can read
        raise InputError(f"DEM: no pixel size (give pixel_size): {error}") from error
    if crs is None:
        raise InputError("DEM: no CRS, so no pixel size in metres; write its projected CRS into the file "
                         "(in Python: pixel_size=(dx, dy))")
    if crs.is_geographic:
        raise InputError(f"DEM: CRS {crs} is geographic (degrees); reproject it to metres first")
    refuse_gcps(dem, "DEM", "its slope (the pixel size in metres)", "give pixel_size=(dx, dy) in Python")
    if transform.b != 0 or transform.d != 0:
        raise InputError(f"DEM: rotated grid (transform {tuple(transform)[:6]}) is not supported")
    unit = _metres_per_unit(crs)
    metres = unit / _metres_per_height_unit(crs)  # ground distance in the heights' unit
    east, north = _map_scale(crs, transform, dem.shape[-2:], unit)
    return float(transform.a) * metres / east, float(transform.e) * metres / north


#: A projection whose scale lies within this of 1 [-] is taken to give ground metres, as gdaldem
#: takes them (UTM: 0.9996-1.001, state planes: 1 +- 1e-4).
SCALE_TOLERANCE = 0.01
#: The most a projection's scale may vary across a DEM [-]: beyond it, one pixel size in ground
#: metres does not serve the whole DEM (Web Mercator over 100 km at 52 N: 2 %).
MAX_SCALE_VARIATION = 0.02


def _map_scale(crs, transform, shape: tuple[int, ...], metres_per_unit: float) -> tuple[float, float]:
    """Map length per ground length [-] along the grid's columns and rows at the DEM's centre:
    a pixel's step in map metres over its geodesic length (pyproj's ``Geod``), which holds in any
    projection, conformal or not (MODIS sinusoidal's curved meridians), where it departs from 1 by
    more than :data:`SCALE_TOLERANCE`, else 1: 1/cos(latitude) in Web Mercator (1.62 at 52 N,
    where its map metres taken as ground metres made slopes of 16.7 deg 10.5 deg). 1 in a local
    CRS, which has no geodetic CRS to measure by.

    Raises
    ------
    InputError
        The scale varies by more than :data:`MAX_SCALE_VARIATION` across the DEM (centre and
        corners), or cannot be measured."""
    from pyproj import CRS, Transformer

    horizontal = CRS.from_user_input(crs.to_wkt()).to_2d()
    geodetic = horizontal.geodetic_crs
    geod = None if geodetic is None else geodetic.get_geod()
    if geodetic is None or geod is None:
        return 1.0, 1.0
    to_lonlat = Transformer.from_crs(horizontal, geodetic, always_xy=True)
    rows, cols = shape
    at = (np.array([cols / 2, 0.5, cols - 0.5, 0.5, cols - 0.5]),  # the centre and the corner pixels
          np.array([rows / 2, 0.5, 0.5, rows - 0.5, rows - 0.5]))
    scales = []
    for step, size in (((0.5, 0.0), abs(transform.a)), ((0.0, 0.5), abs(transform.e))):
        start = to_lonlat.transform(*(transform * (at[0] - step[0], at[1] - step[1])))
        end = to_lonlat.transform(*(transform * (at[0] + step[0], at[1] + step[1])))
        scales.append(size * metres_per_unit / np.asarray(geod.inv(*start, *end)[2]))
    east, north = scales
    spread = max(np.ptp(east) / east[0], np.ptp(north) / north[0])
    if not spread <= MAX_SCALE_VARIATION:
        raise InputError(f"DEM: the scale of its projection ({horizontal.name}) varies by {spread:.1%} across it, or "
                         "cannot be measured: no one pixel size in ground metres; reproject it to a local projection "
                         "(UTM: gdalwarp -t_srs EPSG:326..)")
    if max(abs(east[0] - 1.0), abs(north[0] - 1.0)) <= SCALE_TOLERANCE:
        return 1.0, 1.0
    return float(east[0]), float(north[0])


def _metres_per_height_unit(crs) -> float:
    """Metres per unit of the elevations: the vertical unit of a compound CRS (a US LiDAR DEM in
    EPSG:2263+6360 gives heights in US survey feet: taken as metres, its slopes came out 3.3 times
    too steep in tangent, 30 deg for 10), else 1 (elevations in metres, ``docs/terrain.md``)."""
    from pyproj import CRS

    vertical = [sub for sub in CRS.from_user_input(crs.to_wkt()).sub_crs_list if sub.is_vertical]
    if not vertical:
        return 1.0
    factor = vertical[0].axis_info[0].unit_conversion_factor
    if not (np.isfinite(factor) and factor > 0):
        raise InputError(f"DEM: the vertical CRS of {crs} has the unit {vertical[0].axis_info[0].unit_name!r} "
                         f"of {factor} m; give the elevations in metres")
    return float(factor)


def _metres_per_unit(crs) -> float:
    """Metres per unit of a projected (or local) CRS's axes: the pixel size in metres for elevations
    in metres (US survey feet: 0.3048006; a foot-based grid read as metres gave slopes 3.3 times too
    flat, 1.75 deg for 5.71)."""
    try:
        unit, factor = crs.linear_units_factor if crs.is_projected else crs.units_factor
    except (ValueError, AttributeError) as error:  # rasterio's CRSError: no unit to be found
        raise InputError(f"DEM: CRS {crs} names no linear unit, so no pixel size in metres; give "
                         f"pixel_size=(dx, dy) in Python ({error})") from None
    if not (np.isfinite(factor) and factor > 0):
        raise InputError(f"DEM: CRS {crs} has the linear unit {unit!r} of {factor} m; give pixel_size=(dx, dy) "
                         "in Python")
    return float(factor)


def _odd_pad(z, axis: int):
    """Pad one line on each side along ``axis`` with linear extrapolation ``2 z0 - z1``, so that the
    central differences at the edge become one-sided ones (exact for planes)."""
    xp = da if isinstance(z, da.Array) else np
    n = z.shape[axis]
    first = 2.0 * xp.take(z, [0], axis=axis) - xp.take(z, [1], axis=axis)
    last = 2.0 * xp.take(z, [n - 1], axis=axis) - xp.take(z, [n - 2], axis=axis)
    return xp.concatenate([first, z, last], axis=axis)


def _horn(z, dx: float, dy: float):
    """Slope and aspect [deg] of a 2-D elevation array by Horn's 3x3 finite differences."""
    z = _odd_pad(_odd_pad(z.astype(np.float64), 0), 1)
    # The 3x3 window  a b c / d e f / g h i  around each pixel (rows downwards, columns rightwards).
    a, b, c = z[:-2, :-2], z[:-2, 1:-1], z[:-2, 2:]
    d, f = z[1:-1, :-2], z[1:-1, 2:]
    g, h, i = z[2:, :-2], z[2:, 1:-1], z[2:, 2:]
    dz_dcol = ((c + 2.0 * f + i) - (a + 2.0 * d + g)) / 8.0
    dz_drow = ((g + 2.0 * h + i) - (a + 2.0 * b + c)) / 8.0
    dz_deast, dz_dnorth = dz_dcol / dx, dz_drow / dy
    # Horn's window leaves out its centre: a pixel without an elevation had a slope of its neighbours'.
    slope = np.where(np.isfinite(z[1:-1, 1:-1]), np.degrees(np.arctan(np.hypot(dz_deast, dz_dnorth))), np.nan)
    # The surface faces downslope: its normal's horizontal part is (-dz/de, -dz/dn).
    aspect = np.degrees(np.arctan2(-dz_deast, -dz_dnorth)) % 360.0
    return slope, np.where(slope == 0, 0.0, np.where(np.isnan(slope), np.nan, aspect))


def slope_aspect(dem, *, pixel_size: float | tuple[float, float] | None = None) -> SlopeAspect:
    """Slope and aspect [deg] of a DEM or surface model on the image grid (Horn 1981).

    Parameters
    ----------
    dem : xarray.DataArray (y, x) or array-like
        Elevation [m] on the image grid; numpy or dask backed (stays lazy). A single-band (1, y, x)
        raster is accepted.
    pixel_size : float or (dx, dy), optional
        Ground distance [m] per column (east) and per row (north; negative when rows go south, as
        in a north-up raster). A single number d means (d, -d). By default from the raster's
        transform (``dem.rio.transform()``: ``a`` and ``e``) in its CRS's linear unit, converted to
        metres (a CRS in US survey feet, EPSG:2263: x 0.3048006); required for arrays without one.
        Elevations are in metres, or in the vertical unit of a compound CRS (EPSG:2263+6360:
        heights in US survey feet), to which the pixel size is then converted.

    Returns
    -------
    SlopeAspect
        ``(slope, aspect)`` DataArrays (y, x) [deg] with the DEM's coords: slope in [0, 90],
        aspect (direction faced, downslope, clockwise from north) in [0, 360); 0 on flat ground.
        NaN in the DEM makes the 3x3 neighbourhood NaN.

    Raises
    ------
    InputError
        No pixel size (no CRS or a geographic one, a CRS without a linear unit, a rotated grid), or
        a grid under 2 x 2.

    Notes
    -----
    Horn 1981 [1]_, eqs. in section III.B: with the 3x3 window ``a b c / d e f / g h i`` (rows
    downwards)::

        dz/dcol = ((c + 2f + i) - (a + 2d + g)) / 8,     dz/drow = ((g + 2h + i) - (a + 2b + c)) / 8
        p = dz/dcol / dx,   q = dz/drow / dy             (east and north gradients)
        slope = arctan(sqrt(p^2 + q^2)),   aspect = atan2(-p, -q)  (clockwise from north)

    Edge pixels use a window extended by linear extrapolation (``2 z0 - z1``), which turns the
    central differences into one-sided ones: exact for planes, so a planar roof or slope has the
    same slope and aspect up to the image border.
    """
    if not isinstance(dem, xr.DataArray):
        array = dem if isinstance(dem, da.Array) else np.asarray(dem)
        dem = xr.DataArray(array, dims=("band", "y", "x")[-array.ndim:] if array.ndim <= 3 else None)
    if dem.ndim == 3 and dem.shape[0] == 1:
        dem = dem.isel({dem.dims[0]: 0}, drop=True)
    if dem.ndim != 2:
        raise InputError(f"DEM must be 2-D (y, x), got dims {dem.dims}")
    if min(dem.shape) < 2:
        raise InputError(f"DEM of shape {dem.shape} is too small for 3x3 differences (at least 2 x 2)")
    dx, dy = _pixel_size(dem, pixel_size)
    if not (np.isfinite(dx) and np.isfinite(dy) and dx != 0 and dy != 0):
        raise InputError(f"DEM pixel size ({dx}, {dy}) must be finite and non-zero")
    data = dem.data
    slope, aspect = _horn(data, dx, dy)
    if isinstance(data, da.Array):
        slope, aspect = slope.rechunk(data.chunks), aspect.rechunk(data.chunks)
    coords = {k: v for k, v in dem.coords.items() if set(v.dims) <= set(dem.dims)}
    return SlopeAspect(
        xr.DataArray(slope, dims=dem.dims, coords=coords, name="slope",
                     attrs={"units": "degree", "long_name": "surface slope (Horn 1981)"}),
        xr.DataArray(aspect, dims=dem.dims, coords=coords, name="aspect",
                     attrs={"units": "degree", "long_name": "surface aspect (downslope, clockwise from north)"}),
    )


def check_slope_aspect(surface: SlopeAspect, source: str, *, scheduler: str | None = None,
                       num_workers: int | None = None) -> None:
    """Check that slope and aspect layers read from a file hold degrees, in one pass over them.

    Pixels outside the domain are not an error here (:func:`brdfcorr.normalize` flags a slope
    outside [0, 90] ``invalid_geometry`` and writes nodata); layers that cannot be degrees are:
    every slope at most pi/2 with every aspect in [-pi, 2 pi] and spread over more than 1
    (radians), no slope in [0, 90] at all, or no aspect in [-360, 360] at all (scaled or other
    units: every pixel would be nodata), or a layer without a single finite value (all NaN or inf:
    every pixel would be nodata too).

    Parameters
    ----------
    surface : SlopeAspect
        ``(slope, aspect)`` [deg] (y, x), numpy or dask backed.
    source : str
        What they were read from, for messages (``"slope/aspect file slope.tif"``).
    scheduler, num_workers : optional
        dask scheduler of the pass and its number of workers (as for :func:`dask.compute`).

    Raises
    ------
    InputError
        ``{source}: ...`` with the ranges found.
    """
    per_block = _block_statistics(surface, scheduler, num_workers)
    finite, in_domain = per_block[..., 2].sum(axis=0), per_block[..., 3].sum(axis=0)
    for index, name in enumerate(("slope", "aspect")):
        if not finite[index]:
            raise InputError(f"{source}: no finite {name} value (all NaN, inf or nodata): nothing could be "
                             "corrected")
    low, high = np.nanmin(per_block[..., 0], axis=0), np.nanmax(per_block[..., 1], axis=0)
    found = f"slope {low[0]:.6g}..{high[0]:.6g}, aspect {low[1]:.6g}..{high[1]:.6g}"
    if high[0] <= np.pi / 2 + 0.03 and low[1] >= -np.pi - 0.03 and high[1] <= 2 * np.pi + 0.03 and high[1] - low[1] > 1:
        raise InputError(f"{source}: slope and aspect look like radians ({found}); brdfcorr needs degrees")
    for index, (name, domain) in enumerate((("slope", "[0, 90]"), ("aspect", "[-360, 360]"))):
        if not in_domain[index]:
            raise InputError(f"{source}: no {name} value in {domain} deg (found {found}); are slope and aspect "
                             "scaled or in other units? (Every pixel would be nodata.)")


def check_dem_slope(surface: SlopeAspect, dem: str, *, scheduler: str | None = None,
                    num_workers: int | None = None) -> None:
    """Check that slope and aspect computed from a DEM (:func:`slope_aspect`) leave something to
    correct, in one pass over the DEM: at least one pixel with a finite slope.

    A pixel's slope is NaN where its 3x3 neighbourhood holds nodata (NaN) or an infinite elevation
    (Horn's differences, :func:`slope_aspect`), so a DEM of nodata only, or one whose valid pixels
    are all isolated, has no slope anywhere and :func:`brdfcorr.normalize` would write every pixel
    as nodata. Their units need no check (degrees by construction), unlike those of
    :func:`check_slope_aspect`.

    Parameters
    ----------
    surface : SlopeAspect
        ``(slope, aspect)`` [deg] (y, x) of :func:`slope_aspect`, numpy or dask backed.
    dem : str
        The DEM, for messages (``"DEM file dem.tif"``).
    scheduler, num_workers : optional
        dask scheduler of the pass and its number of workers (as for :func:`dask.compute`).

    Raises
    ------
    InputError
        ``{dem}: no pixel has a slope ...``.
    """
    per_block = _block_statistics(surface, scheduler, num_workers)
    if not per_block[:, 0, 2].sum():
        raise InputError(f"{dem}: no pixel has a slope: every 3x3 neighbourhood holds nodata, NaN or inf (a DEM of "
                         "nodata only?); nothing could be corrected")


def _block_statistics(surface: SlopeAspect, scheduler: str | None, num_workers: int | None) -> np.ndarray:
    """(blocks, 2, 4): :func:`_surface_statistics` of each block of slope and aspect, in one pass."""
    slope = surface.slope.data
    aspect = surface.aspect.data
    if isinstance(slope, da.Array) or isinstance(aspect, da.Array):
        slope = da.asarray(slope)
        aspect = da.asarray(aspect).rechunk(slope.chunks)
        per_block = da.map_blocks(_surface_statistics, slope, aspect, new_axis=[2, 3], chunks=(1, 1, 2, 4),
                                  dtype=np.float64)
        per_block = per_block.compute(scheduler=local_scheduler(scheduler), num_workers=num_workers)
    else:
        per_block = _surface_statistics(np.asarray(slope), np.asarray(aspect))
    return np.asarray(per_block).reshape(-1, 2, 4)


def _surface_statistics(slope: np.ndarray, aspect: np.ndarray) -> np.ndarray:
    """(1, 1, 2, 4): min, max, finite count and count in the domain ([0, 90], [-360, 360]) of a
    (y, x) block of slope and of aspect."""
    result = np.empty((1, 1, 2, 4))
    for index, (block, low, high) in enumerate(((slope, 0.0, 90.0), (aspect, -360.0, 360.0))):
        values = block[np.isfinite(block)]
        result[0, 0, index, :2] = (values.min(), values.max()) if values.size else (np.nan, np.nan)
        result[0, 0, index, 2:] = values.size, np.count_nonzero((values >= low) & (values <= high))
    return result


def slope_aspect_layers(raster: xr.DataArray) -> SlopeAspect:
    """Slope and aspect [deg] from a 2-band raster (band, y, x).

    Band descriptions (``long_name`` attr, as rioxarray reads them) naming ``slope`` and ``aspect``
    (case-insensitive, anywhere in the name) decide which band is which; without such names the
    order is slope, aspect.

    Raises
    ------
    InputError
        Not 2 bands, or names that do not give each of slope and aspect once.
    """
    if raster.ndim != 3 or raster.shape[0] != 2:
        raise InputError(f"slope/aspect raster must have 2 bands (band, y, x), got shape {raster.shape}")
    names = raster.attrs.get("long_name")
    order = (0, 1)
    if isinstance(names, (tuple, list)) and len(names) == 2:
        lowered = [str(name).lower() for name in names]
        found = {key: [i for i, name in enumerate(lowered) if key in name] for key in ("slope", "aspect")}
        if any(found.values()):
            if sorted(len(v) for v in found.values()) != [1, 1] or found["slope"] == found["aspect"]:
                raise InputError(f"slope/aspect raster: band names {tuple(names)} must name slope and aspect once")
            order = (found["slope"][0], found["aspect"][0])
    band = raster.dims[0]
    layers = []
    for index, name in zip(order, ("slope", "aspect")):
        layer = raster.isel({band: index}, drop=True).rename(name)
        layer.attrs = {"units": "degree", "long_name": f"surface {name}"}
        layers.append(layer)
    return SlopeAspect(*layers)
