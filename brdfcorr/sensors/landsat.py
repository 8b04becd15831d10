"""Landsat Collection 2 angles: the per-pixel angle bands and the angle coefficient file (ANG.txt).

Collection 2 Level-1 products (and some Level-2 deliveries) include four angle bands, GeoTIFFs
named ``<product id>_SZA.TIF``, ``_SAA.TIF``, ``_VZA.TIF``, ``_VAA.TIF`` (band 4 geometry), holding
the angles as scaled integers in hundredths of a degree; azimuths in [-180, 180]. Every product
also carries ``<product id>_ANG.txt``, the angle coefficient file: ephemeris, solar vectors, and per
band the scene-mean sun and satellite vectors in the local (east, north, up) frame.

Conventions: the USGS angle tools compute the satellite and sun vectors from the target (pixel)
towards the satellite and the sun, so the stored azimuths are "to sensor" and "to sun" as brdfcorr
wants them (``DESIGN.md``). On the real scene in ``shared/realdata`` the ANG.txt band-1 mean sun
vector gives the sun azimuth of pvlib's SPA at the scene centre to 0.01 deg with ``atan2(east,
north)``, confirming the (east, north, up) frame. ``view_azimuth="from_sensor"`` flips explicitly for
a product that differs.

References
----------
.. [1] USGS: Landsat Collection 2 Level-1 Data Format Control Book (LSDS-1656), angle bands.
.. [2] USGS: Solar Illumination and Sensor Viewing Angle Coefficient Files (ANG.txt).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import rioxarray
import xarray as xr

from brdfcorr.errors import SensorInputError
from brdfcorr.sensors.grids import to_grid, wrap_azimuth
from brdfcorr.sensors.solar import solar_angles

__all__ = [
    "ANGLE_SCALE",
    "ANGLE_SUFFIXES",
    "ang_mean_angles",
    "ang_scene_time",
    "find_angle_bands",
    "parse_ang_txt",
    "read_landsat_angles",
    "vector_angles",
]

#: Angle bands store hundredths of a degree (USGS C2 Level-1 DFCB).
ANGLE_SCALE = 0.01
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
    try:
        lines = path.read_text().splitlines()
    except OSError as error:
        raise SensorInputError(f"{path}: cannot read the angle coefficient file ({error})") from error
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


def ang_scene_time(ang: dict) -> pd.Timestamp:
    """Scene-centre UTC time from an ANG.txt: the middle of the solar-vector sample times."""
    year = int(_item(ang, "SOLAR_VECTOR", "SOLAR_EPOCH_YEAR"))
    day = int(_item(ang, "SOLAR_VECTOR", "SOLAR_EPOCH_DAY"))
    seconds = float(np.mean(_item(ang, "SOLAR_VECTOR", "SAMPLE_TIME")))
    return pd.Timestamp(year=year, month=1, day=1, tz="UTC") + pd.Timedelta(days=day - 1, seconds=seconds)


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


# --- angle bands ----------------------------------------------------------------------------------

def find_angle_bands(path: str | Path) -> dict[str, Path]:
    """The angle band files of a product: ``path`` is its directory or any file of it (the product
    id is the file name up to the last ``_``). Returns the files found, by angle name."""
    path = Path(path)
    if path.is_dir():
        directory, candidates = path, sorted(path.iterdir())
    else:
        directory = path.parent
        prefix = path.name.rsplit("_", 1)[0]
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


def _read_angle_band(path: Path, key: str, like, chunks, flip: bool) -> xr.DataArray:
    band = rioxarray.open_rasterio(path, chunks=chunks or {"y": 2048, "x": 2048}, masked=True)
    if band.sizes.get("band", 1) != 1:
        raise SensorInputError(f"{path}: an angle band must have one band, it has {band.sizes['band']}")
    band = band.isel(band=0, drop=True) * ANGLE_SCALE
    if key == "vaa" and flip:
        band = band + 180.0
    azimuth = key in ("saa", "vaa")
    if azimuth:
        band = wrap_azimuth(band)
    attrs = {"units": "degree", "long_name": LONG_NAMES[key], "source": str(path)}
    if like is not None and not _same_grid(band, like):
        # A coarser or reprojected angle raster: interpolate lazily onto the image grid.
        return to_grid(band, like, angle=azimuth, name=key, attrs=attrs)
    band.attrs = attrs
    if like is not None and like.chunks and chunks is None:  # align blocks with the image's
        band = band.chunk({"y": like.chunksizes["y"], "x": like.chunksizes["x"]})
    return band.rename(key)


def _same_grid(band: xr.DataArray, like: xr.DataArray) -> bool:
    if (band.sizes["y"], band.sizes["x"]) != (like.sizes["y"], like.sizes["x"]):
        return False
    if band.rio.crs != like.rio.crs:
        return False
    return np.allclose(band.rio.transform(), like.rio.transform(), rtol=0, atol=1e-6)


def read_landsat_angles(path: str | Path, like: xr.DataArray | None = None, *,
                        ang: str | Path | None = None, mean_view_from_ang: bool = False,
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
        time of the ANG.txt and the pixel coordinates of ``like``.
    mean_view_from_ang : bool
        With ``ang``: missing view bands are set to the scene-mean view angles of band 4 from the
        ANG.txt (constant over the scene; a coarse approximation, so it must be asked for).
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
    files = find_angle_bands(path)
    variables = {key: _read_angle_band(file, key, like, chunks, view_azimuth == "from_sensor")
                 for key, file in files.items()}
    missing = [key for key in ANGLE_SUFFIXES if key not in variables]
    if missing and ang is not None:
        coefficients = parse_ang_txt(ang)
        grid = like if like is not None else next(iter(variables.values()), None)
        if grid is None:
            raise SensorInputError(f"{path}: no angle band and no image grid (like) to compute angles on")
        if {"sza", "saa"} & set(missing):
            time = ang_scene_time(coefficients)
            sun = solar_angles(time, grid, chunks=chunks)
            for key in {"sza", "saa"} & set(missing):
                variables[key] = sun[key].assign_attrs(source=f"pvlib SPA at {time} ({ang})")
        if mean_view_from_ang and {"vza", "vaa"} & set(missing):
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
            hint = "; mean_view_from_ang=True takes the ANG.txt scene-mean view angles"
        else:
            hint = ""
        raise SensorInputError(f"{path}: missing Landsat angle band(s) {wanted}{hint}")
    angles = xr.Dataset({key: variables[key].rename(key) for key in ANGLE_SUFFIXES})
    angles.attrs = {"source": str(path), "source_kind": "landsat", "view_azimuth_stored": view_azimuth}
    return angles
