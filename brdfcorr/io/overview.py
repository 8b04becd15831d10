"""Small reads of large rasters for figures: bands decimated by GDAL's resampling."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from rasterio.enums import Resampling

from brdfcorr.errors import InputError
from brdfcorr.io.opening import opened

__all__ = ["read_small", "raster_summary"]


def read_small(path: str | os.PathLike, bands: Sequence[int], max_size: int, average: bool = True,
               scaled: bool = False) -> np.ndarray:
    """Bands of a raster decimated to at most ``max_size`` pixels on its longer side.

    Parameters
    ----------
    path : path-like
    bands : sequence of int
        1-based band numbers.
    max_size : int
        Longest side of the result [pixels].
    average : bool, default True
        GDAL resampling: average (reflectance) or nearest (class maps).
    scaled : bool, default False
        The values times the file's own scale plus its offset (GDAL's per-band metadata), else the
        stored values.

    Returns
    -------
    ndarray of float64, (band, y, x)
        Nodata as NaN.
    """
    with opened(path, "image") as dataset:
        missing = [band for band in bands if not 1 <= band <= dataset.count]
        if missing:
            raise InputError(f"{path}: band {missing[0]} does not exist ({dataset.count} bands)")
        scale = max(1.0, max(dataset.height, dataset.width) / max_size)
        shape = (len(bands), max(1, round(dataset.height / scale)), max(1, round(dataset.width / scale)))
        data = dataset.read(list(bands), out_shape=shape, masked=True,
                            resampling=Resampling.average if average else Resampling.nearest)
        scales, offsets = (np.array([values[band - 1] for band in bands], dtype=np.float64)[:, None, None]
                           for values in (dataset.scales, dataset.offsets))
    values = np.ma.filled(data.astype(np.float64), np.nan)
    return values * scales + offsets if scaled else values


def raster_summary(path: str | os.PathLike) -> tuple[int, tuple[float, ...], dict[str, str]]:
    """A raster's band count, affine transform ``(a, b, c, d, e, f)`` (as :class:`affine.Affine`
    orders it) and dataset-level tags."""
    with opened(path, "image") as dataset:
        return dataset.count, tuple(dataset.transform)[:6], dataset.tags()
