"""Does an image hold reflectance factors? Its stored values unpacked, and a sample of its chunks
judged before a pass over it.

- :func:`reflectance_factors`: the values an array stores as the quantity they stand for
  (xarray's ``scale_factor``/``add_offset`` applied to integer counts, nodata as NaN), with no
  reading: what the Python entry points (``normalize``, the ``.brdf`` accessor, strata) do with
  the arrays a caller gives; :func:`unpacked` the same for other layers (angles);
- :func:`check_reflectance_scale`: raw counts read without their scale, reflectance x 10 000 stored
  as floats, or a scale tag that is a divisor, caught from a few chunks, before a correction, a fit
  or strata spend a pass on numbers that are no reflectance;
- :func:`reflectance_factors` refuses values below the reader's floor as it does
  (:func:`brdfcorr.io.rasters.refuse_fill`: an undeclared nodata value such as -9999).
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from pathlib import Path

import dask
import numpy as np
import rasterio
import xarray as xr

from brdfcorr._entry import option
from brdfcorr.errors import InputError
from brdfcorr.io.opening import reading
from brdfcorr.io.product import MIN_GDAL_CACHE, bounded_gdal_cache
from brdfcorr.io.rasters import refuse_fill
from brdfcorr.io.writer import DEFAULT_CHUNK, local_scheduler, pass_threads

__all__ = ["check_reflectance_scale", "checked_factors", "SAMPLE_SIZE", "reflectance_factors", "unpacked",
           "carries_scale"]

#: Valid values of the image that :func:`check_reflectance_scale` judges by (at most, per chunk read).
SAMPLE_SIZE = 20_000


def check_reflectance_scale(image: xr.DataArray, source: str | None = None, *, limit: float = 2.0,
                            blocks: int = 3, scheduler: str | None = None,
                            num_workers: int | None = None) -> float | None:
    """Raise :class:`InputError` if an image does not hold reflectance factors [1] after scaling:
    raw counts read without their scale, reflectance x 10 000 stored as floats, or a scale tag
    that is a divisor (the MODIS HDF convention: 10 000 where GDAL expects 0.0001).

    A cheap check, not a pass over the image: it reads the central chunk and, where that holds fewer
    than :data:`SAMPLE_SIZE` valid values, at most ``blocks`` x ``blocks`` chunks spread evenly over
    the image (corners, edges and centre), and takes the 99th percentile of their valid values. (Each
    chunk read decompresses its input tiles: nine chunks of a 64-band cube in 512-pixel tiles were
    a sixth of the time of its whole correction.) Reflectance factors are mostly 0-1; counts read
    without their scale (0-10000, 7273-43636 for Landsat Collection 2), reflectance x 10 000 and
    reflectance multiplied by a divisor are far above ``limit``. Integer and float images are
    checked alike; values that are meant as they are (radiance, which corrects as well) are
    accepted with a given scale of 1 (the caller skips the check for a given scale).

    Parameters
    ----------
    image : DataArray
        (band, y, x) as from :func:`brdfcorr.io.rasters.open_image` (attrs ``brdf_input_scale`` and
        ``brdf_input_offset`` name the scaling applied in the message).
    source : str, optional
        Name of the image for the message (default: its file).
    limit : float, default 2.0
        Largest plausible 99th percentile [1].
    blocks : int, default 3
        Chunks sampled along each of y and x.
    scheduler, num_workers : optional
        As for :func:`brdfcorr.io.angles.check_angles`.

    Returns
    -------
    float or None
        The 99th percentile of the sample; None for a sample without a valid value (nothing to
        judge: no error).
    """
    where = source or image.encoding.get("label") or image.encoding.get("source", "image")
    values = _sample_values(image, where, blocks, scheduler, num_workers)
    if not values.size:
        return None
    percentile = float(np.percentile(values, 99))
    _judge(percentile, limit, where, image.attrs)
    return percentile


def checked_factors(values: xr.DataArray, image: xr.DataArray, *, limit: float = 2.0) -> xr.DataArray:
    """``values`` computed from ``image`` (e.g. the mean of its red bands [1]) with the check of
    :func:`check_reflectance_scale` on them: numpy at once, dask lazily, by each chunk as it is
    computed (no pass or read of its own: the result stays lazy). For thresholds in reflectance
    factors (strata's water and shadow tests) that counts or percent would make misfire."""
    where = image.encoding.get("label") or image.encoding.get("source", "image")
    if not isinstance(values.data, dask.array.Array):
        check_reflectance_scale(values.assign_attrs(image.attrs), where, limit=limit)
        return values
    checked = values.data.map_blocks(_checked_block, limit=limit, where=where, attrs=dict(image.attrs),
                                     dtype=values.dtype, meta=values.data._meta)
    return values.copy(data=checked)


def _checked_block(block: np.ndarray, *, limit: float, where: str, attrs) -> np.ndarray:
    """A chunk of :func:`checked_factors`, unchanged, or an :class:`InputError`."""
    sample = _valid_sample(block)
    if sample.size:
        _judge(float(np.percentile(sample, 99)), limit, where, attrs)
    return block


def _judge(percentile: float, limit: float, where: str, attrs) -> None:
    """The error of a 99th ``percentile`` above ``limit``, naming the scaling applied (``attrs``)."""
    if percentile <= limit:
        return
    scale, offset = attrs.get("brdf_input_scale", 1.0), attrs.get("brdf_input_offset", 0.0)
    divisor = max(np.atleast_1d(scale)) > 1
    guess = ("the file's scale tag looks like a divisor (as MODIS HDF files store it), not GDAL's "
             "multiplier." if divisor else "raw counts? Or reflectance x 10000 stored as floats?")
    raise InputError(
        f"{where}: the values do not look like reflectance factors: 99th percentile {percentile:.5g} "
        f"of a sample of valid pixels (scale {scale}, offset {offset} applied); {guess} Give the "
        f"scale (and offset) of the stored values: {option('scale')}, e.g. {option('scale_example')}"
    )


def _sample_values(image: xr.DataArray, where: str, blocks: int, scheduler, num_workers) -> np.ndarray:
    """The valid values :func:`check_reflectance_scale` judges by: those of the central chunk and,
    where it holds fewer than :data:`SAMPLE_SIZE`, of ``blocks`` x ``blocks`` chunks spread evenly
    (an array in memory: every 256th row and column at most)."""
    data = image.data
    if isinstance(data, dask.array.Array):
        rows, columns = (sorted({int(i) for i in np.linspace(0, n - 1, min(blocks, n)).round()})
                         for n in data.numblocks[-2:])
        centre = (rows[len(rows) // 2], columns[len(columns) // 2])
        spread = [(i, j) for i in rows for j in columns if (i, j) != centre]
        with _sample_cache(image):
            parts = _read_samples(data, [centre], where, scheduler, num_workers)
            if sum(part.size for part in parts) < SAMPLE_SIZE:
                parts += _read_samples(data, spread, where, scheduler, num_workers)
    else:
        array = np.asarray(data)
        parts = [_valid_sample(array[..., ::max(1, array.shape[-2] // 256), ::max(1, array.shape[-1] // 256)])]
    return np.concatenate([np.ravel(part) for part in parts])


def _sample_cache(image: xr.DataArray) -> contextlib.AbstractContextManager:
    """GDAL's block cache bounded as for the writing pass (:func:`brdfcorr.io.product.gdal_cache_bytes`) while a few
    chunks of ``image`` are read: GDAL's default (5 % of RAM) keeps every tile read in memory,
    and the file's handles (rioxarray's) stay open for the writing pass. Nothing new where the
    caller bounded the cache already for its whole run (:func:`brdfcorr.io.product.bounded_gdal_cache`)."""
    if rasterio.env.hasenv() and "GDAL_CACHEMAX" in rasterio.env.getenv():
        return contextlib.nullcontext()  # the caller bounded it for its whole run (bounded_gdal_cache)
    source = image.encoding.get("source")
    data = image.data
    chunk = max(data.chunksize[-2:]) if isinstance(data, dask.array.Array) else DEFAULT_CHUNK
    if source is not None and Path(source).is_file():
        return bounded_gdal_cache(source, chunk)
    return rasterio.Env(GDAL_CACHEMAX=MIN_GDAL_CACHE)


def _read_samples(data: dask.array.Array, positions, where: str, scheduler, num_workers) -> list[np.ndarray]:
    """:func:`_valid_sample` of each chunk of ``data`` at the (y, x) chunk ``positions``; a failed
    read is an :class:`InputError` with GDAL's reason (:func:`~brdfcorr.io.opening.reading`)."""
    with reading(f"image {where}"):
        # The writing pass's threads (io.writer): every dask thread keeps its own handle of
        # the file, and with it a decompressed input tile, for the rest of the run.
        # Chunk by chunk (a chunk of bands each): a dask array given to dask.delayed as a whole
        # makes dask import dask.distributed (0.3 s) for its graph.
        chunks = [chunk for i, j in positions for chunk in data.blocks[..., i, j].to_delayed().ravel()]
        samples = (dask.delayed(_valid_sample)(chunk) for chunk in chunks)
        return list(dask.compute(*samples, scheduler=local_scheduler(scheduler),
                                 num_workers=pass_threads(scheduler, num_workers)))


def _valid_sample(block: np.ndarray, size: int = SAMPLE_SIZE) -> np.ndarray:
    """At most about ``size`` finite values of a block, evenly strided."""
    values = block[np.isfinite(block)]
    return values[::max(1, values.size // size)]


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
    :data:`~brdfcorr.io.rasters.FILL_FLOOR` are an :class:`InputError`
    (:func:`~brdfcorr.io.rasters.refuse_fill`). Floats that still carry a
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
    scale = float(metadata["scale_factor"])
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
        nodata = _nodata(layer, layer.attrs)
        if nodata is None or np.isnan(nodata):
            return layer
        return _plain(layer.where(layer != nodata), layer)
    metadata = {**layer.encoding, **layer.attrs}
    if layer.dtype.kind not in "iu" or not {"scale_factor", "add_offset"} & set(metadata):
        return layer
    scale, offset = float(metadata.get("scale_factor", 1.0)), float(metadata.get("add_offset", 0.0))
    nodata = _nodata(layer, metadata)
    values = layer if nodata is None else layer.where(layer != nodata)
    scaled = (values.astype(np.float32) * np.float32(scale) + np.float32(offset)).astype(np.float32)
    return _plain(scaled, layer).assign_attrs(brdf_input_scale=scale, brdf_input_offset=offset)


def _plain(values: xr.DataArray, stored: xr.DataArray) -> xr.DataArray:
    """``values`` named as ``stored``, with its attributes less those of the storage
    (:data:`_STORAGE_ATTRS`; xarray keeps attributes through arithmetic)."""
    values = values.rename(stored.name)
    values.attrs = {key: value for key, value in stored.attrs.items() if key not in _STORAGE_ATTRS}
    return values


def _nodata(array: xr.DataArray, metadata: Mapping) -> float | None:
    """The declared nodata value of stored values: rioxarray's, else ``_FillValue`` of ``metadata``."""
    try:
        import rioxarray  # noqa: F401  (registers the .rio accessor)

        nodata = array.rio.nodata
    except Exception:  # noqa: BLE001 (an array rioxarray cannot describe declares no nodata)
        nodata = None
    return nodata if nodata is not None else metadata.get("_FillValue")
