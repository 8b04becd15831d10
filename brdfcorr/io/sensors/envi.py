"""Imaging-spectrometer lines in ENVI format: AVIRIS-NG, AVIRIS-3 and others laid out like them.

An imaging-spectrometer line comes as an image (radiance or reflectance cube, ENVI BSQ/BIL/BIP with
band-centre wavelengths and FWHM in the header) and an observation file (``obs`` for the raw line
geometry, ``obs_ort``/``obs_ortdem`` for the orthorectified line) whose bands hold, per pixel, the
path length, the to-sensor azimuth and zenith, the to-sun azimuth and zenith, the phase angle, and
more. Both are read lazily through GDAL (rioxarray); obs bands are found by their header
``band names``, never by position.

Conventions of the obs file (JPL AVIRIS-NG / AVIRIS-3 processing, also EMIT): "To-sensor azimuth
(0 to 360 degrees cw from N)" is the azimuth of the direction *from the pixel towards the sensor*
and "To-sun azimuth" that of the direction from the pixel towards the sun, exactly the brdfcorr
convention (``docs/conventions.md``). The band ``Solar phase`` (the angle between the two directions) confirms
it on the real lines in ``shared/realdata``: with the azimuths taken as stored, the angle between
the to-sun and to-sensor unit vectors equals the phase band to 1e-3 deg; flipped by 180 deg it is
off by up to 19 deg. ``view_azimuth="from_sensor"`` flips explicitly for a product that differs.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import rasterio
import rioxarray
import xarray as xr

from brdfcorr._entry import option
from brdfcorr.errors import SensorInputError
from brdfcorr.io.commit import short_envi
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.sensors.bands import MICROMETRES_BELOW, UNITS_TO_NM
from brdfcorr.io.sensors.grids import wrap_azimuth

__all__ = [
    "OBS_BAND_NAMES",
    "OBS_TERRAIN_BAND_NAMES",
    "acquisition_time",
    "envi_bad_bands",
    "bad_band_flags",
    "envi_wavelengths",
    "read_envi_image",
    "read_envi_obs",
    "read_envi_obs_terrain",
]

#: Normalized band-name prefixes of the four angles in an obs file (see :func:`_normalize`).
OBS_BAND_NAMES = {
    "sza": "to sun zenith",
    "saa": "to sun azimuth",
    "vza": "to sensor zenith",
    "vaa": "to sensor azimuth",
}

#: Normalized band-name prefixes of the surface orientation in an ``obs_ort`` file ("Slope", "Aspect").
OBS_TERRAIN_BAND_NAMES = {
    "slope": "slope",
    "aspect": "aspect",
}

TERRAIN_LONG_NAMES = {
    "slope": "surface slope",
    "aspect": "surface aspect (direction faced, downslope, clockwise from north)",
}

ANGLE_LONG_NAMES = {
    "sza": "solar zenith angle",
    "saa": "solar azimuth angle (pixel to sun, clockwise from north)",
    "vza": "view zenith angle",
    "vaa": "view azimuth angle (pixel to sensor, clockwise from north)",
}

# Line names: AVIRIS-NG "ang20160910t185702...", AVIRIS-3 "AV320231008t160218..." (UTC start time).
_LINE_TIME = re.compile(r"(?:ang|av3)(\d{8})t(\d{6})", re.IGNORECASE)


def _normalize(name: str) -> str:
    """Lower-case band name before any parenthesis, with '-', '_' and runs of blanks as one blank."""
    return " ".join(re.split(r"[\s_\-]+", name.split("(")[0].strip().lower())).strip()


def _header_list(value: str | None) -> list[str]:
    """Items of an ENVI header list ``{a, b, c}`` as GDAL returns it (braces optional)."""
    if value is None:
        return []
    return [item.strip() for item in value.strip().strip("{}").split(",") if item.strip()]


def _envi_tags(path: Path) -> tuple[dict, tuple]:
    try:
        with rasterio.open(path) as source:
            if source.driver != "ENVI":
                raise SensorInputError(f"{path}: not an ENVI file (GDAL driver {source.driver})")
            short = short_envi(source)  # GDAL reads a missing part as zeros: a sun at the zenith
            if short is not None:
                raise SensorInputError(f"{path}: {short} (a truncated or damaged file?)")
            return source.tags(ns="ENVI"), source.descriptions
    except rasterio.errors.RasterioIOError as error:
        raise SensorInputError(f"{path}: cannot open as ENVI image ({error})") from error


def acquisition_time(path: str | Path) -> pd.Timestamp:
    """UTC start time of an AVIRIS-NG (``angYYYYMMDDtHHMMSS``) or AVIRIS-3 (``AV3...``) line.

    The obs files' to-sun angles of both real lines in ``shared/realdata`` are the sun position at
    this time (checked with pvlib to 0.01 deg), so it is the time to use for solar angles too.
    """
    match = _LINE_TIME.search(Path(path).name)
    if match is None:
        raise SensorInputError(
            f"{path}: no AVIRIS-NG/AVIRIS-3 line time (angYYYYMMDDtHHMMSS) in the file name"
        )
    return pd.Timestamp(f"{match[1]}T{match[2]}", tz="UTC")


def envi_wavelengths(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Band-centre wavelengths and FWHM [nm] from an ENVI header.

    Wavelengths come from the ``wavelength`` item (in ``wavelength units``), else from band names
    that hold a number and a unit (``"376.44 Nanometers"``, as in some AVIRIS-NG radiance
    headers). Without a unit (or ``Unknown``, as ENVI writes it), values below 100 are taken as
    micrometres (no imaging spectrometer has a band centre below 100 nm) and others as nanometres;
    ``Index`` (band numbers, no wavelengths) is refused. FWHM is None when absent.

    Raises
    ------
    SensorInputError
        No wavelengths, or a count that differs from the number of bands.
    """
    path = Path(path)
    tags, descriptions = _envi_tags(path)
    bands = int(tags.get("bands", len(descriptions)))
    unit = tags.get("wavelength_units", "").strip().lower()
    values = _header_list(tags.get("wavelength"))
    if not values:
        parsed = [re.fullmatch(r"\s*([0-9.eE+-]+)\s*([A-Za-zµ]*)\s*", name or "") for name in descriptions]
        if not all(parsed):
            raise SensorInputError(
                f"{path}: the header has no 'wavelength' item and the band names hold no wavelengths"
            )
        values = [match[1] for match in parsed]
        unit = unit or parsed[0][2].lower()
    try:
        wavelength = np.array(values, dtype="float64")
        fwhm = np.array(_header_list(tags.get("fwhm")), dtype="float64")
    except ValueError as error:
        raise SensorInputError(f"{path}: non-numeric wavelength or fwhm in the header ({error})") from error
    if wavelength.size != bands:
        raise SensorInputError(f"{path}: {wavelength.size} wavelengths in the header for {bands} bands")
    if fwhm.size not in (0, bands):
        raise SensorInputError(f"{path}: {fwhm.size} fwhm values in the header for {bands} bands")
    if unit == "index":  # ENVI's "band numbers": 1, 2, ... read as micrometres would be 1000 nm, 2000 nm
        raise SensorInputError(f"{path}: the header's wavelengths are band numbers (wavelength units = Index): give "
                               f"the band centres [nm] ({option('wavelengths')})")
    if unit and unit != "unknown":
        if unit not in UNITS_TO_NM:
            raise SensorInputError(f"{path}: unknown wavelength units {unit!r}")
        scale = UNITS_TO_NM[unit]
    else:
        scale = 1e3 if np.nanmax(wavelength) < MICROMETRES_BELOW else 1.0
    return wavelength * scale, (fwhm * scale if fwhm.size else None)


def envi_bad_bands(path: str | Path) -> np.ndarray | None:
    """Which bands the ENVI header's bad band list marks bad (``bbl``: 1 good, 0 bad), one bool per
    band; None for a file that is no ENVI image or whose header has no ``bbl``.

    Raises
    ------
    SensorInputError
        A ``bbl`` that is not numeric or whose count differs from the number of bands.
    """
    try:
        with rasterio.open(path) as source:
            if source.driver != "ENVI":
                return None
            return bad_band_flags(source.tags(ns="ENVI"), source.count, path)
    except rasterio.errors.RasterioIOError:
        return None  # not a file GDAL opens (a product's path): no ENVI header


def bad_band_flags(tags: Mapping[str, str], count: int, path) -> np.ndarray | None:
    """:func:`envi_bad_bands` of an ENVI file's header items ``tags`` (GDAL's ENVI domain) for its
    ``count`` bands, read already (``path`` names the file in errors)."""
    items = _header_list(tags.get("bbl"))
    if not items:
        return None
    try:
        flags = np.array(items, dtype="float64")
    except ValueError:
        raise SensorInputError(f"{path}: non-numeric bbl (bad band list) in the header") from None
    if flags.size != count:
        raise SensorInputError(f"{path}: {flags.size} bbl (bad band list) values in the header for {count} bands")
    return flags == 0


def read_envi_image(path: str | Path, chunks=None) -> xr.DataArray:
    """Open an ENVI radiance or reflectance cube lazily with its wavelengths.

    Parameters
    ----------
    path : str or Path
        The ENVI data file (its ``.hdr`` beside it).
    chunks : dict, int, True or None
        Dask chunks passed to :func:`rioxarray.open_rasterio`; default: whole spectrum per chunk,
        512 x 512 pixels.

    Returns
    -------
    xarray.DataArray
        (band, y, x), dask-backed, nodata (``data ignore value``) as NaN, with coords
        ``wavelength`` [nm] and, when the header has it, ``fwhm`` [nm] along ``band``; CRS and
        transform when the header has a map info.
    """
    path = Path(path)
    wavelength, fwhm = envi_wavelengths(path)
    image = rioxarray.open_rasterio(
        path, chunks=chunks or {"band": -1, "y": 512, "x": 512}, masked=True
    )
    image = image.drop_vars([name for name in ("wavelength", "fwhm") if name in image.coords])
    image = image.assign_coords(
        wavelength=("band", wavelength, {"units": "nm", "long_name": "band-centre wavelength"})
    )
    if fwhm is not None:
        image = image.assign_coords(
            fwhm=("band", fwhm, {"units": "nm", "long_name": "full width at half maximum"})
        )
    image.attrs = {"long_name": image.attrs.get("description", path.name), "source": str(path)}
    image.name = path.name
    return image


def _obs_band_index(path: Path, names: tuple, wanted: str, label: str) -> int:
    matches = [index for index, name in enumerate(names) if _normalize(name or "").startswith(wanted)]
    if len(matches) == 1:
        return matches[0]
    if not matches:
        raise SensorInputError(
            f"{path}: no obs band for {label} (a band name starting with {wanted!r}); {_some_names(names)}"
            " (is this an obs/obs_ort file?)"
        )
    raise SensorInputError(f"{path}: several obs bands match {label} ({wanted!r}): "
                           f"{', '.join(repr(names[i]) for i in matches)}")


def _some_names(names: tuple, most: int = 6) -> str:
    """``band names are: 'a', 'b', ... (425 bands)``, at most ``most`` names: a message stays one line."""
    listed = ", ".join(repr(name) for name in names[:most])
    return f"band names are: {listed}" + (f", ... ({len(names)} bands)" if len(names) > most else "")


def wanted_bands(band_names: Mapping[str, str] | None, defaults: Mapping[str, str], what: str) -> dict[str, str]:
    """The band-name prefix of each layer: ``defaults`` with the user's ``band_names`` over them
    (normalized, :func:`_normalize`); a key that is no layer is a :class:`SensorInputError`."""
    if band_names is not None and not (isinstance(band_names, Mapping)
                                       and all(isinstance(value, str) for value in band_names.values())):
        raise SensorInputError(f"band_names must map layers ({', '.join(defaults)}) to band-name texts, "
                               f"e.g. {{sza: 'To-sun zenith'}}; got {band_names!r}")
    names = {**defaults, **{key: _normalize(value) for key, value in (band_names or {}).items()}}
    unknown = set(names) - set(defaults)
    if unknown:
        raise SensorInputError(f"band_names: unknown {what} {sorted(unknown)}; use {', '.join(defaults)}")
    return names


def _open_obs_bands(path: Path, names: Mapping[str, str], like, chunks):
    """The obs file (band, y, x) lazily, the index of each named layer's band and the band names;
    the grid checked against ``like``."""
    _, descriptions = _envi_tags(path)
    indices = {key: _obs_band_index(path, descriptions, wanted, key) for key, wanted in names.items()}
    obs = rioxarray.open_rasterio(path, chunks=chunks or {"band": 1, "y": 512, "x": 512}, masked=True)
    if like is not None:
        check_same_grid({"image": like, "obs file": obs})
    return obs, indices, descriptions


def read_envi_obs(path: str | Path, like: xr.DataArray | None = None, *,
                  view_azimuth: str = "to_sensor", band_names: Mapping[str, str] | None = None,
                  chunks=None) -> xr.Dataset:
    """Per-pixel sun and view angles from an ENVI observation (``obs``/``obs_ort``) file.

    Parameters
    ----------
    path : str or Path
        The obs file (ENVI, header ``band names`` required).
    like : xarray.DataArray, optional
        The image the angles are for; its (y, x) grid must be the obs grid (same size and, when
        both are georeferenced, the same transform), else :class:`SensorInputError`. The output
        then takes its ``y``/``x`` coordinates.
    view_azimuth : {"to_sensor", "from_sensor"}
        What the to-sensor azimuth band holds. AVIRIS-NG/AVIRIS-3/EMIT: "to_sensor" (the
        default, checked against the phase band, see the module notes). "from_sensor" flips by
        180 deg.
    band_names : mapping, optional
        Band-name prefixes overriding :data:`OBS_BAND_NAMES` for ``sza``, ``saa``, ``vza``,
        ``vaa``, for products that name them differently (matched case-insensitively, '-'/'_'
        as blanks, text in parentheses ignored).
    chunks :
        Dask chunks for :func:`rioxarray.open_rasterio` (default 512 x 512 pixels).

    Returns
    -------
    xarray.Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] on (y, x), dask-backed, nodata as NaN; azimuths
        in [0, 360) towards the sun and the sensor (``docs/conventions.md``).
    """
    path = Path(path)
    if view_azimuth not in ("to_sensor", "from_sensor"):
        raise SensorInputError(f"view_azimuth must be 'to_sensor' or 'from_sensor', got {view_azimuth!r}")
    names = wanted_bands(band_names, OBS_BAND_NAMES, "angle(s)")
    obs, indices, descriptions = _open_obs_bands(path, names, like, chunks)
    variables = {}
    for key, index in indices.items():
        angle = obs.isel(band=index, drop=True)
        if key == "vaa" and view_azimuth == "from_sensor":
            angle = angle + 180.0
        if key in ("saa", "vaa"):
            angle = wrap_azimuth(angle)
        angle.attrs = {"units": "degree", "long_name": ANGLE_LONG_NAMES[key],
                       "source_band": descriptions[index]}
        variables[key] = angle.rename(key)
    angles = _on_image_grid(xr.Dataset(variables), like, chunks)
    angles.attrs = {"source": str(path), "source_kind": "envi_obs", "view_azimuth_stored": view_azimuth}
    return angles


def _on_image_grid(layers: xr.Dataset, like: xr.DataArray | None, chunks) -> xr.Dataset:
    """Layers read from an obs file with the image's ``y``/``x`` coordinates and, unless ``chunks``
    were given, its blocks (for blockwise work with the image)."""
    if like is None:
        return layers
    layers = layers.assign_coords(y=like["y"].values, x=like["x"].values)
    if like.chunks and chunks is None:
        layers = layers.chunk({"y": like.chunksizes["y"], "x": like.chunksizes["x"]})
    return layers


def read_envi_obs_terrain(path: str | Path, like: xr.DataArray | None = None, *,
                          band_names: Mapping[str, str] | None = None, chunks=None) -> xr.Dataset:
    """Per-pixel surface slope and aspect from an ENVI ``obs_ort``/``obs_ortdem`` file.

    Parameters
    ----------
    path : str or Path
        The obs file (ENVI, header ``band names`` required); its bands "Slope" and "Aspect" are
        found by name like the angle bands (:func:`read_envi_obs`). Opened by its absolute path
        (the terrain step's one entry here, as :func:`brdfcorr.io.sensors.read_angles` is the
        angles'), so that workers started in another folder read it.
    like : xarray.DataArray, optional
        The image the layers are for; its (y, x) grid must be the obs grid, else
        :class:`SensorInputError`. The output then takes its ``y``/``x`` coordinates and chunks.
    band_names : mapping, optional
        Band-name prefixes overriding :data:`OBS_TERRAIN_BAND_NAMES` for ``slope`` and ``aspect``.
    chunks :
        Dask chunks for :func:`rioxarray.open_rasterio` (default 512 x 512 pixels).

    Returns
    -------
    xarray.Dataset
        ``slope`` [deg] and ``aspect`` [deg, wrapped into [0, 360)] on (y, x), dask-backed, nodata
        as NaN. Aspect is the azimuth of the direction the surface faces (downslope), clockwise from
        north, as documented for these files. Checked on real files (``docs/terrain.md``): the
        "Cosine(i)" band of ang20170323t202244 equals
        :func:`brdfcorr.correction.terrain.cos_incidence` to 2.2e-16, but its Slope and Aspect are
        placeholders (90 deg, 0 deg) that do not pin the aspect convention down; the other file,
        ``..._obs_ortdem_mod``, has edited slope and aspect bands whose "Cosine(i)" matches no
        convention.
    """
    # An absolute path, as brdfcorr.io.opening.open_raster opens rasters: the graph's reads may run
    # on dask.distributed workers started elsewhere.
    path = Path(path).absolute()
    names = wanted_bands(band_names, OBS_TERRAIN_BAND_NAMES, "layer(s)")
    obs, indices, descriptions = _open_obs_bands(path, names, like, chunks)
    variables = {}
    for key, index in indices.items():
        layer = obs.isel(band=index, drop=True)
        if key == "aspect":
            layer = wrap_azimuth(layer)
        layer.attrs = {"units": "degree", "long_name": TERRAIN_LONG_NAMES[key], "source_band": descriptions[index]}
        variables[key] = layer.rename(key)
    layers = _on_image_grid(xr.Dataset(variables), like, chunks)
    layers.attrs = {"source": str(path), "source_kind": "envi_obs"}
    return layers
