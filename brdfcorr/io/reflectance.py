"""Stored values as reflectance factors [1], and the floor below which no reflectance factor lies.

- :func:`as_reflectance`: an image as a raster reader gives it (rioxarray's scaling, or a given
  scale and offset in its place) as float reflectance factors, the scaling applied in its attrs;
- :func:`reflectance_factors` and :func:`unpacked`: the values an array in memory or a lazy array
  stores as the quantity they stand for (xarray's ``scale_factor``/``add_offset``, nodata as NaN),
  with no reading: what the Python entry points (``normalize``, the ``.brdf`` accessor, strata, the
  fits) do with the arrays a caller gives;
- :func:`refuse_fill`: values below :data:`FILL_FLOOR` (an undeclared nodata value such as -9999)
  refused as the chunks are computed.

Whether the factors are plausible (raw counts read without their scale) is judged from a sample
by :func:`brdfcorr.io.scale_check.check_reflectance_scale`.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Mapping

import dask.array
import numpy as np
import xarray as xr

from brdfcorr._entry import option
from brdfcorr._validation import short_repr
from brdfcorr.errors import InputError

__all__ = ["FILL_FLOOR", "refuse_fill", "as_reflectance", "reflectance_factors", "unpacked", "carries_scale",
           "declared_nodata"]


#: Lowest reflectance factor [1] taken as a measurement (:func:`refuse_fill`). No surface reflects
#: less than nothing; atmospheric-correction noise over dark water and shade, and Sentinel-2's
#: -0.1 offset (baseline 04.00), stay well above. Below lie fill values nobody declared: -9999
#: as a float, or as counts x 0.0001 (-0.9999), -32768, -1e20.
FILL_FLOOR = -0.5


def refuse_fill(image: xr.DataArray, where: str | None = None, bad_bands=None) -> xr.DataArray:
    """``image`` (reflectance factors [1], band first) with an :class:`InputError` for values below
    :data:`FILL_FLOOR`: an undeclared nodata value, which a correction would multiply into another
    number (-9999 into -11 235) and a fit or an assessment would take as a dark pixel. Bands
    marked bad (``bad_bands``, one bool per band: an ENVI header's ``bbl``, whose values are
    passed through as they are) are not judged.

    A numpy array is checked at once; a dask array lazily, each chunk as it is computed (no pass
    or read of its own: it costs a minimum per chunk of the pass that reads it anyway). ``where``
    names the image in the message (default: its file).
    """
    where = where or image.encoding.get("label") or image.encoding.get("source", "image")
    judged = np.ones(image.shape[0], bool) if bad_bands is None else ~np.asarray(bad_bands, bool)
    if not isinstance(image.data, dask.array.Array):
        _refuse_below_floor(np.asarray(image.data), where=where, attrs=image.attrs, judged=judged)
        return image
    checked = image.data.map_blocks(_refuse_below_floor, where=where, attrs=dict(image.attrs), judged=judged,
                                    dtype=image.dtype, meta=image.data._meta)
    return image.copy(data=checked)


def _refuse_below_floor(block: np.ndarray, *, where: str, attrs, judged: np.ndarray, block_info=None) -> np.ndarray:
    """A chunk of :func:`refuse_fill`, unchanged, or its :class:`InputError` (``judged``: which
    bands of the image are judged; ``block_info``: where the chunk lies, from dask)."""
    if block.dtype.kind != "f" or not block.size:
        return block
    first, last = (0, block.shape[0]) if block_info is None else block_info[0]["array-location"][0]
    values = block[judged[first:last]]
    with np.errstate(invalid="ignore"):
        low = np.isfinite(values) & (values < FILL_FLOOR)  # +-inf is nodata (docs/conventions.md)
    if not low.any():
        return block
    found, counts = np.unique(values[low], return_counts=True)
    common = float(found[np.argmax(counts)])
    scale, offset = attrs.get("brdf_input_scale", 1.0), attrs.get("brdf_input_offset", 0.0)
    stored = f"{(common - offset) / scale:.6g}" if isinstance(scale, float) and isinstance(offset, float) else "VALUE"
    raise InputError(
        f"{where}: {int(low.sum())} values of a chunk lie below {FILL_FLOOR}, which no reflectance factor "
        f"does (most often {common:.6g}, scale {scale} and offset {offset} applied): a nodata value the "
        f"file does not declare? Declare it, e.g. in a VRT beside the image (gdal_translate -of VRT "
        f"-a_nodata {stored} IMAGE IMAGE.vrt) or as an ENVI header's 'data ignore value', and read that"
    )


def as_reflectance(image: xr.DataArray, scale: float | None, offset: float | None, as_stored: bool) -> xr.DataArray:
    """The image as read by :func:`brdfcorr.io.rasters.open_image` turned into reflectance factors [1]: rioxarray's
    scaling (or, with ``scale``/``offset`` given, those replacing the file's), float32 (float64 for
    a float64 file), the scaling applied in attrs ``brdf_input_scale`` and ``brdf_input_offset``."""
    given = scale is not None or offset is not None
    if as_stored and "_FillValue" in image.attrs:  # where a masked read keeps it
        image.encoding["_FillValue"] = image.attrs.pop("_FillValue")
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
    return image


def _one_or_per_band(values: np.ndarray) -> float | tuple[float, ...]:
    return float(values[0]) if np.all(values == values[0]) else tuple(float(v) for v in values)


#: Attributes that describe stored values, not the quantity: dropped once the values are read.
_STORAGE_ATTRS = ("scale_factor", "add_offset", "_FillValue", "missing_value")


def carries_scale(array: xr.DataArray) -> bool:
    """Whether ``array`` carries a ``scale_factor`` (attrs or encoding) for its stored values."""
    return "scale_factor" in {**array.encoding, **array.attrs}


def reflectance_factors(reflectance: xr.DataArray, *, unscaled_counts: bool = False) -> xr.DataArray:
    """Reflectance factors of the stored values, with no packing or nodata attribute left.

    Integer counts are scaled with the scale and offset they carry (attrs or encoding
    ``scale_factor``/``add_offset``; their ``_FillValue`` or rioxarray nodata as NaN) by
    :func:`unpacked`. Integer counts without a scale are an :class:`InputError`, or, with
    ``unscaled_counts``, taken as they are (values in their own units: the topographic
    correction's, a fit's ``reflectance_scale``). Without ``unscaled_counts`` a ``scale_factor``
    above 1 is an :class:`InputError` too: a divisor (the MODIS HDF convention, reflectance =
    counts / 10000) where xarray and GDAL multiply. Floats are taken as they are, their declared
    nodata (rioxarray's, or a ``_FillValue`` attribute) as NaN; reflectance factors below
    :data:`FILL_FLOOR` are an :class:`InputError`
    (:func:`refuse_fill`). Floats that still carry a
    ``scale_factor`` or ``add_offset`` attribute are packed values (as
    ``rioxarray.open_rasterio(path, masked=True)`` reads them) and an :class:`InputError`: neither
    reading is safe to guess.
    """
    if unscaled_counts and reflectance.dtype.kind in "iu" and not carries_scale(reflectance):
        return unpacked(reflectance, "reflectance")  # counts in their own units: no floor
    if reflectance.dtype.kind == "f":
        return refuse_fill(unpacked(reflectance, "reflectance"), "reflectance")
    if reflectance.dtype.kind not in "iu":
        return reflectance
    metadata = {**reflectance.encoding, **reflectance.attrs}
    if "scale_factor" not in metadata:
        raise InputError(
            f"reflectance holds integer counts ({reflectance.dtype}) without a scale_factor: give reflectance "
            f"factors, {option('scale')} (e.g. Sentinel-2 L2A from baseline 04.00: counts * 0.0001 - 0.1)"
        )
    scale = _one_number(metadata, "scale_factor", "reflectance")
    if scale > 1 and not unscaled_counts:  # every count >= 1 would be a reflectance factor above 1
        raise InputError(
            f"reflectance holds integer counts ({reflectance.dtype}) with scale_factor {scale:g}: a divisor "
            f"(as MODIS HDF files store it: reflectance = counts / {scale:g}), where xarray and GDAL multiply "
            f"(counts * scale_factor + add_offset); set scale_factor to {1 / scale:.6g}"
        )
    return refuse_fill(unpacked(reflectance, "reflectance"), "reflectance")


def unpacked(layer: xr.DataArray, role: str) -> xr.DataArray:
    """The values ``layer`` stores as the quantity they stand for, as xarray decodes them: integers
    that carry a ``scale_factor`` or ``add_offset`` (attrs or encoding) scaled to float32, their
    nodata (rioxarray's or ``_FillValue``) as NaN; floats' declared nodata as NaN; other layers as
    they are. A float layer that still carries ``scale_factor``/``add_offset`` among its attributes
    holds packed values: an :class:`InputError` naming ``role`` (``"reflectance"``, ``"sza"``)."""
    if layer.dtype.kind == "f":
        packed = {key: layer.attrs[key] for key in ("scale_factor", "add_offset") if key in layer.attrs}
        if packed:
            described = ", ".join(f"{key}={value}" for key, value in packed.items())
            raise InputError(
                f"{role} holds floats that still carry {described} among their attributes: packed values "
                "(as rioxarray.open_rasterio(path, masked=True) reads them). Read them with mask_and_scale=True, "
                "or drop the attributes if they are applied already"
            )
        nodata = declared_nodata(layer)
        if nodata is None or np.isnan(nodata):
            return layer
        return _plain(_masked(layer, nodata), layer)
    metadata = {**layer.encoding, **layer.attrs}
    if layer.dtype.kind not in "iu" or not {"scale_factor", "add_offset"} & set(metadata):
        return layer
    scale, offset = _one_number(metadata, "scale_factor", role, 1.0), _one_number(metadata, "add_offset", role, 0.0)
    nodata = declared_nodata(layer, metadata)
    values = layer if nodata is None else layer.where(layer != nodata)
    scaled = (values.astype(np.float32) * np.float32(scale) + np.float32(offset)).astype(np.float32)
    return _plain(scaled, layer).assign_attrs(brdf_input_scale=scale, brdf_input_offset=offset)


def _one_number(metadata: Mapping, key: str, role: str, default: float = 0.0) -> float:
    """``metadata[key]`` (a ``scale_factor`` or ``add_offset``) as one number, as xarray decodes it
    (one per variable); a list of them (one per band) or text is an :class:`InputError`."""
    value = metadata.get(key, default)
    try:
        return float(np.asarray(value, dtype=float).item())
    except (TypeError, ValueError):
        raise InputError(f"{role} carries {key}={short_repr(value)}: one number is expected (xarray's {key} is one "
                         f"per variable); for one per band, scale the bands first, e.g. counts * "
                         f"xr.DataArray(scales, dims='band') + xr.DataArray(offsets, dims='band')") from None


def _masked(layer: xr.DataArray, nodata: float) -> xr.DataArray:
    """A float ``layer`` with its values equal to ``nodata`` as NaN, chunk by chunk (a chunk
    without one as it is, not copied: a masked read holds none)."""
    data = layer.data
    if isinstance(data, dask.array.Array):
        return layer.copy(data=data.map_blocks(_nan_at, nodata, dtype=data.dtype, meta=data._meta))
    return layer.copy(data=_nan_at(np.asarray(data), nodata))


def _nan_at(block: np.ndarray, value: float) -> np.ndarray:
    hit = block == value
    return np.where(hit, np.nan, block).astype(block.dtype, copy=False) if hit.any() else block


def _plain(values: xr.DataArray, stored: xr.DataArray) -> xr.DataArray:
    """``values`` named as ``stored``, with its attributes less those of the storage
    (:data:`_STORAGE_ATTRS`; xarray keeps attributes through arithmetic) and, where arithmetic
    dropped its encoding, the file it came from (encoding ``source`` and ``label``: messages name it)."""
    values = values.rename(stored.name)
    values.attrs = {key: value for key, value in stored.attrs.items() if key not in _STORAGE_ATTRS}
    if not values.encoding:
        values.encoding = {key: stored.encoding[key] for key in ("source", "label") if key in stored.encoding}
    return values


def declared_nodata(layer: xr.DataArray, metadata: Mapping | None = None):
    """The nodata value a layer declares (a class map, an angle layer, stored reflectance), or None:
    rioxarray's; else its encoded one (``rio.write_nodata(value, encoded=True)``, a masked read's
    ``_FillValue`` kept in the encoding: a value still equal to it is nodata too, where rioxarray's
    own is NaN, or an error for integers); else the ``_FillValue`` of ``metadata`` (default: the
    layer's attributes)."""
    import rioxarray  # noqa: F401  (registers the .rio accessor)

    nodata = encoded = None
    with contextlib.suppress(Exception):  # a layer rioxarray cannot describe declares none of its own
        nodata = layer.rio.nodata
    if nodata is None or (isinstance(nodata, (float, np.floating)) and math.isnan(nodata)):
        with contextlib.suppress(Exception):
            encoded = layer.rio.encoded_nodata
    for found in (encoded, nodata, (layer.attrs if metadata is None else metadata).get("_FillValue")):
        if found is not None:
            return found
    return None
