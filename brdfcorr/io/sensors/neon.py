"""NEON AOP imaging-spectrometer reflectance in HDF5: the image cube and its sun and view angles.

Layout followed: the NEON AOP spectrometer reflectance HDF5 of the data products DP1.30006.001
(flight lines) and DP3.30006.001 (1 km mosaic tiles), as NEON's HDF5 file description and its
"NEON AOP Hyperspectral Data in HDF5 format with Python" tutorial document it (also read so by
HyTools' ``open_neon``). One root group named after the site holds everything::

    /<SITE>/Reflectance/Reflectance_Data        (rows, columns, bands) int16, attrs
                                                Scale_Factor (10000), Data_Ignore_Value (-9999)
    /<SITE>/Reflectance/Metadata/Spectral_Data/Wavelength, FWHM     (bands,) [nm]
    /<SITE>/Reflectance/Metadata/Coordinate_System/Map_Info         ENVI map info string
    /<SITE>/Reflectance/Metadata/Coordinate_System/EPSG Code        "32618"
    /<SITE>/Reflectance/Metadata/Coordinate_System/Coordinate_System_String   WKT
    /<SITE>/Reflectance/Metadata/to-sensor_Azimuth_Angle, to-sensor_Zenith_Angle   (rows, columns) [deg]
    /<SITE>/Reflectance/Metadata/Logs/<HHMMSS>/Solar_Azimuth_Angle, Solar_Zenith_Angle   scalars [deg]

(the ``Logs`` values are scalar datasets in NEON's files; attributes of the ``<HHMMSS>`` group are
read too). NEON's ``Scale_Factor`` is a *divisor*: reflectance = stored / Scale_Factor, i.e. stored
x scale with brdfcorr's scale = 1 / Scale_Factor (``brdf_input_scale``), which must be finite and
> 0. Stored values equal to ``Data_Ignore_Value`` are nodata (NaN); an attribute that is NaN or inf
(no fill an int16 cube can hold) means NEON's documented -9999 (:data:`NEON_FILL_VALUE`).

Hostile metadata is refused, never read into a wrong number: attributes and scalars that are no
real number, complex cubes, metadata items declaring more than
:data:`~brdfcorr.io.sensors.hdf5.METADATA_LIMIT` entries (checked before reading), a non-finite map
info, NaN sun angles in the logs, view rasters in radians.

Angle conventions: the to-sensor azimuth is the azimuth of the direction *from the pixel towards
the sensor*, clockwise from north (0-360 deg), as in the JPL obs files of the AVIRIS-NG design NEON's
spectrometer shares (:mod:`brdfcorr.io.sensors.envi`); the solar azimuth of the logs is the sun's
azimuth seen from the ground (pixel towards the sun), clockwise from north. Both are brdfcorr's
convention (``docs/conventions.md``) and are used as stored; ``view_azimuth="from_sensor"`` flips
the view azimuth by 180 deg for a file that differs. The sun angles are one value per flight line:
a DP1 flight line has one log, a DP3 mosaic tile one per flight line it is made of. A mosaic says
which flight line each pixel comes from in ``Metadata/Ancillary_Imagery/Data_Selection_Index``
(rows, columns): the position of the line in its attribute ``Data_Files`` (the lines' file names,
comma-separated, each naming its log, ``..._160559_reflectance``), negative where no line has the
pixel; each pixel then gets the sun of its own line. A tile without that index needs its flight
line named (``flight_line="HHMMSS"``), and a line named is used for every pixel: brdfcorr never
picks one.

The bidirectional products DP1/DP3.30006.002 (2024 on) are already BRDF- and topography-corrected
(FlexBRDF, run with HyTools): told by their Logs' ``BRDF_COEFFS_JSON_for_Hytools`` or
``BRDF_Config_JSON_for_Hytools`` entries or a name ending ``bidirectional_reflectance.h5``, their
image carries the attribute ``brdf_normalized`` (:data:`NEON_BIDIRECTIONAL`), and a correction
refuses it (``brdfcorr correct``, chains: :mod:`brdfcorr.tasks.correct`): correct the directional .001
reflectance. Assessing them is fine.

Reading needs h5py and h5netcdf (``pip install 'brdfcorr[hdf5]'``): metadata is read with h5py, the
cube and the angle rasters lazily, in dask chunks, through xarray's h5netcdf engine.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr
from affine import Affine
from rasterio.crs import CRS
from rasterio.errors import CRSError

from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors.grids import wrap_azimuth
from brdfcorr.io.sensors.hdf5 import as_number, check_transform, on_grid, read_small, require_hdf5, spatial_chunks

__all__ = [
    "is_neon_reflectance",
    "neon_band_count",
    "parse_map_info",
    "read_neon_angles",
    "read_neon_image",
]

#: The ``brdf_normalized`` attribute of a bidirectional (.002) image: what normalized it.
NEON_BIDIRECTIONAL = ("NEON's bidirectional reflectance (DP1/DP3.30006.002: FlexBRDF BRDF and topographic "
                      "correction); correct the directional DP1/DP3.30006.001 reflectance instead")

#: A mosaic tile's raster of the flight line (a position in its ``Data_Files``) each pixel comes from.
_SELECTION = "Ancillary_Imagery/Data_Selection_Index"

#: Log entries that only the bidirectional (.002) products have.
_BRDF_LOGS = ("BRDF_COEFFS_JSON_for_Hytools", "BRDF_Config_JSON_for_Hytools")

#: NEON's fill of reflectance and angle rasters (its ``Data_Ignore_Value``), used where a file's
#: attribute is NaN or inf.
NEON_FILL_VALUE = -9999.0

ANGLE_LONG_NAMES = {
    "sza": "solar zenith angle",
    "saa": "solar azimuth angle (pixel to sun, clockwise from north)",
    "vza": "view zenith angle",
    "vaa": "view azimuth angle (pixel to sensor, clockwise from north)",
}

def _site_group(h5file, path: Path, site: str | None) -> str:
    """Name of the root group holding ``Reflectance/Reflectance_Data`` (the NEON site code)."""
    sites = [name for name in h5file if isinstance(h5file.get(f"{name}/Reflectance/Reflectance_Data"),
                                                    _h5py_dataset())]
    if site is not None:
        if site not in sites:
            raise SensorInputError(f"{path}: no /{site}/Reflectance/Reflectance_Data (sites found: {sites})")
        return site
    if len(sites) != 1:
        raise SensorInputError(
            f"{path}: {len(sites)} root groups with Reflectance/Reflectance_Data ({sites}); a NEON AOP "
            "reflectance file has one (the site code); name it with site=..."
        )
    return sites[0]


def _h5py_dataset():
    import h5py

    return h5py.Dataset


def is_neon_reflectance(path: str | Path) -> bool:
    """True if ``path`` is an HDF5 file laid out as a NEON AOP reflectance file (one root group
    with ``Reflectance/Reflectance_Data``). Needs h5py (:func:`require_hdf5`)."""
    h5py = require_hdf5(path)
    try:
        with h5py.File(path, "r") as h5file:
            return any(isinstance(h5file.get(f"{name}/Reflectance/Reflectance_Data"), h5py.Dataset)
                       for name in h5file)
    except OSError:
        return False


def _text(value) -> str:
    """A string from an HDF5 scalar (bytes, str, or a one-element array of either)."""
    values = np.asarray(value).ravel()
    value = values[0] if values.size else ""
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def parse_map_info(text: str, source: str = "Map_Info") -> Affine:
    """Pixel-corner affine transform from an ENVI ``map info`` string.

    The items are: projection name, reference pixel x and y (1-based file coordinates, (1, 1) the
    upper-left corner of the upper-left pixel), the easting and northing of that reference point,
    the pixel sizes in x and y [CRS units], then zone, hemisphere, datum, ``units=``,
    ``rotation=``. As GDAL's ENVI driver: x0 = easting - (ref_x - 1) * dx,
    y0 = northing + (ref_y - 1) * dy.

    Examples
    --------
    >>> parse_map_info("UTM, 1.000, 1.000, 368000.0, 4307000.0, 1.0, 1.0, 18, North, WGS-84, units=Meters")
    Affine(1.0, 0.0, 368000.0,
           0.0, -1.0, 4307000.0)

    Raises
    ------
    SensorInputError
        Fewer than seven items, non-numeric ones, or a rotation (not supported).
    """
    items = [item.strip() for item in text.strip().strip("{}").split(",")]
    try:
        ref_x, ref_y, easting, northing, dx, dy = (float(item) for item in items[1:7])
    except ValueError:
        raise SensorInputError(f"{source}: {text!r} is not an ENVI map info (numbers expected in items 2-7)") from None
    rotation = next((item for item in items if item.lower().startswith("rotation")), None)
    if rotation is not None and float(re.sub(r"[^0-9.eE+-]", "", rotation.split("=")[-1]) or 0) != 0.0:
        raise SensorInputError(f"{source}: a rotated map info ({rotation}) is not supported")
    check_transform((ref_x, ref_y, easting, northing, dx, dy), f"{source} {text!r}")
    if dx <= 0 or dy <= 0:
        raise SensorInputError(f"{source}: pixel sizes {dx}, {dy} in {text!r} must be > 0")
    return Affine(dx, 0.0, easting - (ref_x - 1.0) * dx, 0.0, -dy, northing + (ref_y - 1.0) * dy)


def _crs(coordinates, path: Path) -> CRS | None:
    """CRS from ``EPSG Code``, else ``Coordinate_System_String`` (WKT), else ``Proj4``."""
    for name, parse in (("EPSG Code", lambda text: CRS.from_epsg(int(float(text)))),
                        ("Coordinate_System_String", CRS.from_wkt), ("Proj4", CRS.from_proj4)):
        if name in coordinates:
            text = _text(read_small(coordinates[name], f"{path}: Coordinate_System/{name}"))
            try:
                return parse(text)
            except (CRSError, ValueError) as error:
                raise SensorInputError(f"{path}: Coordinate_System/{name} {text!r} is no CRS ({error})") from None
    return None


def _metadata(path: Path, site: str | None) -> dict:
    """Everything but the big arrays: site, shape, scaling, wavelengths, grid, logs. Every item is
    checked before it is read (type, size: :func:`read_small`)."""
    h5py = require_hdf5(path)
    try:
        h5file = h5py.File(path, "r")
    except OSError as error:
        raise SensorInputError(f"{path}: cannot open as HDF5 ({error})") from None
    with h5file:
        site = _site_group(h5file, path, site)
        group = h5file[f"{site}/Reflectance"]
        data = group["Reflectance_Data"]
        if data.ndim != 3:
            raise SensorInputError(f"{path}: Reflectance_Data has {data.ndim} dimensions; NEON's has 3 "
                                   "(rows, columns, bands)")
        _check_real(data, f"{path}: Reflectance_Data")
        metadata = group.get("Metadata")
        if metadata is None:
            raise SensorInputError(f"{path}: no /{site}/Reflectance/Metadata group")
        missing = [name for name in ("Spectral_Data/Wavelength", "Coordinate_System/Map_Info") if name not in metadata]
        if missing:
            raise SensorInputError(f"{path}: no {', '.join(missing)} in /{site}/Reflectance/Metadata")
        where = f"{path}: Metadata/"
        info = {
            "site": site, "shape": data.shape, "dtype": data.dtype,
            "scale_factor": as_number(data.attrs.get("Scale_Factor", 1.0), f"{path}: Reflectance_Data Scale_Factor"),
            "ignore": _ignore_value(data.attrs, f"{path}: Reflectance_Data"),
            "wavelength": _numbers(metadata["Spectral_Data/Wavelength"], f"{where}Spectral_Data/Wavelength"),
            "wavelength_units": _text(metadata["Spectral_Data/Wavelength"].attrs.get("Units", "nanometers")),
            "fwhm": (_numbers(metadata["Spectral_Data/FWHM"], f"{where}Spectral_Data/FWHM")
                     if "Spectral_Data/FWHM" in metadata else None),
            "transform": parse_map_info(_text(read_small(metadata["Coordinate_System/Map_Info"],
                                                         f"{where}Coordinate_System/Map_Info")), f"{path}: Map_Info"),
            "crs": _crs(metadata["Coordinate_System"], path),
            "logs": _logs(metadata.get("Logs"), f"{where}Logs"),
            "bidirectional": path.name.endswith("bidirectional_reflectance.h5") or any(
                name in getattr(log, "keys", lambda: ())() for log in (metadata.get("Logs") or {}).values()
                for name in _BRDF_LOGS),
            "angle_rasters": [name for name in ("to-sensor_Azimuth_Angle", "to-sensor_Zenith_Angle")
                              if name in metadata],
        }
        info["angle_ignore"] = {name: _ignore_value(metadata[name].attrs, f"{where}{name}", info["ignore"])
                                for name in info["angle_rasters"]}
        selection = metadata.get(_SELECTION)
        info["selection_files"] = (
            tuple(name.strip() for name in _text(selection.attrs["Data_Files"]).split(",") if name.strip())
            if selection is not None and "Data_Files" in selection.attrs else None)
        for name in info["angle_rasters"]:
            _check_real(metadata[name], f"{where}{name}")
    return info


def _check_real(dataset, source: str) -> None:
    """Refuse a dataset that holds no real numbers (complex: its imaginary part would be lost)."""
    if dataset.dtype.kind not in "biuf":
        raise SensorInputError(f"{source} holds {dataset.dtype} values; real numbers are expected")


def _numbers(dataset, source: str) -> np.ndarray:
    """A small dataset of real numbers (wavelengths, FWHM) as float64, checked before it is read."""
    _check_real(dataset, source)
    return np.asarray(read_small(dataset, source), dtype=float).ravel()


def _ignore_value(attrs, source: str, default: float | None = None) -> float | None:
    """``Data_Ignore_Value`` of a dataset (``default`` where it has none). NaN or inf is no fill
    value an integer cube can hold: NEON's documented fill, :data:`NEON_FILL_VALUE`, is used
    instead, so that stored -9999 values stay nodata (NaN taken as the fill made them reflectance -1)."""
    if "Data_Ignore_Value" not in attrs:
        return default
    value = as_number(attrs["Data_Ignore_Value"], f"{source} Data_Ignore_Value")
    return value if math.isfinite(value) else NEON_FILL_VALUE


def _logs(logs, source: str) -> dict[str, dict[str, float]]:
    """``{flight line: {"Solar_Zenith_Angle": ..., "Solar_Azimuth_Angle": ...}}`` from the Logs
    group: scalar datasets, or attributes of the flight line's group."""
    found: dict[str, dict[str, float]] = {}
    for line, group in (logs or {}).items():
        values = {}
        for name in ("Solar_Zenith_Angle", "Solar_Azimuth_Angle"):
            where = f"{source}/{line}/{name}"
            if name in getattr(group, "keys", lambda: ())():
                values[name] = as_number(read_small(group[name], where, limit=1), where)
            elif name in getattr(group, "attrs", {}):
                values[name] = as_number(group.attrs[name], where)
        if values:
            found[line] = values
    return found


def neon_band_count(path: str | Path) -> int:
    """Number of bands of a NEON AOP reflectance file (the last dimension of Reflectance_Data)."""
    return int(_metadata(Path(path), None)["shape"][2])


def _open_lazy(path: Path, group: str) -> xr.Dataset:
    """A group of the file as a lazy Dataset (h5netcdf engine, no CF decoding, no caching)."""
    return xr.open_dataset(path, engine="h5netcdf", group=group, phony_dims="sort", mask_and_scale=False,
                           decode_times=False, cache=False)


def read_neon_image(path: str | Path, chunks=None, *, site: str | None = None, scale: float | None = None,
                    offset: float | None = None) -> xr.DataArray:
    """Open a NEON AOP reflectance HDF5 cube lazily as reflectance factors (band, y, x).

    Parameters
    ----------
    path : str or Path
        The ``NEON_D.._<SITE>_DP1_..._reflectance.h5`` (or DP3 tile) file.
    chunks : int or dict, optional
        Spatial chunk size [pixels] (or a dict with ``"y"``, ``"x"``); all bands in one chunk.
        Default 512.
    site : str, optional
        The root group (site code); needed only if the file has several.
    scale, offset : float, optional
        Reflectance factor per stored unit and of a stored 0 [1], replacing the file's
        (1 / ``Scale_Factor`` and 0).

    Returns
    -------
    xarray.DataArray
        float32 (band, y, x), dask-backed: ``stored * scale + offset`` with ``Data_Ignore_Value`` as
        NaN; coords ``wavelength`` and ``fwhm`` [nm] along ``band``; CRS and transform from the
        file's ``EPSG Code`` and ``Map_Info``; attrs ``brdf_input_scale`` and ``brdf_input_offset``.

    Raises
    ------
    SensorInputError
        A file not laid out as NEON's (the message names the missing item).
    """
    path = Path(path)
    info = _metadata(path, site)
    n_bands = info["shape"][2]
    wavelength, fwhm = info["wavelength"], info["fwhm"]
    if wavelength.size != n_bands or (fwhm is not None and fwhm.size != n_bands):
        raise SensorInputError(
            f"{path}: {wavelength.size} wavelengths and {None if fwhm is None else fwhm.size} FWHM values "
            f"in Metadata/Spectral_Data for {n_bands} bands"
        )
    unit = info["wavelength_units"].strip().lower()
    factor = 1e3 if unit in ("micrometers", "micrometer", "microns", "micron", "um") else 1.0
    if scale is None and not (math.isfinite(info["scale_factor"]) and info["scale_factor"] > 0):
        raise SensorInputError(f"{path}: Reflectance_Data Scale_Factor {info['scale_factor']} must be a finite "
                               "number > 0 (reflectance = stored / Scale_Factor); give the scale to override it")
    stored = _open_lazy(path, f"/{info['site']}/Reflectance")["Reflectance_Data"]
    stored = stored.rename(dict(zip(stored.dims, ("y", "x", "band")))).transpose("band", "y", "x")
    rows, cols = spatial_chunks(chunks)
    stored = stored.chunk({"band": -1, "y": rows, "x": cols})
    valid = stored != info["ignore"] if info["ignore"] is not None else True
    if scale is None:  # NEON's Scale_Factor divides: dividing is exact where multiplying by 1e-4 rounds
        values = stored.astype("float32") / np.float32(info["scale_factor"])
        applied_scale = 1.0 / info["scale_factor"]
    else:
        values = stored.astype("float32") * np.float32(scale)
        applied_scale = float(scale)
    if offset:
        values = values + np.float32(offset)
    image = values.where(valid).astype("float32")
    image = image.assign_coords(
        band=np.arange(1, n_bands + 1),
        wavelength=("band", wavelength * factor, {"units": "nm", "long_name": "band-centre wavelength"}),
    )
    if fwhm is not None:
        image = image.assign_coords(fwhm=("band", fwhm * factor, {"units": "nm",
                                                                  "long_name": "full width at half maximum"}))
    image = on_grid(image, info["transform"], info["crs"])
    image.attrs = {"brdf_input_scale": applied_scale, "brdf_input_offset": float(offset or 0.0),
                   "units": "1", "long_name_product": "NEON AOP reflectance"}
    if info["bidirectional"]:
        image.attrs["brdf_normalized"] = NEON_BIDIRECTIONAL
    image.encoding.update({"source": str(path), "rasterio_dtype": str(info["dtype"])})
    image.name = "reflectance"
    return image


def read_neon_angles(path: str | Path, like: xr.DataArray | None = None, *, view_azimuth: str = "to_sensor",
                     flight_line: str | None = None, site: str | None = None, chunks=None) -> xr.Dataset:
    """Sun and view angles [deg] of a NEON AOP reflectance HDF5 file on its image grid.

    Parameters
    ----------
    path : str or Path
        The NEON reflectance file (the same file as the image).
    like : xarray.DataArray, optional
        The image the angles are for: its (y, x) chunks are taken (the grid itself is checked by
        :func:`brdfcorr.io.grid.check_same_grid` in :func:`brdfcorr.io.scene.open_scene`).
    view_azimuth : {"to_sensor", "from_sensor"}
        What ``to-sensor_Azimuth_Angle`` holds: "to_sensor" for NEON (the default, see the module
        notes); "from_sensor" flips it by 180 deg.
    flight_line : str, optional
        The ``Logs`` group (``"HHMMSS"``) whose sun angles to use for every pixel. Default: the
        only one logged, or, for a mosaic tile of several, each pixel's own
        (``Data_Selection_Index``); a tile of several without that index needs one named.
    site : str, optional
        The root group (site code), where the file has several.
    chunks : int or dict, optional
        Spatial chunks (default: ``like``'s, else 512).

    Returns
    -------
    xarray.Dataset
        ``sza``, ``saa`` (the flight line's, or each pixel's line's) and ``vza``, ``vaa`` (per pixel) on (y, x),
        dask-backed, nodata (``Data_Ignore_Value``) as NaN, azimuths in [0, 360) towards the sun
        and the sensor, with the file's CRS and transform.

    Raises
    ------
    SensorInputError
        Missing angle rasters or logs, several flight lines and none named, a bad option.
    """
    path = Path(path)
    if view_azimuth not in ("to_sensor", "from_sensor"):
        raise SensorInputError(f"view_azimuth must be 'to_sensor' or 'from_sensor', got {view_azimuth!r}")
    info = _metadata(path, site)
    if len(info["angle_rasters"]) != 2:
        raise SensorInputError(
            f"{path}: no to-sensor_Azimuth_Angle and to-sensor_Zenith_Angle rasters in "
            f"/{info['site']}/Reflectance/Metadata"
        )
    by_pixel = flight_line is None and info["selection_files"] is not None and len(_complete(info["logs"])) > 1
    sun = None if by_pixel else _flight_line_sun(path, info["logs"], flight_line)
    _check_degrees(path, info)
    if chunks is None and like is not None and like.chunks:
        chunks = {"y": like.chunksizes["y"], "x": like.chunksizes["x"]}
    rows, cols = spatial_chunks(chunks)
    metadata = _open_lazy(path, f"/{info['site']}/Reflectance/Metadata")
    variables = {}
    for key, name in (("vza", "to-sensor_Zenith_Angle"), ("vaa", "to-sensor_Azimuth_Angle")):
        stored = metadata[name]
        if stored.shape != info["shape"][:2]:
            raise SensorInputError(f"{path}: {name} is {stored.shape}, the reflectance {info['shape'][:2]}")
        stored = stored.rename(dict(zip(stored.dims, ("y", "x")))).chunk({"y": rows, "x": cols})
        ignore = info["angle_ignore"].get(name, info["ignore"])
        angle = stored.astype("float64")
        if ignore is not None:
            angle = angle.where(stored != ignore)
        if key == "vaa":
            angle = wrap_azimuth(angle + 180.0) if view_azimuth == "from_sensor" else wrap_azimuth(angle)
        variables[key] = angle.assign_attrs(units="degree", long_name=ANGLE_LONG_NAMES[key], source_item=name)
    if by_pixel:
        variables.update(_sun_by_pixel(path, info, rows, cols))
    else:
        for key, name in (("sza", "Solar_Zenith_Angle"), ("saa", "Solar_Azimuth_Angle")):
            value = sun[name] % 360.0 if key == "saa" else sun[name]
            variables[key] = xr.full_like(variables["vza"], value).assign_attrs(
                units="degree", long_name=ANGLE_LONG_NAMES[key], source_item=f"Logs/{sun['line']}/{name}")
    angles = xr.Dataset({key: on_grid(variables[key].rename(key), info["transform"], info["crs"])
                         for key in ("sza", "saa", "vza", "vaa")})
    angles.attrs = {"source": str(path), "source_kind": "neon",
                    "flight_line": "each pixel's (Data_Selection_Index)" if by_pixel else sun["line"],
                    "view_azimuth_stored": view_azimuth}
    return angles


def _sun_by_pixel(path: Path, info: dict, rows, cols) -> dict[str, xr.DataArray]:
    """``sza`` and ``saa`` [deg] of each pixel of a mosaic tile: the sun of the flight line its
    ``Data_Selection_Index`` names (a position in ``Data_Files``), NaN where it names none."""
    complete = _complete(info["logs"])
    lines = []
    for name in info["selection_files"]:
        matching = [line for line in complete if line in name]
        if len(matching) != 1:
            raise SensorInputError(
                f"{path}: {_SELECTION} Data_Files entry {name!r} names {len(matching)} of the flight lines in "
                f"Metadata/Logs ({', '.join(sorted(complete))}); name the one to use: flight_line=HHMMSS")
        lines.append(_flight_line_sun(path, info["logs"], matching[0]))
    group, dataset = _SELECTION.split("/")
    index = _open_lazy(path, f"/{info['site']}/Reflectance/Metadata/{group}")[dataset]
    if index.shape != info["shape"][:2] or index.dtype.kind not in "iu":
        raise SensorInputError(f"{path}: {_SELECTION} is {index.shape} {index.dtype}; it must hold integer line "
                               f"positions for the reflectance's {info['shape'][:2]} pixels")
    index = index.rename(dict(zip(index.dims, ("y", "x")))).chunk({"y": rows, "x": cols})
    found = {}
    for key, name in (("sza", "Solar_Zenith_Angle"), ("saa", "Solar_Azimuth_Angle")):
        table = np.array([line[name] % 360.0 if key == "saa" else line[name] for line in lines] + [np.nan])
        values = index.data.map_blocks(_lookup, table=table, dtype=np.float64)
        found[key] = xr.DataArray(values, dims=("y", "x"), coords=index.coords, attrs={
            "units": "degree", "long_name": ANGLE_LONG_NAMES[key],
            "source_item": f"Logs/<each pixel's line: {_SELECTION}>/{name}"})
    return found


def _lookup(positions: np.ndarray, *, table: np.ndarray) -> np.ndarray:
    """``table[positions]``, its last entry (NaN) where a position is outside the lines (no line)."""
    outside = (positions < 0) | (positions >= table.size - 1)
    return table[np.where(outside, table.size - 1, positions)]


def _complete(logs: dict) -> dict:
    """The flight lines of the logs with both sun angles."""
    return {line: values for line, values in logs.items() if len(values) == 2}


def _flight_line_sun(path: Path, logs: dict, flight_line: str | None) -> dict:
    """The sun zenith and azimuth [deg] of the chosen (or only) flight line of the logs."""
    complete = _complete(logs)
    if not complete:
        raise SensorInputError(f"{path}: no Metadata/Logs/<flight line>/Solar_Zenith_Angle and "
                               "Solar_Azimuth_Angle")
    if flight_line is None:
        if len(complete) > 1:
            raise SensorInputError(
                f"{path}: sun angles of {len(complete)} flight lines in Metadata/Logs ({', '.join(sorted(complete))}); "
                "name one: flight_line=HHMMSS (--angle-option flight_line=...)"
            )
        flight_line = next(iter(complete))
    # A flight line given on the command line is read as a YAML number (070512 -> 70512): match digits.
    flight_line = next((line for line in complete if line == str(flight_line)
                        or (line.isdigit() and line.lstrip("0") == str(flight_line).lstrip("0"))), str(flight_line))
    if flight_line not in complete:
        raise SensorInputError(f"{path}: no sun angles of flight line {flight_line!r} in Metadata/Logs "
                               f"(found: {', '.join(sorted(complete))})")
    bad = {name: value for name, value in complete[flight_line].items() if not math.isfinite(value)}
    if bad:  # a constant layer: every pixel would be nodata
        shown = ", ".join(f"{name} {value}" for name, value in bad.items())
        raise SensorInputError(f"{path}: Metadata/Logs/{flight_line}: {shown}; the sun angles must be "
                               "finite numbers [deg]")
    return {**complete[flight_line], "line": flight_line}


#: Samples per axis of the view rasters read to tell degrees from radians (:func:`_check_degrees`).
_SAMPLES = 256


def _check_degrees(path: Path, info: dict) -> None:
    """Refuse view rasters in radians: ``to-sensor_Zenith_Angle`` below pi/2 and
    ``to-sensor_Azimuth_Angle`` below 2 pi everywhere (NEON stores degrees; its spectrometer sees
    up to about 17 deg off nadir on either side of the line, so degrees are never all that small).
    Read on a sparse regular sample of at most :data:`_SAMPLES` x :data:`_SAMPLES` pixels, after
    their shapes are checked against the cube's. (The sun angles of the logs are single numbers:
    too few to tell their unit by.)"""
    h5py = require_hdf5(path)
    highest = {}
    steps = [max(1, size // _SAMPLES) for size in info["shape"][:2]]
    with h5py.File(path, "r") as h5file:
        metadata = h5file[f"{info['site']}/Reflectance/Metadata"]
        for name in ("to-sensor_Zenith_Angle", "to-sensor_Azimuth_Angle"):
            if metadata[name].shape != info["shape"][:2]:
                raise SensorInputError(f"{path}: {name} is {metadata[name].shape}, the reflectance {info['shape'][:2]}")
            values = np.asarray(metadata[name][::steps[0], ::steps[1]], dtype=float)
            ignore = info["angle_ignore"].get(name)
            values = values[np.isfinite(values) & ((values != ignore) if ignore is not None else True)]
            if values.size == 0:
                return  # nothing to judge here: the angle check names a layer without values
            highest[name] = float(values.max())
    if highest["to-sensor_Zenith_Angle"] < 1.6 and highest["to-sensor_Azimuth_Angle"] < 6.3:
        found = ", ".join(f"{name} up to {value:.3g}" for name, value in highest.items())
        raise SensorInputError(f"{path}: the view angle rasters look like radians ({found}); brdfcorr needs "
                               "degrees, as NEON stores them")
