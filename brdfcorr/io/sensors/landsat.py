"""Landsat Collection 2 angles: the per-pixel angle bands and the angle coefficient file (ANG.txt).

Collection 2 Level-1 products (and some Level-2 deliveries) include four angle bands, GeoTIFFs
named ``<product id>_SZA.TIF``, ``_SAA.TIF``, ``_VZA.TIF``, ``_VAA.TIF`` (band 4 geometry), holding
the angles as scaled integers in hundredths of a degree; azimuths in [-180, 180]. Every product
also carries ``<product id>_ANG.txt``, the angle coefficient file: ephemeris, solar vectors, and per
band the scene-mean sun and satellite vectors in the local (east, north, up) frame.

Conventions: the USGS angle tools compute the satellite and sun vectors from the target (pixel)
towards the satellite and the sun, so the stored azimuths are "to sensor" and "to sun" as brdfcorr
wants them (``docs/conventions.md``). On the real scene in ``shared/realdata`` the ANG.txt band-1 mean sun
vector gives the sun azimuth of pvlib's SPA at the scene centre to 0.01 deg with ``atan2(east,
north)``, confirming the (east, north, up) frame. ``view_azimuth="from_sensor"`` flips explicitly for
a product that differs.

Level-2 deliveries often carry only some angle bands (the scene in ``shared/realdata`` has only
SZA). With the ANG.txt, missing solar angles are computed with pvlib at the scene time, and missing
view angles, on request, from the ANG.txt ephemeris with a geometric scan-plane model
(:func:`ang_angles`) or as the scene mean.

References
----------
.. [1] USGS: Landsat Collection 2 Level-1 Data Format Control Book (LSDS-1656), angle bands.
.. [2] USGS: Solar Illumination and Sensor Viewing Angle Coefficient Files (ANG.txt).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

import dask.array as da
import numpy as np
import pandas as pd
import rasterio
import rioxarray
import xarray as xr
from pyproj import CRS, Transformer

from brdfcorr.errors import SensorInputError
from brdfcorr.io.files import read_regular
from brdfcorr.io.grid import grid_difference
from brdfcorr.io.sensors.grids import GRID_CHUNK, _grid_of, pixel_centres, to_grid, wrap_azimuth
from brdfcorr.io.sensors.solar import solar_angles

if TYPE_CHECKING:
    from scipy.interpolate import CubicSpline

__all__ = [
    "ANGLE_SCALE",
    "ANGLE_SUFFIXES",
    "HUNDREDTHS",
    "check_hundredths",
    "ang_angles",
    "ang_mean_angles",
    "ang_scene_time",
    "find_angle_bands",
    "find_ang_txt",
    "parse_ang_txt",
    "read_landsat_angles",
    "vector_angles",
]

#: Angle bands store hundredths of a degree (USGS C2 Level-1 DFCB).
ANGLE_SCALE = 0.01
#: The range of each angle band [hundredths of a degree]: zeniths in [0, 90] deg, azimuths in
#: [-180, 180] deg (USGS) or [0, 360) deg.
HUNDREDTHS = {"sza": (0, 9000), "vza": (0, 9000), "saa": (-18000, 36000), "vaa": (-18000, 36000)}
#: File-name suffixes of the four angle bands.
ANGLE_SUFFIXES = {"sza": "_SZA", "saa": "_SAA", "vza": "_VZA", "vaa": "_VAA"}

LONG_NAMES = {
    "sza": "solar zenith angle",
    "saa": "solar azimuth angle (pixel to sun, clockwise from north)",
    "vza": "view zenith angle",
    "vaa": "view azimuth angle (pixel to sensor, clockwise from north)",
}


# --- ANG.txt --------------------------------------------------------------------------------------

def _odl_value(text: str):
    text = text.strip()
    if text.startswith("("):
        return tuple(_odl_value(item) for item in text.strip("()").split(",") if item.strip())
    if text.startswith('"'):
        return text.strip('"')
    try:
        return float(text)
    except ValueError:
        return text


def parse_ang_txt(path: str | Path) -> dict[str, dict]:
    """Parse an ANG.txt (ODL: ``GROUP = name`` ... ``END_GROUP``, ``KEY = value``) into
    ``{group: {key: value}}``; tuples, possibly continued over lines, become tuples of floats."""
    path = Path(path)
    # A regular file only (a FIFO would block); ODL is ASCII: a stray byte is shown, not fatal.
    lines = read_regular(path, "the angle coefficient file", SensorInputError).decode("utf-8", "replace").splitlines()
    groups: dict[str, dict] = {}
    current: dict | None = None
    pending = ""
    for number, line in enumerate(lines, start=1):
        pending = f"{pending} {line.strip()}" if pending else line.strip()
        if pending.count("(") > pending.count(")"):
            continue  # a tuple continued on the next line
        statement, pending = pending, ""
        if not statement or statement == "END":
            continue
        key, separator, value = statement.partition("=")
        if not separator:
            raise SensorInputError(f"{path}: line {number}: expected 'KEY = value', got {statement!r}")
        key, value = key.strip(), value.strip()
        if key == "GROUP":
            current = groups.setdefault(value, {})
        elif key == "END_GROUP":
            current = None
        elif current is None:
            raise SensorInputError(f"{path}: line {number}: {key} outside any GROUP")
        else:
            current[key] = _odl_value(value)
    if not groups:
        raise SensorInputError(f"{path}: no GROUP in the angle coefficient file")
    return groups


def _item(ang: dict, group: str, key: str, path="ANG.txt"):
    try:
        return ang[group][key]
    except KeyError:
        raise SensorInputError(f"{path}: no {key} in group {group}") from None


def ang_scene_time(ang: dict, source: str | Path = "ANG.txt") -> pd.Timestamp:
    """Scene-centre UTC time from an ANG.txt: the middle of the solar-vector sample times.

    The Collection-2 files at hand give the sample times as seconds of the day, the first at
    ``SOLAR_EPOCH_SECONDS``; USGS's own reader of the format calls them offsets from that epoch.
    Both are read, by the first sample: at the epoch (within :data:`_SLACK`), seconds of the day;
    at 0, offsets from the epoch (read as seconds of the day, they put the sun at midnight, its
    azimuth ~180 deg off). A first sample at neither is an error."""
    year, day = (_samples(ang, "SOLAR_VECTOR", key, source) for key in ("SOLAR_EPOCH_YEAR", "SOLAR_EPOCH_DAY"))
    seconds = _samples(ang, "SOLAR_VECTOR", "SAMPLE_TIME", source)
    if year.size != 1 or day.size != 1 or not 1 <= day[0] <= 366 or not 1900 <= year[0] <= 2200:
        raise SensorInputError(f"{source}: SOLAR_VECTOR SOLAR_EPOCH_YEAR {year.tolist()} and SOLAR_EPOCH_DAY "
                               f"{day.tolist()} are no year and day of the year")
    middle = float(np.mean(seconds))
    if "SOLAR_EPOCH_SECONDS" in ang["SOLAR_VECTOR"]:
        epoch = float(_samples(ang, "SOLAR_VECTOR", "SOLAR_EPOCH_SECONDS", source)[0])
        if abs(seconds[0] - epoch) > _SLACK:
            if abs(seconds[0]) > _SLACK:
                raise SensorInputError(
                    f"{source}: SOLAR_VECTOR SAMPLE_TIME starts at {seconds[0]:g} s, neither at SOLAR_EPOCH_SECONDS "
                    f"({epoch:g} s, seconds of the day) nor at 0 (offsets from it): the acquisition time is unknown")
            middle += epoch  # offsets from the epoch
    return pd.Timestamp(year=int(year[0]), month=1, day=1, tz="UTC") + pd.Timedelta(days=int(day[0]) - 1,
                                                                                     seconds=middle)


#: How far [s] an ANG.txt's first sample time may lie from its epoch, or from 0 for offsets
#: (:func:`ang_scene_time`).
_SLACK = 60.0


def vector_angles(east, north, up):
    """Zenith and azimuth [deg] of a direction given in the local (east, north, up) frame.

    Returns ``zenith = atan2(hypot(east, north), up)`` and ``azimuth = atan2(east, north)``
    clockwise from north in [0, 360). The vector need not be normalized.
    """
    zenith = np.degrees(np.arctan2(np.hypot(east, north), up))
    return zenith, wrap_azimuth(np.degrees(np.arctan2(east, north)))


def ang_mean_angles(ang: dict, band: int = 4) -> dict[str, float]:
    """Scene-mean sun and view angles [deg] of one band from an ANG.txt (mean sun and satellite
    vectors, both pointing from the scene towards the sun/satellite, in (east, north, up))."""
    group = f"RPC_BAND{band:02d}"
    if group not in ang:
        bands = sorted(int(name[-2:]) for name in ang if name.startswith("RPC_BAND"))
        raise SensorInputError(f"ANG.txt: no group {group}; bands present: {bands}")
    sza, saa = vector_angles(*_item(ang, group, f"BAND{band:02d}_MEAN_SUN_VECTOR"))
    vza, vaa = vector_angles(*_item(ang, group, f"BAND{band:02d}_MEAN_SAT_VECTOR"))
    return {"sza": float(sza), "saa": float(saa), "vza": float(vza), "vaa": float(vaa)}


#: Earth rotation rate [rad/s] (WGS 84).
EARTH_ROTATION = 7.292115e-5


def _enu_basis(longitude_deg, latitude_deg):
    """East, north and up unit vectors (ECEF components, last axis) at geodetic positions."""
    lam, phi = np.radians(longitude_deg), np.radians(latitude_deg)
    east = np.stack([-np.sin(lam), np.cos(lam), np.zeros_like(lam)], axis=-1)
    north = np.stack([-np.sin(phi) * np.cos(lam), -np.sin(phi) * np.sin(lam), np.cos(phi)], axis=-1)
    up = np.stack([np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)], axis=-1)
    return east, north, up


def _local_angles(vector, basis):
    """Zenith and azimuth [deg] of ECEF direction vectors (last axis) in the local ENU frame."""
    east, north, up = (np.sum(vector * axis, axis=-1) for axis in basis)
    return vector_angles(east, north, up)


def _imaging_time(pixels, position, inertial_velocity, times):
    """Per pixel, the time at which the scan plane (perpendicular to the inertial velocity)
    contains it: the root of f(t) = (P - S(t)) . V(t), bracketed on the ephemeris samples and
    refined by two Newton steps with f'(t) = -|V|^2 + (P - S) . V' (spline derivatives)."""
    samples = np.einsum("nk,tk->nt", pixels, inertial_velocity(times)) - np.sum(
        position(times) * inertial_velocity(times), axis=-1)
    crossing = np.argmax(np.diff(np.sign(samples), axis=1) != 0, axis=1)
    f0 = np.take_along_axis(samples, crossing[:, None], axis=1)[:, 0]
    f1 = np.take_along_axis(samples, crossing[:, None] + 1, axis=1)[:, 0]
    inside = np.sign(f0) != np.sign(f1)
    step = times[1] - times[0]
    time = times[crossing] + step * f0 / np.where(f0 != f1, f0 - f1, 1.0)
    for _ in range(2):
        offset = pixels - position(time)
        velocity = inertial_velocity(time)
        slope = -np.sum(velocity * velocity, axis=-1) + np.sum(offset * inertial_velocity(time, 1), axis=-1)
        time = time - np.sum(offset * velocity, axis=-1) / slope
    return np.where(inside, time, np.nan)


def _ang_block(block_info, *, transform, to_lonlat, to_ecef, model, altitude):
    (row0, row1), (col0, col1) = block_info[None]["array-location"][1:]  # skip the (4,) axis
    shape = (row1 - row0, col1 - col0)
    x, y = pixel_centres(transform, row0, col0, shape)
    longitude, latitude = to_lonlat.transform(x, y)
    pixels = np.stack(to_ecef.transform(longitude, latitude, np.full(shape, altitude)), axis=-1).reshape(-1, 3)
    time = _imaging_time(pixels, model["position"], model["inertial_velocity"], model["times"])
    valid = np.isfinite(time)
    time = np.where(valid, time, model["times"][0])
    basis = [axis.reshape(-1, 3) for axis in _enu_basis(longitude, latitude)]
    vza, vaa = _local_angles(model["position"](time) - pixels, basis)
    sun = model["sun"](time)
    sza, saa = _local_angles(sun, basis)
    stacked = np.stack([sza, saa, vza, vaa]).reshape(4, *shape)
    return np.where(valid.reshape(shape), stacked, np.nan)


def _samples(ang: dict, group: str, key: str, source) -> np.ndarray:
    """A tuple of numbers of the ANG.txt as float64, else one error naming the group and key."""
    value = _item(ang, group, key, source)
    values = value if isinstance(value, tuple) else (value,)
    if not all(isinstance(item, float) and np.isfinite(item) for item in values):
        raise SensorInputError(f"{source}: {group} {key} holds {str(value)[:60]!r}, not a list of finite numbers")
    return np.asarray(values, dtype="float64")


def _spline(ang: dict, group: str, time_key: str, prefix: str, source) -> tuple[np.ndarray, CubicSpline]:
    """The sample times of a group of the ANG.txt (at least 2, strictly increasing) and the cubic
    spline through its ECEF X, Y, Z samples (one per time)."""
    times = _samples(ang, group, time_key, source)
    if times.size < 2 or np.any(np.diff(times) <= 0):
        shown = ", ".join(f"{t:g}" for t in times[:4]) + (", ..." if times.size > 4 else "")
        raise SensorInputError(f"{source}: {group} {time_key} must be at least 2 strictly increasing times, got "
                               f"{times.size} ({shown})")
    axes = []
    for axis in "XYZ":
        values = _samples(ang, group, f"{prefix}{axis}", source)
        if values.size != times.size:
            raise SensorInputError(f"{source}: {group} {prefix}{axis} has {values.size} values for {times.size} "
                                   f"times ({time_key})")
        axes.append(values)
    from scipy.interpolate import CubicSpline  # at first use: opening a product without ANG.txt needs none

    return times, CubicSpline(times, np.stack(axes, axis=-1))


def ang_angles(ang: dict, like: xr.DataArray, *, altitude: float = 0.0, chunks=None,
               source: str | Path = "ANG.txt") -> xr.Dataset:
    """Per-pixel sun and view angles from the ANG.txt ephemeris and solar vectors, lazily.

    Parameters
    ----------
    ang : dict
        A parsed ANG.txt (:func:`parse_ang_txt`).
    like : xarray.DataArray
        Georeferenced image grid (y, x).
    altitude : float
        Terrain height above the ellipsoid [m] used for every pixel.
    chunks :
        Output chunks; default ``like``'s, else 2048.
    source : str or Path
        The ANG.txt, in messages.

    Returns
    -------
    xarray.Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg]; NaN for pixels the ephemeris does not cover.

    Raises
    ------
    SensorInputError
        A group or key missing, samples that are no numbers, fewer than 2 or unsorted times, or
        samples of unequal count (named with ``source``).

    Notes
    -----
    A geometric model, not the USGS angle tool (which evaluates the per-band RPC polynomials of the
    ANG.txt): the spacecraft position S(t) is a cubic spline through the ECEF ephemeris; a pixel
    P (ECEF of its longitude, latitude and ``altitude``) is imaged when it lies in the scan plane
    perpendicular to the inertial velocity S'(t) + w x S(t) (whisk-broom ETM+/TM and push-broom
    OLI both image across track; no yaw steering). The view vector is S(t) - P and the sun vector
    the ANG.txt ECEF solar unit vector at t, both expressed in the pixel's (east, north, up)
    frame. Checked on the real scene: the sun part reproduces the product's SZA band to 0.1 deg
    and the mean sun vector of the ANG.txt; the view part reproduces the ANG.txt scene-mean
    satellite vector (see the tests). Band-to-band focal-plane offsets (below 0.1 deg) are ignored.
    """
    times, position = _spline(ang, "EPHEMERIS", "EPHEMERIS_TIME", "EPHEMERIS_ECEF_", source)
    _, sun = _spline(ang, "SOLAR_VECTOR", "SAMPLE_TIME", "SOLAR_ECEF_", source)
    if ang["EPHEMERIS"].get("EPHEMERIS_EPOCH_DAY", -1) != ang["SOLAR_VECTOR"].get("SOLAR_EPOCH_DAY", -2):
        raise SensorInputError(f"{source}: ephemeris and solar vectors have different epoch days")
    omega = np.array([0.0, 0.0, EARTH_ROTATION])

    def inertial_velocity(t, derivative=0):
        # Velocity relative to the inertial frame, expressed in ECEF axes: S' + w x S.
        return position(t, 1 + derivative) + np.cross(omega, position(t, derivative))

    plane = like.isel({dim: 0 for dim in like.dims if dim not in ("y", "x")}).transpose("y", "x")
    transform, crs, shape = _grid_of(plane, "the image grid (like)")
    if crs is None:
        raise SensorInputError("angles from the ANG.txt need pixel coordinates: the image grid has no CRS")
    if chunks is None:
        chunks = plane.data.chunks if isinstance(plane.data, da.Array) else GRID_CHUNK
    template = da.empty(shape, chunks=chunks)
    model = {"times": times, "position": position, "inertial_velocity": inertial_velocity, "sun": sun}
    stacked = da.map_blocks(
        _ang_block, dtype="float64", chunks=((4,),) + template.chunks, meta=np.empty((0, 0, 0)),
        transform=transform, to_lonlat=Transformer.from_crs(crs, CRS.from_epsg(4326), always_xy=True),
        to_ecef=Transformer.from_crs(CRS.from_epsg(4326), CRS.from_epsg(4978), always_xy=True),
        model=model, altitude=altitude,
    )
    coords = {"y": plane["y"], "x": plane["x"]}
    angles = xr.Dataset({
        key: xr.DataArray(stacked[index], dims=("y", "x"), coords=coords, attrs={
            "units": "degree", "long_name": LONG_NAMES[key], "source": "ANG.txt ephemeris model"})
        for index, key in enumerate(("sza", "saa", "vza", "vaa"))
    })
    return angles.rio.write_crs(crs).rio.write_transform(transform)


# --- angle bands ----------------------------------------------------------------------------------

#: A Landsat Collection 2 product id at the start of its files' names (sensor, level, path/row,
#: dates, collection, tier): what ``LC08_L2SP_..._02_T1_SR_B4.TIF`` and ``..._T1_SZA.TIF`` share.
PRODUCT_ID = re.compile(r"^L[COTEM]\d{2}_[A-Z0-9]{4}_\d{6}_\d{8}_\d{8}_\d{2}_(?:T1|T2|RT)", re.IGNORECASE)


def _product_id(name: str) -> str:
    """The product id of a file's ``name`` (:data:`PRODUCT_ID`), else the name up to its last ``_``."""
    found = PRODUCT_ID.match(name)
    return found.group(0) if found else name.rsplit("_", 1)[0]


def find_angle_bands(path: str | Path) -> dict[str, Path]:
    """The angle band files of a product: ``path`` is its directory or any file of it (a band
    GeoTIFF such as ``..._SR_B4.TIF``: the product id, :func:`_product_id`). Returns the files
    found, by angle name."""
    path = Path(path)
    if path.is_dir():
        directory, candidates = path, sorted(path.iterdir())
    else:
        directory = path.parent
        prefix = _product_id(path.name)
        candidates = sorted(p for p in directory.iterdir() if p.name.startswith(prefix))
    found = {}
    for key, suffix in ANGLE_SUFFIXES.items():
        pattern = re.compile(re.escape(suffix) + r"\.tiff?$", re.IGNORECASE)
        matches = [p for p in candidates if pattern.search(p.name)]
        if len(matches) > 1:
            raise SensorInputError(f"{directory}: several {suffix} angle bands: {[p.name for p in matches]}")
        if matches:
            found[key] = matches[0]
    return found


def find_ang_txt(path: str | Path) -> Path | None:
    """The product's angle coefficient file: the one ``*_ANG.txt`` in the directory ``path`` (or,
    for a file of the product, beside it with the same product id), else None (none, or several)."""
    path = Path(path)
    if path.is_dir():
        candidates = list(path.glob("*_ANG.txt"))
    else:
        prefix = _product_id(path.name)
        candidates = [p for p in path.parent.glob("*_ANG.txt") if p.name.startswith(prefix)]
    return candidates[0] if len(candidates) == 1 else None


def _sample_range(path: Path) -> tuple[tuple[float, float] | None, rasterio.coords.BoundingBox, CRS | None]:
    """(min, max) of a decimated read (at most 256 x 256, cheap on any size) of a band's valid
    values (None where it has none), with the band's bounds and CRS."""
    with rasterio.open(path) as dataset:
        sample = dataset.read(1, out_shape=(min(dataset.height, 256), min(dataset.width, 256)), masked=True)
        bounds, crs = dataset.bounds, (CRS.from_user_input(dataset.crs) if dataset.crs else None)
    values = np.ma.masked_invalid(sample.astype("float64")).compressed()
    found = (float(values.min()), float(values.max())) if values.size else None
    return found, bounds, crs


#: Landsat's view zenith at the swath edge [deg] (185 km swath from 705 km): a view zenith band in
#: degrees holds at most about this many units.
VZA_EDGE = 7.5
#: Side [m] of a scene beyond which some pixel lies at least half of it (2 km) from any straight
#: ground track: seen at least atan(2 / 705) = 0.16 deg off nadir, 16 hundredths.
WIDE_ENOUGH = 4000.0
#: Latitude [deg] below which Landsat's ground track (inclination 98.2 deg) runs more than 15 deg
#: from east-west, so no pixel sees the satellite within 1.8 deg of due north or south.
TRACK_TURN_LATITUDE = 81.5


def _looks_like_degrees(key: str, high_abs: float, bounds, crs: CRS | None) -> str | None:
    """Why a view band's values read as degrees rather than hundredths, or None.

    A view zenith band whose values stay within Landsat's edge view zenith (7.5) over a scene wider
    than :data:`WIDE_ENOUGH` each way would put every pixel within 0.09 deg of nadir, where some
    pixel must be 0.16 deg off it. A view azimuth band whose values all lie within 180 of 0 would
    put the satellite within 1.8 deg of due north or south of every pixel, which the across-track
    view of a near-polar orbit gives only near its turning latitude. A sun azimuth band whose values
    all lie within 180 of 0 would put the sun within 1.8 deg of due north at every pixel, which a
    morning overpass (about 10:00 local time, the sun 30 deg or more east of the meridian) never has.
    """
    if crs is None:
        return None
    if key == "vza" and crs.is_projected and high_abs <= VZA_EDGE + 1.0:
        if min(bounds.right - bounds.left, bounds.top - bounds.bottom) >= WIDE_ENOUGH:
            return f"a scene {WIDE_ENOUGH / 1000:g} km wide seen within {(VZA_EDGE + 1.0) / 100:g} deg of nadir"
    if key == "vaa" and high_abs <= 180.0:
        to_geographic = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
        _, latitudes = to_geographic.transform([bounds.left, bounds.right, bounds.left, bounds.right],
                                               [bounds.top, bounds.top, bounds.bottom, bounds.bottom])
        if max(abs(value) for value in latitudes) < TRACK_TURN_LATITUDE:
            return "the satellite within 1.8 deg of due north or south of every pixel"
    if key == "saa" and high_abs <= 180.0:
        return "the sun within 1.8 deg of due north of every pixel at a morning overpass"
    return None


def check_hundredths(path: Path, key: str) -> None:
    """Refuse an angle band whose values are no hundredths of a degree (:data:`HUNDREDTHS`).

    A sun zenith band of values all at most 90 would be a sun within 0.9 deg of the zenith, which
    no Landsat overpass has (morning orbit): it holds degrees, and read as hundredths the sun would
    be put at the zenith (NBAR 15 % off). View bands in degrees beside a sun band in hundredths
    (a product written by another tool) are found by :func:`_looks_like_degrees`; on a scene too
    small or too far north for those rules they pass, within their hundredths range.
    """
    found, bounds, crs = _sample_range(path)
    if found is None:
        return
    (low, high), (least, most) = found, HUNDREDTHS[key]
    name = ANGLE_SUFFIXES[key][1:]
    if low < least or high > most:
        raise SensorInputError(f"{path}: {name} values {low:g} to {high:g} are outside {least} to "
                               f"{most}, the hundredths of a degree of a Landsat angle band")
    if key == "sza" and high <= 90.0:
        raise SensorInputError(f"{path}: SZA values {low:g} to {high:g} are degrees, not the hundredths of a degree "
                               "of a Landsat angle band (a sun within 0.9 deg of the zenith); store them x 100")
    reason = _looks_like_degrees(key, max(abs(low), abs(high)), bounds, crs)
    if reason is not None:
        raise SensorInputError(f"{path}: {name} values {low:g} to {high:g} are degrees, not the hundredths of a "
                               f"degree of a Landsat angle band ({reason}); store them x 100")


def _read_angle_band(path: Path, key: str, like, chunks, flip: bool) -> xr.DataArray:
    band = rioxarray.open_rasterio(path, chunks=chunks or {"y": 2048, "x": 2048}, masked=True)
    if band.sizes.get("band", 1) != 1:
        raise SensorInputError(f"{path}: an angle band must have one band, it has {band.sizes['band']}")
    check_hundredths(path, key)
    band = band.isel(band=0, drop=True) * ANGLE_SCALE
    if key == "vaa" and flip:
        band = band + 180.0
    azimuth = key in ("saa", "vaa")
    if azimuth:
        band = wrap_azimuth(band)
    attrs = {"units": "degree", "long_name": LONG_NAMES[key], "source": str(path)}
    if like is not None and grid_difference(band, like) is not None:
        # A coarser or reprojected angle raster: interpolate lazily onto the image grid.
        return to_grid(band, like, angle=azimuth, name=key, attrs=attrs, source=f"{path}: the {key} angle band")
    band.attrs = attrs
    if like is not None and like.chunks and chunks is None:  # align blocks with the image's
        band = band.chunk({"y": like.chunksizes["y"], "x": like.chunksizes["x"]})
    return band.rename(key)


def read_landsat_angles(path: str | Path, like: xr.DataArray | None = None, *,
                        ang: str | Path | None = None, view_from_ang: str | None = None,
                        view_azimuth: str = "to_sensor", chunks=None) -> xr.Dataset:
    """Sun and view angles of a Landsat Collection 2 product on the image grid, lazily.

    Parameters
    ----------
    path : str or Path
        Product directory, or any file of the product (e.g. a band GeoTIFF or ``..._SZA.TIF``).
    like : xarray.DataArray, optional
        The image; angle bands on another grid (coarser, other CRS) are interpolated onto it
        lazily. Required when angles have to be computed (see below).
    ang : str or Path, optional
        The product's ANG.txt. With it, missing solar bands are computed with pvlib at the scene
        time of the ANG.txt and the pixel coordinates of ``like``. Default: the product's own
        ``*_ANG.txt`` where exactly one lies beside its bands (:func:`find_ang_txt`).
    view_from_ang : {None, "ephemeris", "mean"}
        With ``ang``, how to obtain missing view bands (Level-2 deliveries often lack them); a
        model rather than product data, so it must be asked for. "ephemeris": per pixel from the
        ANG.txt ephemeris (:func:`ang_angles`, about 0.15 deg); "mean": the scene-mean view
        angles of band 4 (constant; only for near-nadir work). None: missing view bands are an
        error.
    view_azimuth : {"to_sensor", "from_sensor"}
        What the VAA band holds; Landsat C2: "to_sensor".
    chunks :
        Dask chunks for reading the bands (default 2048 x 2048).

    Returns
    -------
    xarray.Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] on (y, x); each variable's ``source`` attr says
        where it came from.

    Raises
    ------
    SensorInputError
        A needed angle band is missing and cannot be computed (the message names it).
    """
    if view_azimuth not in ("to_sensor", "from_sensor"):
        raise SensorInputError(f"view_azimuth must be 'to_sensor' or 'from_sensor', got {view_azimuth!r}")
    if view_from_ang not in (None, "ephemeris", "mean"):
        raise SensorInputError(f"view_from_ang must be None, 'ephemeris' or 'mean', got {view_from_ang!r}")
    files = find_angle_bands(path)
    ang = find_ang_txt(path) if ang is None else ang
    variables = {key: _read_angle_band(file, key, like, chunks, view_azimuth == "from_sensor")
                 for key, file in files.items()}
    missing = [key for key in ANGLE_SUFFIXES if key not in variables]
    if missing and ang is not None:
        coefficients = parse_ang_txt(ang)
        grid = like if like is not None else next(iter(variables.values()), None)
        if grid is None:
            raise SensorInputError(f"{path}: no angle band and no image grid (like) to compute angles on")
        if {"sza", "saa"} & set(missing):
            time = ang_scene_time(coefficients, ang)
            sun = solar_angles(time, grid, chunks=chunks)
            for key in {"sza", "saa"} & set(missing):
                variables[key] = sun[key].assign_attrs(source=f"pvlib SPA at {time} ({ang})")
        if view_from_ang == "ephemeris" and {"vza", "vaa"} & set(missing):
            view = ang_angles(coefficients, grid, chunks=chunks, source=ang)
            for key in {"vza", "vaa"} & set(missing):
                variables[key] = view[key].assign_attrs(source=f"ephemeris model ({ang})")
        if view_from_ang == "mean" and {"vza", "vaa"} & set(missing):
            mean = ang_mean_angles(coefficients, band=4)
            template = next(iter(variables.values()))
            for key in {"vza", "vaa"} & set(missing):
                variables[key] = xr.full_like(template, mean[key], dtype="float64").assign_attrs(
                    units="degree", long_name=LONG_NAMES[key], source=f"scene mean, band 4 ({ang})")
        missing = [key for key in ANGLE_SUFFIXES if key not in variables]
    if missing:
        wanted = ", ".join(f"*{ANGLE_SUFFIXES[key]}.TIF" for key in missing)
        if ang is None:
            hint = "; give the ANG.txt (ang=...) to compute solar angles"
        elif {"vza", "vaa"} & set(missing):
            hint = "; view_from_ang='ephemeris' computes view angles from the ANG.txt"
        else:
            hint = ""
        raise SensorInputError(f"{path}: missing Landsat angle band(s) {wanted}{hint}")
    angles = xr.Dataset({key: variables[key].rename(key) for key in ANGLE_SUFFIXES})
    angles.attrs = {"source": str(path), "source_kind": "landsat", "view_azimuth_stored": view_azimuth}
    return angles
