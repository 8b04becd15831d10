"""GeoTIFF input and output for the normalization, through rioxarray and rasterio.

Readers open lazily (dask chunks), with nodata as NaN for reflectance and angles and the class map
kept as integers with its nodata value; the image's stored values are scaled to reflectance
factors (the file's GDAL scale/offset, or given ones; :func:`check_reflectance_scale` catches raw
counts). :func:`check_same_grid` says which layer differs from the
image and how (shape, transform or CRS). :func:`band_wavelengths` finds band centres in the
order fixed by ``docs/conventions.md``. :func:`write_rasters` (from :mod:`brdfcorr.io.writer`) writes tiled,
compressed GeoTIFFs chunk by chunk, atomically. A whole scene is opened and checked by
:func:`brdfcorr.io.scene.open_scene`.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import NamedTuple

import dask
import dask.array
import numpy as np
import rasterio
import rasterio.shutil
import rioxarray
import xarray as xr
from rasterio._err import CPLE_BaseError  # GDAL errors rasterio passes on as they are

from brdfcorr.errors import BrdfcorrError, GridMismatchError, InputError
from brdfcorr.io.writer import DEFAULT_CHUNK, _GdalMessages, write_rasters

__all__ = [
    "AngleStatistics",
    "open_image",
    "open_angles",
    "open_classes",
    "check_same_grid",
    "check_angles",
    "check_reflectance_scale",
    "band_wavelengths",
    "parse_wavelength",
    "write_rasters",
    "auto_chunk",
    "gdal_cache_bytes",
    "DEFAULT_CHUNK",
    "ANGLE_NAMES",
    "ANGLE_BAND_NAMES",
    "angle_band_name",
    "SENTINEL2_WAVELENGTHS",
    "LANDSAT_OLI_WAVELENGTHS",
]

ANGLE_NAMES = ("sza", "saa", "vza", "vaa")

#: Band descriptions that name an angle in a 4-band angle raster (:func:`open_angles`), after
#: lower-casing, spaces and hyphens turned into ``_`` and an ``_angle`` suffix dropped.
ANGLE_BAND_NAMES = {
    "sza": ("sza", "solar_zenith", "sun_zenith"),
    "saa": ("saa", "solar_azimuth", "sun_azimuth"),
    "vza": ("vza", "view_zenith", "viewing_zenith", "sensor_zenith"),
    "vaa": ("vaa", "view_azimuth", "viewing_azimuth", "sensor_azimuth"),
}

_UNITS_TO_NM = {
    "": 1.0, "nm": 1.0, "nanometer": 1.0, "nanometers": 1.0, "nanometre": 1.0, "nanometres": 1.0,
    "um": 1e3, "µm": 1e3, "μm": 1e3, "micron": 1e3, "microns": 1e3, "micrometer": 1e3,
    "micrometers": 1e3, "micrometre": 1e3, "micrometres": 1e3,
}
_NUMBER = r"[0-9]+(?:\.[0-9]*)?(?:[eE][+-]?[0-9]+)?"

#: Central wavelengths [nm] of the Sentinel-2A MSI bands (ESA, Sentinel-2 spectral response
#: functions, COPE-GSEG-EOPG-TN-15-0007). Sentinel-2B's centres differ by 3 nm or less in B01 to
#: B8A (by up to 17 nm in B12): the S2A values serve both.
SENTINEL2_WAVELENGTHS = {
    "B01": 442.7, "B02": 492.4, "B03": 559.8, "B04": 664.6, "B05": 704.1, "B06": 740.5, "B07": 782.8,
    "B08": 832.8, "B8A": 864.7, "B09": 945.1, "B10": 1373.5, "B11": 1613.7, "B12": 2202.4,
}

#: Central wavelengths [nm] of the Landsat 8/9 OLI reflective bands 1-7 (USGS, Landsat 8 Data
#: Users Handbook, Table 2-1), used only for images whose tags state the sensor (:func:`band_wavelengths`).
LANDSAT_OLI_WAVELENGTHS = {1: 443.0, 2: 482.0, 3: 562.0, 4: 655.0, 5: 865.0, 6: 1609.0, 7: 2201.0}

#: Dataset tags that may state the sensor of an image (Landsat MTL's ``SENSOR_ID``: ``OLI_TIRS``).
_SENSOR_TAGS = ("sensor", "SENSOR", "SENSOR_ID")


def _open(path, role: str, chunks, masked: bool, mask_and_scale: bool = False) -> xr.DataArray:
    path = Path(path)
    if not path.exists():
        raise InputError(f"{role} file {path} does not exist")
    try:
        with warnings.catch_warnings():
            # Per-band scales/offsets: rioxarray applies each band's, and says so in a warning.
            warnings.filterwarnings("ignore", r"(Scales|Offsets) differ across bands", UserWarning)
            # lock=False: every dask thread reads through its own handle, so reads run in parallel.
            array = rioxarray.open_rasterio(path, chunks=chunks, masked=masked, mask_and_scale=mask_and_scale,
                                            lock=False)
    except rasterio.errors.RasterioError as error:
        raise InputError(f"cannot read {role} file {path}: {error}{_hdf5_hint(path)}") from None
    if isinstance(array, list):  # subdatasets: not a plain raster
        raise InputError(f"{role} file {path} holds several subdatasets; give one raster{_hdf5_hint(path)}")
    array.encoding["source"] = str(path)
    return array


def open_layer(path, role: str, chunks=None) -> xr.DataArray:
    """Any raster (band, y, x), lazily, nodata as NaN; ``role`` names it in errors ("DEM")."""
    return _open(path, role, _chunks(chunks), masked=True)


def _hdf5_product(path) -> str | None:
    """``"neon"`` or ``"emit"`` for an image that is a NEON AOP reflectance HDF5 or an EMIT L2A
    reflectance NetCDF (told by content, not by name), else None: a raster GDAL reads. Without h5py
    such a file is None too, and GDAL's error on it says what to install (:func:`_hdf5_hint`)."""
    from brdfcorr.io.sensors import emit, neon

    if not neon.is_hdf5(path):
        return None
    try:
        neon.require_hdf5(path)
    except InputError:
        return None
    if neon.is_neon_reflectance(path):
        return "neon"
    if emit.is_emit_reflectance(path):
        return "emit"
    return None


def _hdf5_hint(path) -> str:
    """For an error on an HDF5/NetCDF-4 file while h5py or h5netcdf is missing: what to install."""
    from brdfcorr.io.sensors import neon

    if not neon.is_hdf5(path):
        return ""
    try:
        neon.require_hdf5(path)
    except InputError:
        return " (NEON AOP .h5 and EMIT .nc images need h5py and h5netcdf: pip install 'brdfcorr[hdf5]')"
    return ""


def _open_product(kind: str, path, chunks, wavelengths: Sequence[float] | None, scale: float | None,
                  offset: float | None) -> xr.DataArray:
    """A NEON or EMIT image through its reader (:mod:`brdfcorr.io.sensors.neon`, ``.emit``), with
    ``wavelengths`` replacing the product's band centres where given."""
    from brdfcorr.io.sensors import read_emit_image, read_neon_image

    reader = read_neon_image if kind == "neon" else read_emit_image
    try:
        image = reader(path, chunks=_chunks(chunks), scale=scale, offset=offset)
    except OSError as error:  # an HDF5 file that h5py opened but cannot read further
        raise InputError(f"cannot read image file {path}: {error}") from None
    if wavelengths is not None:
        values = np.asarray([float(value) for value in wavelengths])
        if values.size != image.sizes["band"] or not np.all(np.isfinite(values) & (values > 0)):
            raise InputError(f"{path}: the given wavelengths must be {image.sizes['band']} finite values > 0 nm")
        image = image.assign_coords(wavelength=("band", values, {"units": "nm"}))
    return image


def _band_count(path) -> int:
    """Number of bands of an image file (GDAL's count, or the NEON/EMIT product's)."""
    kind = _hdf5_product(path)
    if kind is not None:
        from brdfcorr.io.sensors import emit, neon

        return neon.neon_band_count(path) if kind == "neon" else emit.emit_band_count(path)
    with _opened(path, "image") as dataset:
        return dataset.count


def auto_chunk(path, target_bytes: int = 16 * 2**20) -> int:
    """Spatial chunk (and tile) size [pixels] for an image: the largest of 512, 256, 128, 64 whose
    chunk of all bands (as float32) holds at most ``target_bytes``, so memory stays flat for
    hyperspectral cubes."""
    count = _band_count(path)
    for size in (512, 256, 128, 64):
        if count * size * size * 4 <= target_bytes:
            return size
    return 64


def gdal_cache_bytes(path, chunk: int) -> int:
    """A GDAL block cache [bytes] for reading ``path`` in chunks of ``chunk`` pixels: room for two
    decompressed input tiles (all bands) and four chunks, between 64 and 512 MiB. GDAL's default
    (5 % of RAM) would let the cache, and so the peak memory, grow with the image. A NEON or EMIT
    image is not read through GDAL: room for four chunks (the class map's reads) suffices."""
    if _hdf5_product(path) is not None:
        return int(np.clip(4 * _band_count(path) * chunk * chunk * 4, 64 * 2**20, 512 * 2**20))
    with _opened(path, "image") as dataset:
        count, itemsize = dataset.count, np.dtype(dataset.dtypes[0]).itemsize
        tile_rows, tile_columns = dataset.block_shapes[0]
    tile = count * min(tile_rows, 1024) * min(tile_columns, 4096) * itemsize
    chunk_bytes = count * chunk * chunk * 4
    return int(np.clip(max(2 * tile, 4 * chunk_bytes), 64 * 2**20, 512 * 2**20))


@contextlib.contextmanager
def _opened(path, role: str):
    try:
        with rasterio.open(path) as dataset:
            yield dataset
    except rasterio.errors.RasterioError as error:
        raise InputError(f"cannot read {role} file {path}: {error}") from None


def _chunks(chunks):
    if chunks is None:
        chunks = DEFAULT_CHUNK
    if isinstance(chunks, int):
        return {"band": -1, "y": chunks, "x": chunks}
    return chunks


def parse_wavelength(text: str) -> float | None:
    """A band-centre wavelength [nm] from a band description, or None.

    Accepts a number with an optional unit (``"560"``, ``"560 nm"``, ``"0.56 um"``), or a
    description containing a number followed by a unit (``"B3 (560 nm)"``). ``"Band 3"`` is not a
    wavelength.
    """
    if not text:
        return None
    text = text.strip()
    match = re.fullmatch(rf"({_NUMBER})\s*([A-Za-zµμ]*)", text)
    if match is None:
        match = re.search(rf"({_NUMBER})\s*(nm|um|µm|μm|nanometers?|micrometers?|microns?)\b", text, re.I)
    if match is None or match[2].lower() not in _UNITS_TO_NM:
        return None
    return float(match[1]) * _UNITS_TO_NM[match[2].lower()]


def _sentinel2_band(text: str | None) -> str | None:
    """``"B02"`` for a description ``"B02"``, ``"b2"`` or ``"B2"``; ``"B8A"`` for ``"B8A"``; else None."""
    match = re.fullmatch(r"B(0?[1-9]|1[0-2]|8A)", (text or "").strip(), re.I)
    if match is None:
        return None
    number = match[1].upper()
    return "B8A" if number == "8A" else f"B{int(number):02d}"


def _landsat_oli_band(text: str | None) -> int | None:
    """Band number of a Landsat OLI band name (``"SR_B4"``, ``"B4"``, ``"B04"``) of bands 1-7, or None."""
    match = re.fullmatch(r"(?:SR_)?B0?([1-7])", (text or "").strip(), re.I)
    return int(match[1]) if match else None


def _named_band_wavelengths(descriptions, tags) -> tuple[list[float] | None, str]:
    """Wavelengths [nm] from band names, and their origin: Landsat OLI names where a tag states the
    sensor (``sensor``/``SENSOR_ID`` holding ``OLI``), else Sentinel-2 names when every description
    is one. Anything else (a mix, ``SR_B4`` without the sensor): None, no guess."""
    if not descriptions:
        return None, ""
    sensor = next((str(tags[key]) for key in _SENSOR_TAGS if key in tags), "")
    if "OLI" in sensor.upper():
        bands = [_landsat_oli_band(text) for text in descriptions]
        if all(band is not None for band in bands):
            return [LANDSAT_OLI_WAVELENGTHS[band] for band in bands], f"Landsat OLI band names (sensor {sensor})"
        return None, ""
    names = [_sentinel2_band(text) for text in descriptions]
    if all(name is not None for name in names):
        return [SENTINEL2_WAVELENGTHS[name] for name in names], "Sentinel-2 band names"
    return None, ""


def band_wavelengths(image: xr.DataArray, path: str | os.PathLike | None = None,
                     explicit: Sequence[float] | None = None) -> np.ndarray | None:
    """Band-centre wavelengths [nm] of an image, or None when nothing gives them.

    Sources, in the order of ``docs/conventions.md``: ``explicit``; a dataset tag ``wavelength`` with
    comma-separated values (``wavelength_units`` tag honoured, nm by default); band descriptions
    holding a number with an optional unit; band descriptions that are band names, Landsat 8/9 OLI
    names (``SR_B1`` ... ``SR_B7``, ``B1`` ...; :data:`LANDSAT_OLI_WAVELENGTHS`) where a dataset tag
    ``sensor`` or ``SENSOR_ID`` says ``OLI``, else Sentinel-2 names (``B02``, ``B2``, ``B8A``;
    Sentinel-2A centres, :data:`SENTINEL2_WAVELENGTHS`) when every band has one; the ENVI header of
    an ENVI image. Band names that fit neither rule (a mix, ``SR_B4`` without the sensor) give no
    wavelengths rather than a guess.

    Raises
    ------
    InputError
        A source is present but malformed, or gives a count other than the number of bands.
    """
    n_bands = image.sizes[image.dims[0]]
    source = path or image.encoding.get("source", "image")
    envi_header = {}
    if path is not None:
        # The file's own dataset-level tags: rioxarray's attrs mix in the tags of band 1.
        with _opened(path, "image") as dataset:
            tags, descriptions = dataset.tags(), dataset.descriptions
            if dataset.driver == "ENVI":
                envi_header = dataset.tags(ns="ENVI")
    else:
        tags = image.attrs
        descriptions = image.attrs.get("long_name")
        if isinstance(descriptions, str):
            descriptions = (descriptions,) if n_bands == 1 else None
    values = None
    origin = ""
    if explicit is not None:
        values, origin = [float(v) for v in explicit], "the given wavelengths"
    elif "wavelength" in tags:
        text = str(tags["wavelength"])
        try:
            values = [float(v) for v in re.split(r"[,\s]+", text.strip(" {}[]()")) if v]
        except ValueError:
            raise InputError(f"{source}: tag wavelength={text!r} is not a comma-separated list of numbers") from None
        unit = str(tags.get("wavelength_units", "nm")).strip().lower()
        if unit not in _UNITS_TO_NM:
            raise InputError(f"{source}: unknown wavelength_units {unit!r}")
        values = [v * _UNITS_TO_NM[unit] for v in values]
        origin = "tag 'wavelength'"
    else:
        parsed = [parse_wavelength(d or "") for d in descriptions] if descriptions else []
        named, named_origin = _named_band_wavelengths(descriptions, tags)
        if parsed and all(p is not None for p in parsed):
            values, origin = parsed, "band descriptions"
        elif named is not None:
            values, origin = named, named_origin
        elif "wavelength" in envi_header:
            from brdfcorr.io.sensors.envi import envi_wavelengths

            try:
                values, origin = envi_wavelengths(path)[0].tolist(), "ENVI header"
            except BrdfcorrError as error:
                raise InputError(str(error)) from None
    if values is None:
        return None
    if len(values) != n_bands:
        raise InputError(f"{source}: {len(values)} wavelengths from {origin} for {n_bands} bands")
    values = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(values) & (values > 0)):
        raise InputError(f"{source}: wavelengths from {origin} must be finite and > 0 nm")
    return values


def open_image(path, chunks=None, wavelengths: Sequence[float] | None = None, *, scale: float | None = None,
               offset: float | None = None) -> xr.DataArray:
    """Open a reflectance image (band, y, x) lazily as reflectance factors [1], nodata as NaN, with a
    ``wavelength`` coord.

    Stored values are turned into reflectance factors with the file's per-band GDAL scale and
    offset (``reflectance = stored * scale + offset``, as rioxarray's ``mask_and_scale`` does; 1 and
    0 where the file tags none), after masking nodata. ``scale`` and ``offset`` are for products that
    do not tag them: a given value replaces the file's for every band (an explicit scale wins over a
    different tagged one), one not given stays the file's.

    A NEON AOP reflectance HDF5 (``.h5``) or an EMIT L2A reflectance NetCDF (``.nc``), told by
    content, is opened by its reader instead (:func:`brdfcorr.io.sensors.read_neon_image`,
    :func:`brdfcorr.io.sensors.read_emit_image`: the product's scale and nodata, wavelengths and
    FWHM, CRS and transform; EMIT's swath orthorectified onto its GLT grid); ``scale``/``offset``
    given replace the product's.

    Parameters
    ----------
    path : path-like
        Any raster GDAL reads (GeoTIFF, ENVI, ...), or a NEON ``.h5`` / EMIT ``.nc`` image.
    chunks : int or dict, optional
        Dask chunks; an int is the spatial chunk size with all bands in one chunk (default 512).
    wavelengths : sequence of float, optional
        Band centres [nm], overriding what the file says (:func:`band_wavelengths`).
    scale : float, optional
        Reflectance factor per stored unit [1] (> 0), e.g. 0.0001 for reflectance stored as
        0-10000 (default: the file's).
    offset : float, optional
        Reflectance factor of a stored 0 [1], e.g. -0.2 for Landsat Collection 2 level 2
        (default: the file's).

    Returns
    -------
    DataArray
        float32 (float64 for a float64 file), with attrs ``brdf_input_scale`` and
        ``brdf_input_offset``: the scale and offset applied (a float, or a tuple of one per band
        where the bands differ).
    """
    for name, value in (("scale", scale), ("offset", offset)):
        if value is not None and not math.isfinite(value):
            raise InputError(f"image {path}: the given {name} {value} is not a finite number")
    if scale is not None and scale <= 0:
        raise InputError(f"image {path}: the given scale {scale} must be > 0")
    if Path(path).exists():
        product = _hdf5_product(path)
        if product is not None:
            return _open_product(product, path, chunks, wavelengths, scale, offset)
    given = scale is not None or offset is not None
    image = _open(path, "image", _chunks(chunks), masked=True, mask_and_scale=not given)
    metadata = {**image.attrs, **image.encoding}  # scaled by rioxarray: in encoding, else in attrs
    n_bands = image.sizes[image.dims[0]]
    scales = np.broadcast_to(np.asarray(metadata.get("scales", metadata.get("scale_factor", 1.0)), float), n_bands)
    offsets = np.broadcast_to(np.asarray(metadata.get("offsets", metadata.get("add_offset", 0.0)), float), n_bands)
    data = image.data
    if given:  # rioxarray has no override: apply the given (and the file's other) values to the masked values
        scales = np.full(n_bands, float(scale)) if scale is not None else scales
        offsets = np.full(n_bands, float(offset)) if offset is not None else offsets
        data = data * scales.astype(data.dtype)[:, None, None] + offsets.astype(data.dtype)[:, None, None]
    if data.dtype != np.float32 and image.encoding.get("rasterio_dtype") != "float64":
        data = data.astype(np.float32)  # (u)int32 counts are promoted to float64 on read
    # copy(data=): keeps coords, attrs and encoding (``source``, ``_FillValue``), which arithmetic drops.
    image = image.copy(data=data)
    for name in ("scale_factor", "add_offset", "scales", "offsets"):  # the values are physical now
        image.attrs.pop(name, None)
    applied = {"scale": _one_or_per_band(scales), "offset": _one_or_per_band(offsets)}
    if given:  # the storage in encoding, as rioxarray keeps it for a scaled read
        image.encoding.update({"scale_factor" if isinstance(applied["scale"], float) else "scales": applied["scale"],
                               "add_offset" if isinstance(applied["offset"], float) else "offsets": applied["offset"]})
    image.attrs["brdf_input_scale"] = applied["scale"]
    image.attrs["brdf_input_offset"] = applied["offset"]
    found = band_wavelengths(image, path, wavelengths)
    if found is not None:
        image = image.assign_coords(wavelength=(image.dims[0], found, {"units": "nm"}))
    image.name = image.name or "reflectance"
    return image


def _one_or_per_band(values: np.ndarray) -> float | tuple[float, ...]:
    return float(values[0]) if np.all(values == values[0]) else tuple(float(v) for v in values)


def open_classes(path, chunks=None) -> xr.DataArray:
    """Open a class map (y, x) lazily, keeping its integer values and its nodata (``.rio.nodata``)."""
    classes = _open(path, "class map", _chunks(chunks), masked=False)
    if classes.sizes[classes.dims[0]] != 1:
        raise InputError(f"class map {path} has {classes.sizes[classes.dims[0]]} bands; it needs 1")
    if classes.dtype.kind not in "iu":  # a float map is usually a reflectance or a resampled map
        raise InputError(
            f"class map {path} has data type {classes.dtype}; it needs integer class ids "
            "(uint8, uint16, int16, ...): convert it, e.g. gdal_translate -ot UInt16"
        )
    nodata = classes.rio.nodata
    classes = classes.isel({classes.dims[0]: 0}, drop=True)
    classes.name = "classes"
    return classes.rio.write_nodata(nodata) if nodata is not None else classes


def angle_band_name(description: str | None) -> str | None:
    """The angle (``"sza"``, ``"saa"``, ``"vza"``, ``"vaa"``) a band description names, or None.

    Case and spaces/hyphens are ignored (``"Solar Zenith"`` is ``solar_zenith``), and a suffix
    ``_angle`` is allowed (CF standard names: ``solar_zenith_angle``, ``sensor_azimuth_angle``);
    the names are those of :data:`ANGLE_BAND_NAMES`.
    """
    if not description:
        return None
    key = re.sub(r"[\s\-]+", "_", description.strip().lower())
    key = key.removesuffix("_angle")
    return next((angle for angle, names in ANGLE_BAND_NAMES.items() if key in names), None)


def _angle_band_order(path, descriptions) -> dict[str, int]:
    """Band index of each angle of a 4-band angle raster: by band descriptions that name the
    angles, else the documented order sza, saa, vza, vaa."""
    if isinstance(descriptions, str):  # rioxarray keeps one description as a string
        descriptions = (descriptions,)
    descriptions = tuple(descriptions or ())
    named = [angle_band_name(text) for text in descriptions]
    # No descriptions, none naming an angle ("Band 1"), or one on every band (rioxarray describes
    # every band by the array's name: a stack of layers named "sza" says "sza" four times): positional.
    if not any(named) or len(set(descriptions)) == 1:
        return {name: index for index, name in enumerate(ANGLE_NAMES)}
    if len(named) != len(ANGLE_NAMES) or sorted(map(str, named)) != sorted(ANGLE_NAMES):
        shown = ", ".join(repr(text) if text else "(none)" for text in descriptions)
        raise InputError(
            f"angle file {path}: band descriptions {shown} do not name each of sza, saa, vza, vaa once; "
            "describe every band (sza, saa, vza, vaa, or solar_zenith, ...) or none (then the order "
            "is sza, saa, vza, vaa)"
        )
    return {name: index for index, name in enumerate(named)}


def open_angles(path=None, *, sza=None, saa=None, vza=None, vaa=None, chunks=None) -> dict[str, xr.DataArray]:
    """Open the sun/view angles [deg] as four (y, x) arrays, nodata as NaN.

    Either ``path``, a 4-band raster, or four single-band files. The bands of a 4-band raster are
    picked by their band descriptions where these name the angles (:data:`ANGLE_BAND_NAMES`: ``sza``
    or ``solar_zenith``, ..., any case), else (no descriptions, none naming an angle, or the same
    one on every band) taken in the order sza, saa, vza, vaa.

    Raises
    ------
    InputError
        A missing or unreadable file, a wrong band count, or band descriptions that name some
        angles but not each of the four once (one line naming the file and its descriptions).
    """
    separate = {"sza": sza, "saa": saa, "vza": vza, "vaa": vaa}
    given = [name for name, value in separate.items() if value is not None]
    if path is not None and given:
        raise InputError("give either one 4-band angle file or the separate sza/saa/vza/vaa files, not both")
    if path is not None:
        stack = _open(path, "angle", _chunks(chunks), masked=True)
        if stack.sizes[stack.dims[0]] != 4:
            raise InputError(
                f"angle file {path} has {stack.sizes[stack.dims[0]]} bands; it needs 4 (sza, saa, vza, vaa)"
            )
        order = _angle_band_order(path, stack.attrs.get("long_name"))
        return {name: stack.isel({stack.dims[0]: order[name]}, drop=True).rename(name) for name in ANGLE_NAMES}
    missing = [name for name in ANGLE_NAMES if separate[name] is None]
    if missing:
        raise InputError(f"missing angle file(s): {', '.join(missing)} (or give one 4-band angle file)")
    angles = {}
    for name in ANGLE_NAMES:
        layer = _open(separate[name], f"{name} angle", _chunks(chunks), masked=True)
        if layer.sizes[layer.dims[0]] != 1:
            raise InputError(f"{name} angle file {separate[name]} has {layer.sizes[layer.dims[0]]} bands; it needs 1")
        angles[name] = layer.isel({layer.dims[0]: 0}, drop=True).rename(name)
    return angles


class AngleStatistics(NamedTuple):
    """What one pass over the angle layers found (:func:`check_angles`)."""

    ranges: dict[str, tuple[float, float]]
    """(min, max) of the finite values of each layer [deg]."""
    means: dict[str, float]
    """Mean of each layer's values in [0, 90) [deg] (NaN where there is none); ``means["sza"]`` is
    the scene-mean sun zenith of a ``"mean"`` reference geometry."""


def check_angles(layers: Mapping[str, xr.DataArray], source: str | None = None, *, scheduler: str | None = None,
                 num_workers: int | None = None) -> AngleStatistics:
    """Check that sun/view angle layers hold degrees; return their ranges and means [deg].

    One pass over the (lazy) layers, which also gives the scene-mean sun zenith. Pixels with a
    zenith outside [0, 90) are not an error here: :func:`brdfcorr.correct.normalize` flags them
    (QA ``invalid_geometry``) and writes nodata. A layer set that cannot be degrees is an error:
    every zenith below 1.6 with every azimuth below 6.3 (radians: pi/2 and 2 pi), or no zenith of a
    layer in [0, 90) at all (scaled or other units).

    Parameters
    ----------
    layers : mapping of str to DataArray
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] (as from :func:`open_angles`).
    source : str, optional
        Name of the angle source for messages (default: the layers' files).
    scheduler, num_workers : optional
        dask scheduler of the pass and its number of workers (as for :func:`dask.compute`;
        default: dask's).

    Raises
    ------
    InputError
        Naming the angle file (or layer) and the range found.
    """
    names = [name for name in ANGLE_NAMES if name in layers]
    arrays = [layers[name].data for name in names]
    if any(isinstance(a, dask.array.Array) for a in arrays):
        # One small task per chunk for all layers (not one graph per statistic and layer).
        first = next(a for a in arrays if isinstance(a, dask.array.Array))
        arrays = [dask.array.asarray(a).rechunk(first.chunks) for a in arrays]
        per_block = dask.array.map_blocks(
            _angle_statistics, *arrays, new_axis=[2, 3], chunks=(1, 1, len(names), 5), dtype=np.float64,
        ).compute(scheduler=scheduler, num_workers=num_workers)
    else:
        per_block = _angle_statistics(*(np.asarray(a) for a in arrays))
    per_block = per_block.reshape(-1, len(names), 5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN layers: NaN range
        low, high = np.nanmin(per_block[..., 0], axis=0), np.nanmax(per_block[..., 1], axis=0)
    totals = per_block[..., 2:].sum(axis=0)
    ranges = {name: (float(low[i]), float(high[i])) for i, name in enumerate(names)}
    counts = {name: (int(totals[i, 0]), int(totals[i, 1])) for i, name in enumerate(names)}
    means = {name: totals[i, 2] / totals[i, 1] if totals[i, 1] else math.nan for i, name in enumerate(names)}

    def where(name):
        return source or _describe(name, layers[name])

    zeniths = [name for name in ("sza", "vza") if name in ranges and counts[name][0]]
    azimuths = [name for name in ("saa", "vaa") if name in ranges and counts[name][0]]
    if zeniths and azimuths and all(ranges[n][1] < 1.6 for n in zeniths) and all(
            ranges[n][1] < 6.3 for n in azimuths):
        found = ", ".join(f"{n} {ranges[n][0]:.3g}..{ranges[n][1]:.3g}" for n in zeniths + azimuths)
        raise InputError(f"{where(zeniths[0])}: the angles look like radians ({found}); brdfcorr needs degrees")
    for name in zeniths:
        finite, in_domain = counts[name]
        if in_domain == 0:
            lowest, highest = ranges[name]
            raise InputError(
                f"{where(name)}: no {name} value in [0, 90) deg (found {lowest:.6g}..{highest:.6g}); "
                "are the angles scaled or in other units?"
            )
    return AngleStatistics(ranges, means)


def _angle_statistics(*blocks: np.ndarray) -> np.ndarray:
    """(1, 1, n_layers, 5): min, max, finite count, count in [0, 90) and the sum of the values in
    [0, 90) of each (y, x) block."""
    result = np.empty((1, 1, len(blocks), 5))
    for index, block in enumerate(blocks):
        values = block[np.isfinite(block)]
        in_domain = values[(values >= 0) & (values < 90)]
        result[0, 0, index, :2] = (values.min(), values.max()) if values.size else (np.nan, np.nan)
        result[0, 0, index, 2:] = values.size, in_domain.size, in_domain.sum(dtype=np.float64)
    return result


def check_reflectance_scale(image: xr.DataArray, source: str | None = None, *, limit: float = 2.0,
                            blocks: int = 3, scheduler: str | None = None,
                            num_workers: int | None = None) -> float | None:
    """Raise :class:`InputError` if an image stored as integers does not hold reflectance factors
    [1] after scaling (raw counts read without their scale).

    A cheap check, not a pass over the image: it reads at most ``blocks`` x ``blocks`` chunks spread
    evenly over the image (corners, edges and centre) and takes the 99th percentile of their valid
    values. Reflectance factors are mostly 0-1; counts read without their scale (0-10000,
    7273-43636 for Landsat Collection 2) are far above ``limit``. An image stored as floats holds
    physical values (reflectance, or radiance, which corrects as well) and is not checked.

    Parameters
    ----------
    image : DataArray
        (band, y, x) as from :func:`open_image` (attrs ``brdf_input_scale``/``brdf_input_offset``
        name the scaling applied in the message).
    source : str, optional
        Name of the image for the message (default: its file).
    limit : float, default 2.0
        Largest plausible 99th percentile [1].
    blocks : int, default 3
        Chunks sampled along each of y and x.
    scheduler, num_workers : optional
        As for :func:`check_angles`.

    Returns
    -------
    float or None
        The 99th percentile of the sample; None for a float image or a sample without a valid
        value (nothing to judge: no error).
    """
    if np.dtype(image.encoding.get("rasterio_dtype", image.dtype)).kind not in "iu":
        return None
    data = image.data
    where = source or image.encoding.get("source", "image")
    if isinstance(data, dask.array.Array):
        rows, columns = (sorted({int(i) for i in np.linspace(0, n - 1, min(blocks, n)).round()})
                         for n in data.numblocks[-2:])
        messages = _GdalMessages()  # GDAL's log lines of a failed read: into the one error
        try:
            with messages:
                parts = dask.compute(
                    *(dask.delayed(_valid_sample)(data.blocks[..., i, j]) for i in rows for j in columns),
                    scheduler=scheduler, num_workers=num_workers,
                )
        except (OSError, rasterio.errors.RasterioError, CPLE_BaseError) as error:
            reason = "; ".join(messages.messages[:2]) or str(error) or type(error).__name__
            raise InputError(f"cannot read image {where}: {reason}") from None
    else:
        array = np.asarray(data)
        parts = [_valid_sample(array[..., ::max(1, array.shape[-2] // 256), ::max(1, array.shape[-1] // 256)])]
    values = np.concatenate([np.ravel(part) for part in parts])
    if not values.size:
        return None
    percentile = float(np.percentile(values, 99))
    if percentile > limit:
        scale, offset = image.attrs.get("brdf_input_scale", 1.0), image.attrs.get("brdf_input_offset", 0.0)
        raise InputError(
            f"{where}: the values do not look like reflectance factors: 99th percentile {percentile:.5g} "
            f"of a sample of valid pixels (scale {scale}, offset {offset} applied); raw counts? Give the "
            "scale (and offset) of the stored values: --scale/--offset (inputs.scale/inputs.offset in a "
            "chain), e.g. --scale 0.0001 for reflectance stored as 0-10000 (--scale 1: use them as they are)"
        )
    return percentile


def _valid_sample(block: np.ndarray, size: int = 20_000) -> np.ndarray:
    """At most about ``size`` finite values of a block, evenly strided."""
    values = block[np.isfinite(block)]
    return values[::max(1, values.size // size)]


def _describe(name: str, layer: xr.DataArray) -> str:
    source = layer.encoding.get("source")
    return f"{name} ({source})" if source else name


def check_same_grid(layers: Mapping[str, xr.DataArray], reference: str | None = None) -> None:
    """Raise :class:`GridMismatchError` unless all layers share shape, transform and CRS.

    Parameters
    ----------
    layers : mapping of str to DataArray
        Named layers (``{"image": ..., "classes": ...}``), compared on their last two dims.
    reference : str, optional
        The layer the others are compared with (default: the first).
    """
    names = list(layers)
    reference = reference or names[0]
    base = layers[reference]
    base_shape = base.shape[-2:]
    base_transform = base.rio.transform()
    base_crs = base.rio.crs
    for name in names:
        if name == reference:
            continue
        layer = layers[name]
        what = f"{_describe(name, layer)} is not on the grid of {_describe(reference, base)}"
        if layer.shape[-2:] != base_shape:
            raise GridMismatchError(
                f"{what}: shape (rows, columns) {layer.shape[-2:]} differs from {base_shape}"
            )
        crs = layer.rio.crs
        if (crs is None) != (base_crs is None) or (crs is not None and crs != base_crs):
            raise GridMismatchError(f"{what}: CRS {crs} differs from {base_crs}")
        transform = layer.rio.transform()
        if not transform.almost_equals(base_transform, precision=1e-6 * max(abs(base_transform.a), 1e-12)):
            raise GridMismatchError(
                f"{what}: transform {tuple(transform)[:6]} differs from {tuple(base_transform)[:6]}"
            )
