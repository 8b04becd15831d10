"""Does an image hold reflectance factors? A sample of its chunks judged before a pass over it.

- :func:`check_reflectance_scale`: raw counts read without their scale, reflectance x 10 000 stored
  as floats, or a scale tag that is a divisor, caught from a few chunks, before a correction, a fit
  or strata spend a pass on numbers that are no reflectance;
- :func:`checked_factors`: the same check on values computed from an image, chunk by chunk.

The stored values themselves are turned into reflectance factors by :mod:`brdfcorr.io.reflectance`.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import dask
import numpy as np
import rasterio
import xarray as xr

from brdfcorr._entry import option
from brdfcorr.errors import InputError
from brdfcorr.io.opening import reading
from brdfcorr.io.product import MIN_GDAL_CACHE, bounded_gdal_cache
from brdfcorr.io.writer import DEFAULT_CHUNK, local_scheduler, pass_threads

__all__ = ["check_reflectance_scale", "checked_factors", "SAMPLE_SIZE"]

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
