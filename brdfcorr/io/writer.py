"""Writing GeoTIFFs: tiled, compressed (optionally COG), chunk by chunk, atomically.

:func:`write_rasters` writes DataArrays through rioxarray's writer under a lock per file, to
temporary names renamed when complete, computing any extra lazy results (QA counts) in the same
dask pass; a failed write (disk full, permissions) is one :class:`~brdfcorr.errors.OutputError`.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path

import dask
import rasterio
import rasterio.shutil
import rioxarray  # noqa: F401  (registers the .rio accessor the writer uses)
import xarray as xr
from rasterio._err import CPLE_BaseError  # GDAL errors rasterio passes on as they are

from brdfcorr.errors import BrdfcorrError, InputError, OutputError
from brdfcorr.io.files import atomic_path

__all__ = ["write_rasters", "DEFAULT_CHUNK", "COMPRESSIONS"]

#: Spatial chunk (and output tile) size [pixels].
DEFAULT_CHUNK = 512
#: Lossless GeoTIFF compressions for reflectance (GDAL names, lower case; the CLI's choices).
COMPRESSIONS = ("deflate", "lzw", "zstd", "none")


def _write_options(compress: str, blocksize: int, array: xr.DataArray) -> dict:
    options = {"driver": "GTiff", "tiled": True, "blockxsize": blocksize, "blockysize": blocksize,
               "compress": compress, "BIGTIFF": "IF_SAFER"}
    if compress.lower() in ("deflate", "lzw", "zstd"):
        options["predictor"] = 3 if array.dtype.kind == "f" else 2
    return options


def write_rasters(
    rasters: Mapping[str | os.PathLike, xr.DataArray],
    *,
    compress: str = "deflate",
    blocksize: int = DEFAULT_CHUNK,
    cog: bool = False,
    tags: Mapping[str, str] | None = None,
    compute_with: object = None,
    callbacks: Sequence = (),
    gdal_cache: int | None = None,
    scheduler: str | None = None,
    num_workers: int | None = None,
):
    """Write DataArrays to tiled, compressed GeoTIFFs, chunk by chunk, atomically.

    All rasters (and ``compute_with``, any dask collection such as lazy QA counts) are computed in
    one dask pass, so shared inputs are read once. Each file is written under its own lock to a
    temporary name beside the target and renamed only when complete (with ``cog``, the finished
    GeoTIFF is then copied to a Cloud-Optimized GeoTIFF with overviews, streaming by blocks).
    Nothing appears at a target when anything fails; a failed write (disk full, file size limit,
    permissions) raises :class:`~brdfcorr.errors.OutputError` naming the targets and the reason.

    Parameters
    ----------
    rasters : mapping of path to DataArray
        Targets and their (band, y, x) or (y, x) arrays with georeference (``spatial_ref``);
        the array's ``rio.nodata`` (or ``_FillValue``) is written as nodata, ``long_name``
        tuples as band descriptions and attrs as dataset tags.
    compress : str, default "deflate"
        GDAL compression (``deflate``, ``lzw``, ``zstd``, ``none``).
    blocksize : int, default 512
        Tile size [pixels]; a multiple of 16. Chunks should be multiples of it.
    cog : bool, default False
        Write Cloud-Optimized GeoTIFFs.
    tags : mapping, optional
        Extra dataset tags for every file (provenance).
    compute_with : optional
        Lazy results to compute in the same pass; returned computed.
    callbacks : sequence of dask callbacks
        E.g. a progress bar, active during the computation.
    gdal_cache : int, optional
        GDAL block cache [bytes] while reading and writing (:func:`gdal_cache_bytes`); GDAL's
        default otherwise.
    scheduler, num_workers : optional
        dask scheduler of the pass and its number of workers (as for :func:`dask.compute`;
        default: dask's).

    Returns
    -------
    The computed ``compute_with`` (None if not given).
    """
    if not (blocksize >= 16 and blocksize % 16 == 0):
        raise InputError(f"tile size {blocksize} must be a positive multiple of 16")
    for target in rasters:
        if not Path(target).parent.is_dir():
            raise InputError(f"output directory {Path(target).parent} does not exist")
    compress = "none" if compress is None else str(compress).lower()
    if compress not in COMPRESSIONS:  # GDAL would write uncompressed, silently
        raise InputError(f"unknown compression {compress!r}; choose one of {', '.join(COMPRESSIONS)}")
    gdal_messages = _GdalMessages()
    try:
        with gdal_messages:
            return _write(rasters, compress, blocksize, cog, tags, compute_with, callbacks, gdal_cache,
                          scheduler, num_workers)
    except BrdfcorrError:
        raise
    except (OSError, rasterio.errors.RasterioError, CPLE_BaseError) as error:
        raise _io_failure(error, list(rasters), gdal_messages.messages) from error


class _GdalMessages(logging.Handler):
    """Collects GDAL's error messages (logged by rasterio) while writing, for one clear error
    instead of one log line per failed block on stderr."""

    def __init__(self):
        super().__init__(logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage().strip())

    def __enter__(self):
        logging.getLogger("rasterio").addHandler(self)
        return self

    def __exit__(self, *exc):
        logging.getLogger("rasterio").removeHandler(self)
        return False


def _io_failure(error: Exception, targets: list, messages: list[str]) -> BrdfcorrError:
    """A failed read or write as one message: what failed, and why (the OS or GDAL reason)."""
    reasons = []
    cause = error
    while cause is not None:  # rasterio's "Write failed. See previous exception" names GDAL's cause
        if isinstance(cause, OSError) and cause.strerror:
            reasons.append(f"{cause.strerror}" + (f": {cause.filename}" if cause.filename else ""))
        elif str(cause):
            reasons.append(str(cause))
        cause = cause.__cause__ or cause.__context__
    reasons = [r for r in dict.fromkeys(messages[-1:] + reasons) if "See previous exception" not in r]
    reason = "; ".join(reasons[:2]) or type(error).__name__
    if "Read failed" in str(error) or "IReadBlock" in reason:
        return InputError(f"reading an input failed while writing {', '.join(map(str, targets))}: {reason}")
    folders = ", ".join(dict.fromkeys(str(Path(target).parent) for target in targets))
    return OutputError(
        f"cannot write {', '.join(map(str, targets))}: {reason}; nothing was written (check the free "
        f"space, file size limit and permissions of {folders})"
    )


def _write(rasters, compress, blocksize, cog, tags, compute_with, callbacks, gdal_cache, scheduler, num_workers):
    with contextlib.ExitStack() as stack:
        writes, copies = [], []
        for target, array in rasters.items():
            temporary = stack.enter_context(atomic_path(target))
            if cog:  # GDAL's COG driver only copies: write a tiled GeoTIFF first, beside the target
                gtiff = stack.enter_context(_scratch_path(temporary))
                copies.append((gtiff, temporary))
            else:
                gtiff = temporary
            writes.append(
                array.rio.to_raster(
                    gtiff, tags=dict(tags or {}), lock=threading.Lock(), compute=False,
                    **_write_options(compress, blocksize, array),
                )
            )
        environment = rasterio.Env(GDAL_CACHEMAX=int(gdal_cache)) if gdal_cache else contextlib.nullcontext()
        with environment:
            with contextlib.ExitStack() as active:
                for callback in callbacks:
                    active.enter_context(callback)
                # One pass for everything: shared inputs are read and normalized once.
                *_, extra = dask.compute(*writes, compute_with, scheduler=scheduler, num_workers=num_workers)
            for gtiff, temporary in copies:
                rasterio.shutil.copy(
                    gtiff, temporary, driver="COG", compress=compress.upper(), blocksize=blocksize,
                    overview_resampling="average", BIGTIFF="IF_SAFER",
                )
    return extra


@contextlib.contextmanager
def _scratch_path(beside: Path):
    """A temporary file name beside ``beside``, removed on exit whatever happens."""
    path = Path(f"{beside}.gtiff")
    try:
        yield path
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
