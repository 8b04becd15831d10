"""EMIT L2A surface reflectance and L1B observation geometry (NetCDF-4), orthorectified by the GLT.

Layout followed: EMIT L2A RFL and L1B OBS V001 NetCDF granules as the EMIT Data Product User
Guide and the LP DAAC ``emit_tools`` document them::

    EMIT_L2A_RFL_001_<time>_<orbit>_<scene>.nc
      reflectance                      (downtrack, crosstrack, bands) float32, _FillValue -9999
      sensor_band_parameters/wavelengths, fwhm      (bands,) [nm]; good_wavelengths (bands,) 1/0
      location/glt_x, glt_y            (ortho_y, ortho_x) int32: 1-based crosstrack (glt_x) and
                                       downtrack (glt_y) index of the swath pixel seen at each
                                       orthorectified cell; 0 = no pixel
      location/lat, lon                (downtrack, crosstrack) [deg]
      global attrs geotransform        GDAL order (x0, dx, 0, y0, 0, dy) of the GLT grid's corners
                   spatial_ref         WKT of its CRS (EPSG:4326)
    EMIT_L1B_OBS_001_<time>_<orbit>_<scene>.nc
      obs                              (downtrack, crosstrack, bands) float32, _FillValue -9999
      sensor_band_parameters/observation_bands      (bands,) names: "Path length ...",
                                       "To-sensor azimuth (0 to 360 degrees CW from N)",
                                       "To-sensor zenith ...", "To-sun azimuth ...", "To-sun zenith ...",
                                       "Solar phase ...", ...
      location/glt_x, glt_y and the global attrs as above

The swath (downtrack, crosstrack) is brought onto the GLT grid (y, x) by nearest-pixel lookup,
:func:`apply_glt`: ``ortho[:, i, j] = swath[glt_y[i, j] - 1, glt_x[i, j] - 1, :]`` where both GLT
values are > 0, NaN where either is 0 (a float GLT only where all its values are integers;
fractional, NaN or negative values, and a grid of more than :data:`GLT_CELLS_PER_PIXEL` cells per
swath pixel, are refused; an obs granule must share the reflectance granule's GLT, not only its
geotransform). This is what EMIT's own ``apply_glt`` does; brdfcorr does it
lazily: the GLT (two small integer rasters) is read into memory, and each output chunk is one dask
task that reads only the bounding box of the swath rows and columns its cells point to, then
indexes it with numpy (vectorised, no loop over pixels).

Angle convention: EMIT's obs bands follow the JPL obs convention of AVIRIS-NG
(:mod:`brdfcorr.io.sensors.envi`): "To-sensor azimuth (0 to 360 degrees CW from N)" is the azimuth of
the direction *from the pixel towards the sensor*, "To-sun azimuth" that towards the sun, both
clockwise from north: brdfcorr's convention (``docs/conventions.md``), used as stored;
``view_azimuth="from_sensor"`` flips the view azimuth for a product that differs. Bands are found by
their names (as for ENVI obs files), never by position.

Reading needs h5py and h5netcdf (``pip install 'brdfcorr[hdf5]'``).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path

import dask
import dask.array as da
import numpy as np
import xarray as xr
from affine import Affine
from dask.base import tokenize
from rasterio.crs import CRS
from rasterio.errors import CRSError

from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors.envi import ANGLE_LONG_NAMES, OBS_BAND_NAMES, _obs_band_index, wanted_bands
from brdfcorr.io.sensors.grids import wrap_azimuth
from brdfcorr.io.sensors.hdf5 import METADATA_LIMIT, as_number, check_transform, on_grid, require_hdf5, spatial_chunks

__all__ = [
    "apply_glt",
    "emit_band_count",
    "is_emit_reflectance",
    "read_emit_image",
    "read_emit_obs",
    "read_glt",
]

#: _FillValue of EMIT's reflectance and obs variables when the variable does not state one.
EMIT_FILL_VALUE = -9999.0
#: Largest distance [index units] of a float GLT value from an integer that is still that integer.
GLT_TOLERANCE = 1e-6
#: Most cells of an orthorectified grid per swath pixel: the grid covers the swath's footprint (a
#: swath rotated 45 deg fills about half of it); far more is a damaged or hostile granule.
GLT_CELLS_PER_PIXEL = 64
#: Most cells of a GLT grid at all (two int64 layers of 4 GiB).
GLT_MAX_CELLS = 2**28


def is_emit_reflectance(path: str | Path) -> bool:
    """True if ``path`` is laid out as an EMIT L2A reflectance granule (root ``reflectance``,
    ``location/glt_x`` and ``glt_y``, ``sensor_band_parameters``). Needs h5py."""
    h5py = require_hdf5(path)
    try:
        with h5py.File(path, "r") as h5file:
            return all(isinstance(h5file.get(name), h5py.Dataset) for name in
                       ("reflectance", "location/glt_x", "location/glt_y", "sensor_band_parameters/wavelengths"))
    except OSError:
        return False


def emit_band_count(path: str | Path) -> int:
    """Number of bands of an EMIT L2A reflectance granule."""
    h5py = require_hdf5(path)
    with h5py.File(path, "r") as h5file:
        return int(h5file["reflectance"].shape[-1])


def apply_glt(swath: np.ndarray, glt_x: np.ndarray, glt_y: np.ndarray, row0: int = 0, col0: int = 0) -> np.ndarray:
    """Orthorectify (a box of) a swath with a geometry lookup table, by nearest pixel.

    Parameters
    ----------
    swath : ndarray, (rows, columns, bands)
        Swath values, or the box of the swath that starts at downtrack row ``row0`` and crosstrack
        column ``col0`` (0-based) and holds every pixel the GLT cells point to.
    glt_x, glt_y : ndarray of int, (ny, nx)
        1-based crosstrack (``glt_x``) and downtrack (``glt_y``) indices; 0 = no pixel.
    row0, col0 : int
        Offset of the box in the swath.

    Returns
    -------
    ndarray, (bands, ny, nx)
        float, NaN where the GLT has no pixel:
        ``out[:, i, j] = swath[glt_y[i, j] - 1 - row0, glt_x[i, j] - 1 - col0, :]``.
    """
    valid = (glt_x > 0) & (glt_y > 0)
    dtype = np.result_type(swath.dtype, np.float32)
    out = np.full((swath.shape[2], *glt_x.shape), np.nan, dtype=dtype)
    out[:, valid] = swath[glt_y[valid] - 1 - row0, glt_x[valid] - 1 - col0, :].T
    return out


def read_glt(path: str | Path, swath_shape: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The GLT ``(glt_x, glt_y)`` of an EMIT granule as int64 arrays, checked.

    A float GLT is taken only where every value is an integer within :data:`GLT_TOLERANCE` (then
    rounded to it): truncating fractional indices would shift pixels.

    Raises
    ------
    SensorInputError
        Missing ``location/glt_x``/``glt_y``, shapes that differ, a grid larger than the swath
        can fill (checked before it is read), NaN, inf or fractional values, negative values, or
        indices beyond the swath (``swath_shape``: rows, columns).
    """
    h5py = require_hdf5(path)
    with h5py.File(path, "r") as h5file:
        if "location/glt_x" not in h5file or "location/glt_y" not in h5file:
            raise SensorInputError(f"{path}: no location/glt_x and location/glt_y (the geometry lookup table)")
        datasets = h5file["location/glt_x"], h5file["location/glt_y"]
        _check_glt_shape(path, datasets[0].shape, datasets[1].shape, swath_shape)
        glt_x, glt_y = (_glt_indices(path, dataset) for dataset in datasets)
    if (glt_x < 0).any() or (glt_y < 0).any():
        raise SensorInputError(f"{path}: negative values in location/glt_x or glt_y (1-based indices, 0 = no pixel)")
    if swath_shape is not None and (glt_y.max(initial=0) > swath_shape[0] or glt_x.max(initial=0) > swath_shape[1]):
        raise SensorInputError(
            f"{path}: the GLT points beyond the swath of {swath_shape[0]} x {swath_shape[1]} pixels "
            f"(largest glt_y {glt_y.max()}, glt_x {glt_x.max()})"
        )
    return glt_x, glt_y


def _check_glt_shape(path, shape_x, shape_y, swath_shape) -> None:
    """Refuse, before reading, GLT grids that differ, are not 2-D, or have more cells than the swath
    can fill (:data:`GLT_CELLS_PER_PIXEL`, :data:`GLT_MAX_CELLS`)."""
    if shape_x != shape_y or len(shape_x) != 2:
        raise SensorInputError(f"{path}: location/glt_x {shape_x} and glt_y {shape_y} must be one 2-D grid")
    cells = shape_x[0] * shape_x[1]
    limit = GLT_MAX_CELLS
    if swath_shape is not None:
        limit = min(limit, GLT_CELLS_PER_PIXEL * max(1, swath_shape[0] * swath_shape[1]))
    if cells > limit:
        swath = f" for a swath of {swath_shape[0]} x {swath_shape[1]} pixels" if swath_shape is not None else ""
        raise SensorInputError(f"{path}: location/glt_x declares {shape_x[0]} x {shape_x[1]} cells{swath}; "
                               f"an orthorectified grid of at most {limit} cells is expected")


def _glt_indices(path, dataset) -> np.ndarray:
    """One GLT layer as int64: integers as they are, floats only where all are integers (rounded);
    cells holding the layer's declared ``_FillValue`` (-9999, as EMIT's NetCDF converter declares
    it) are 0, no pixel, as EMIT's own tools read them (its granules hold 0 there)."""
    name = dataset.name.lstrip("/")
    values = np.asarray(dataset[()])
    fill = dataset.attrs.get("_FillValue")
    if fill is not None and np.size(fill) == 1 and np.isfinite(fill):
        values = np.where(values == np.asarray(fill).item(), 0, values)
    if values.dtype.kind in "iub":
        return values.astype(np.int64)
    if values.dtype.kind != "f":
        raise SensorInputError(f"{path}: {name} holds {values.dtype} values; GLT indices are integers")
    bad = ~np.isfinite(values)
    if bad.any():
        raise SensorInputError(f"{path}: {name} holds {int(bad.sum())} NaN or infinite values; GLT indices "
                               "are integers (0 = no pixel)")
    nearest = np.rint(values)
    off = np.abs(values - nearest)
    if off.max(initial=0.0) > GLT_TOLERANCE:
        where = np.unravel_index(int(np.argmax(off)), values.shape)
        raise SensorInputError(f"{path}: {name} holds fractional indices (e.g. {values[where]:.6g} at cell "
                               f"{tuple(int(i) for i in where)}); GLT indices are integers (0 = no pixel)")
    return nearest.astype(np.int64)


def _grid(path: Path, attrs: Mapping) -> tuple[Affine, CRS | None]:
    """The GLT grid's transform and CRS from the global attrs ``geotransform`` and ``spatial_ref``."""
    if "geotransform" not in attrs:
        raise SensorInputError(f"{path}: no global attribute 'geotransform' (the GLT grid)")
    raw = np.asarray(attrs["geotransform"])
    if raw.dtype.kind not in "iuf":
        raise SensorInputError(f"{path}: geotransform {str(attrs['geotransform'])[:80]!r} is {raw.dtype.name} "
                               "data, not 6 numbers (GDAL order)")
    values = raw.astype(float).ravel()
    if values.size != 6:
        raise SensorInputError(f"{path}: geotransform has {values.size} values; it needs 6 (GDAL order)")
    check_transform(values, str(path))
    if values[1] == 0 or values[5] == 0:
        raise SensorInputError(f"{path}: geotransform {tuple(values)} has a pixel size of 0")
    crs = None
    if "spatial_ref" in attrs:
        try:
            crs = CRS.from_user_input(str(attrs["spatial_ref"]))
        except CRSError as error:
            raise SensorInputError(f"{path}: spatial_ref is no CRS ({error})") from None
    return Affine.from_gdal(*values), crs


def _small_values(path: Path, variable: xr.DataArray, name: str) -> np.ndarray:
    """The values of a metadata variable (wavelengths, band names), refused unread when it declares
    more than :data:`~brdfcorr.io.sensors.hdf5.METADATA_LIMIT` entries."""
    if variable.size > METADATA_LIMIT:
        raise SensorInputError(f"{path}: {name} declares {variable.size} entries; a metadata item has at most "
                               f"{METADATA_LIMIT}")
    return np.asarray(variable.values)


def glt_digest(glt_x: np.ndarray, glt_y: np.ndarray) -> str:
    """A fingerprint of a GLT (both layers), to tell whether two granules share one."""
    digest = hashlib.sha256(np.ascontiguousarray(glt_x, dtype=np.int64).tobytes())
    digest.update(np.ascontiguousarray(glt_y, dtype=np.int64).tobytes())
    return digest.hexdigest()[:16]


def _open(path: Path, group: str | None = None) -> xr.Dataset:
    require_hdf5(path)
    try:
        return xr.open_dataset(path, engine="h5netcdf", group=group, mask_and_scale=False, decode_times=False,
                               cache=False, phony_dims="sort")
    except (OSError, ValueError) as error:
        where = f" group {group}" if group else ""
        raise SensorInputError(f"{path}: cannot open as NetCDF-4{where} ({error})") from None


def _ortho_block(source, glt_x: np.ndarray, glt_y: np.ndarray, bands, fill: float) -> np.ndarray:
    """One output chunk: read the swath box its GLT cells point to, mask the fill, apply the GLT."""
    valid = (glt_x > 0) & (glt_y > 0)
    if not valid.any():
        return np.full((len(bands), *glt_x.shape), np.nan, dtype=np.float32)
    row0, row1 = int(glt_y[valid].min()) - 1, int(glt_y[valid].max())
    col0, col1 = int(glt_x[valid].min()) - 1, int(glt_x[valid].max())
    box = np.asarray(source[row0:row1, col0:col1, :].values, dtype=np.float32)[:, :, bands]
    box[box == fill] = np.nan
    return apply_glt(box, glt_x, glt_y, row0, col0).astype(np.float32, copy=False)


def _orthorectified(source: xr.Variable, glt_x: np.ndarray, glt_y: np.ndarray, bands, fill: float,
                    chunks: tuple[int, int], name: str) -> da.Array:
    """(bands, ny, nx) dask array on the GLT grid: one task per (y, x) chunk (:func:`_ortho_block`)."""
    ny, nx = glt_x.shape
    token = tokenize(name, glt_x, glt_y, list(bands), fill, chunks)
    rows = [(start, min(start + chunks[0], ny)) for start in range(0, ny, chunks[0])]
    cols = [(start, min(start + chunks[1], nx)) for start in range(0, nx, chunks[1])]
    blocks = [[
        da.from_delayed(
            dask.delayed(_ortho_block, pure=True)(
                source, glt_x[r0:r1, c0:c1], glt_y[r0:r1, c0:c1], list(bands), fill,
                dask_key_name=f"emit-ortho-{token}-{i}-{j}"),
            shape=(len(bands), r1 - r0, c1 - c0), dtype=np.float32, meta=np.empty((0, 0, 0), np.float32))
        for j, (c0, c1) in enumerate(cols)] for i, (r0, r1) in enumerate(rows)]
    return da.block([blocks])


def _swath_layers(path: Path, variable: xr.DataArray, bands: list[int], ortho: bool, chunks: tuple[int, int],
                  attrs: Mapping) -> xr.DataArray:
    """The chosen bands of a (downtrack, crosstrack, bands) variable as (band, y, x) float32 with the
    fill as NaN: on the GLT grid (georeferenced) with ``ortho``, else on the swath (no CRS)."""
    fill = as_number(variable.attrs.get("_FillValue", EMIT_FILL_VALUE), f"{path}: {variable.name} _FillValue")
    if not np.isfinite(fill):  # NaN values are NaN anyway; EMIT's documented fill stays nodata too
        fill = EMIT_FILL_VALUE
    if variable.ndim != 3:
        raise SensorInputError(f"{path}: {variable.name} has dims {variable.dims}; EMIT's are "
                               "(downtrack, crosstrack, bands)")
    if variable.dtype.kind not in "iuf":  # complex: the imaginary part would be lost
        raise SensorInputError(f"{path}: {variable.name} holds {variable.dtype} values; real numbers are expected")
    if not ortho:
        swath = variable.isel({variable.dims[2]: bands}).rename(dict(zip(variable.dims, ("y", "x", "band"))))
        swath = swath.chunk({"y": chunks[0], "x": chunks[1], "band": -1}).transpose("band", "y", "x")
        return swath.astype("float32").where(swath != fill)
    glt_x, glt_y = read_glt(path, (variable.shape[0], variable.shape[1]))
    transform, crs = _grid(path, attrs)
    data = _orthorectified(variable.variable, glt_x, glt_y, bands, fill, chunks, f"{path}:{variable.name}")
    layers = on_grid(xr.DataArray(data, dims=("band", "y", "x")), transform, crs)
    layers.encoding["emit_glt"] = glt_digest(glt_x, glt_y)
    return layers


def _band_parameters(path: Path, n_bands: int) -> tuple[np.ndarray, np.ndarray | None]:
    """``sensor_band_parameters/wavelengths`` and ``fwhm`` [nm] (None where absent), checked
    against the band count."""
    parameters = _open(path, "sensor_band_parameters")
    if "wavelengths" not in parameters:
        raise SensorInputError(f"{path}: no sensor_band_parameters/wavelengths")
    try:
        wavelength = _small_values(path, parameters["wavelengths"], "sensor_band_parameters/wavelengths").astype(float)
        fwhm = (_small_values(path, parameters["fwhm"], "sensor_band_parameters/fwhm").astype(float)
                if "fwhm" in parameters else None)
    except (TypeError, ValueError):
        raise SensorInputError(f"{path}: sensor_band_parameters/wavelengths and fwhm must be numbers [nm]") from None
    if wavelength.size != n_bands or (fwhm is not None and fwhm.size != n_bands):
        raise SensorInputError(f"{path}: {wavelength.size} wavelengths in sensor_band_parameters for {n_bands} bands")
    return wavelength, fwhm


def read_emit_image(path: str | Path, chunks=None, *, ortho: bool = True, scale: float | None = None,
                    offset: float | None = None) -> xr.DataArray:
    """Open an EMIT L2A reflectance granule lazily as (band, y, x) reflectance factors.

    Parameters
    ----------
    path : str or Path
        The ``EMIT_L2A_RFL_001_...nc`` granule.
    chunks : int or dict, optional
        Spatial chunk size [pixels] of the output (a dict with ``"y"``, ``"x"``); default 512.
    ortho : bool, default True
        Map the swath onto the GLT grid (:func:`apply_glt`), georeferenced by ``geotransform`` and
        ``spatial_ref``; False keeps the (downtrack, crosstrack) swath as (y, x), without a CRS.
    scale, offset : float, optional
        Reflectance factor per stored unit and of a stored 0 [1] (EMIT stores reflectance
        factors: 1 and 0 unless given).

    Returns
    -------
    xarray.DataArray
        float32, dask-backed, ``_FillValue`` and cells without a swath pixel as NaN, coords
        ``wavelength`` and ``fwhm`` [nm] along ``band`` (all 285 bands as delivered, the
        ``good_wavelengths = 0`` water-vapour bands included).

    Raises
    ------
    SensorInputError
        A granule not laid out as EMIT's (the message names the missing item).
    """
    path = Path(path)
    root = _open(path)
    if "reflectance" not in root:
        raise SensorInputError(f"{path}: no root variable 'reflectance' (an EMIT L2A RFL granule has one)")
    variable = root["reflectance"]
    n_bands = variable.shape[-1]
    wavelength, fwhm = _band_parameters(path, n_bands)
    image = _swath_layers(path, variable, list(range(n_bands)), ortho, spatial_chunks(chunks), root.attrs)
    glt = image.encoding.get("emit_glt")  # arithmetic below drops the encoding
    if scale is not None:
        image = image * np.float32(scale)
    if offset:
        image = image + np.float32(offset)
    image = image.assign_coords(
        band=np.arange(1, n_bands + 1),
        wavelength=("band", wavelength, {"units": "nm", "long_name": "band-centre wavelength"}),
    )
    if fwhm is not None:
        image = image.assign_coords(fwhm=("band", fwhm, {"units": "nm", "long_name": "full width at half maximum"}))
    image.attrs = {"brdf_input_scale": float(1.0 if scale is None else scale),
                   "brdf_input_offset": float(offset or 0.0), "units": "1"}
    image.encoding.update({"source": str(path), "rasterio_dtype": str(variable.dtype)})
    if glt is not None:
        image.encoding["emit_glt"] = glt
    image.name = "reflectance"
    return image


def _check_same_glt(path: Path, layers: xr.DataArray, like: xr.DataArray | None) -> None:
    """Refuse an obs granule whose GLT is not the reflectance granule's (``like``, read by
    :func:`read_emit_image`): both may share a geotransform, and the grid check would pass, yet
    the cells would show other swath pixels (angles of another row or granule)."""
    ours, theirs = layers.encoding.get("emit_glt"), None if like is None else like.encoding.get("emit_glt")
    if ours is not None and theirs is not None and ours != theirs:
        source = like.encoding.get("source", "the image")  # type: ignore[union-attr]
        raise SensorInputError(f"{path}: its GLT (location/glt_x, glt_y) differs from that of {source}: "
                               "the obs granule is not of the reflectance granule's scene")


def read_emit_obs(path: str | Path, like: xr.DataArray | None = None, *, view_azimuth: str = "to_sensor",
                  band_names: Mapping[str, str] | None = None, ortho: bool = True, chunks=None) -> xr.Dataset:
    """Sun and view angles [deg] from an EMIT L1B OBS granule, on the GLT grid.

    Parameters
    ----------
    path : str or Path
        The ``EMIT_L1B_OBS_001_...nc`` granule of the scene (its GLT is the L2A granule's).
    like : xarray.DataArray, optional
        The image the angles are for: its (y, x) chunks are taken (the grid is checked by
        :func:`brdfcorr.io.grid.check_same_grid` in :func:`brdfcorr.io.scene.open_scene`).
    view_azimuth : {"to_sensor", "from_sensor"}
        What the to-sensor azimuth band holds; EMIT: "to_sensor" (the module notes).
    band_names : mapping, optional
        Band-name prefixes overriding :data:`brdfcorr.io.sensors.envi.OBS_BAND_NAMES`.
    ortho : bool, default True
        On the GLT grid (as :func:`read_emit_image`), or False for the swath.
    chunks : int or dict, optional
        Spatial chunks (default: ``like``'s, else 512).

    Returns
    -------
    xarray.Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` on (y, x), dask-backed, float32, nodata as NaN, azimuths
        in [0, 360) towards the sun and the sensor.
    """
    path = Path(path)
    if view_azimuth not in ("to_sensor", "from_sensor"):
        raise SensorInputError(f"view_azimuth must be 'to_sensor' or 'from_sensor', got {view_azimuth!r}")
    names = wanted_bands(band_names, OBS_BAND_NAMES, "angle(s)")
    root = _open(path)
    parameters = _open(path, "sensor_band_parameters")
    if "obs" not in root or "observation_bands" not in parameters:
        raise SensorInputError(f"{path}: no 'obs' variable and sensor_band_parameters/observation_bands "
                               "(an EMIT L1B OBS granule has both)")
    descriptions = tuple(str(name.decode() if isinstance(name, bytes) else name)
                         for name in _small_values(path, parameters["observation_bands"],
                                                   "sensor_band_parameters/observation_bands").ravel())
    if len(descriptions) != root["obs"].shape[-1]:
        raise SensorInputError(f"{path}: {len(descriptions)} observation_bands for {root['obs'].shape[-1]} obs bands")
    keys = list(names)
    indices = [_obs_band_index(path, descriptions, names[key], key) for key in keys]
    layers = _swath_layers(path, root["obs"], indices, ortho, spatial_chunks(chunks, like), root.attrs)
    _check_same_glt(path, layers, like)
    variables = {}
    for position, key in enumerate(keys):
        angle = layers.isel(band=position, drop=True)
        if key == "vaa" and view_azimuth == "from_sensor":
            angle = angle + np.float32(180.0)
        if key in ("saa", "vaa"):
            angle = wrap_azimuth(angle)
        angle.attrs = {"units": "degree", "long_name": ANGLE_LONG_NAMES[key],
                       "source_band": descriptions[indices[position]]}
        variables[key] = angle.rename(key)
    angles = xr.Dataset(variables)
    angles.attrs = {"source": str(path), "source_kind": "emit", "view_azimuth_stored": view_azimuth,
                    "orthorectified": int(ortho)}
    return angles
