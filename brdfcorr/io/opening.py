"""Opening rasters with one error for every reader: a missing or unreadable file, or one GDAL
reads only as subdatasets, is an :class:`~brdfcorr.errors.InputError` naming the file and its role
("image", "class map", "DEM")."""

from __future__ import annotations

import contextlib
import logging
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path

import rasterio
import rioxarray
import xarray as xr
from rasterio._err import CPLE_BaseError  # GDAL errors rasterio passes on as they are

from brdfcorr.errors import BrdfcorrError, InputError
from brdfcorr.io.commit import remote_failure, short_envi
from brdfcorr.io.gdal_log import GdalLog
from brdfcorr.io.sensors.hdf5 import hdf5_open_failure
from brdfcorr.io.sensors.products import hdf5_hint
from brdfcorr.io.writer import DEFAULT_CHUNK

__all__ = ["open_raster", "open_layer", "opened", "reading", "read_failure", "chunk_spec", "refuse_short_envi",
           "has_envi_header"]


def open_raster(path, role: str, chunks, masked: bool, mask_and_scale: bool = False) -> xr.DataArray:
    """A raster (band, y, x) as rioxarray opens it, lazily, read without a lock; ``source`` in its encoding."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{role} file {path} does not exist")
    _refuse_broken_hdf5(path, role)
    refuse_short_envi(path, role)
    # GDAL's warnings while opening, through rasterio's logger (under an Env, never printed by GDAL
    # itself): a header tag it could not read means a file cut short, not a raster without a CRS.
    messages = GdalLog(logging.WARNING, thread=threading.get_ident())
    try:
        with warnings.catch_warnings(), rasterio.Env(), messages:
            # Per-band scales/offsets: rioxarray applies each band's, and says so in a warning.
            warnings.filterwarnings("ignore", r"(Scales|Offsets) differ across bands", UserWarning)
            # lock=False: every dask thread reads through its own handle, so reads run in parallel.
            # An absolute path: the graph's reads may run on dask.distributed workers started elsewhere.
            array = rioxarray.open_rasterio(path.absolute(), chunks=chunks, masked=masked,
                                            mask_and_scale=mask_and_scale, lock=False)
    except rasterio.errors.RasterioError as error:
        raise InputError(f"cannot read {role} file {path}: {error}{hdf5_hint(path)}") from None
    damaged = [message for message in messages.messages if "IO error" in message]
    if damaged:
        raise InputError(f"cannot read {role} file {path}: {damaged[0]} (a truncated or damaged file?)")
    if isinstance(array, (list, xr.Dataset)):  # subdatasets (of other shapes, or one): not a plain raster
        raise InputError(container_message(role, path))
    stored = str(array.encoding.get("rasterio_dtype", array.dtype))
    if array.dtype.kind == "c" or stored.startswith("complex"):
        raise InputError(f"{role} file {path} holds complex values ({stored}); brdfcorr reads real numbers "
                         "(the imaginary part would be lost)")
    array.encoding["source"] = str(path)
    return array


def container_message(role: str, path) -> str:
    """The refusal of a file GDAL opens as a container of subdatasets (NetCDF, HDF) without a band
    of its own, saying what it may be instead (an EMIT granule other than the L2A reflectance) or
    what to install to read it (:func:`~brdfcorr.io.sensors.products.hdf5_hint`)."""
    name = Path(path).name
    if name.startswith("EMIT_") and not name.startswith("EMIT_L2A_RFL_"):
        hint = (" (an EMIT granule other than the L2A reflectance: the image is EMIT_L2A_RFL_...nc, the L1B OBS "
                "granule its --angles with --angles-kind emit)")
    else:
        hint = hdf5_hint(path)
    return f"{role} file {path} holds several subdatasets and no raster band; give one raster{hint}"


def _refuse_broken_hdf5(path, role: str) -> None:
    """An HDF5 file that HDF5 cannot open is refused before GDAL tries it: GDAL's own HDF5 library
    prints its error stack (tens of ``HDF5-DIAG`` lines) on stderr before GDAL's error."""
    failure = hdf5_open_failure(path)
    if failure is not None:
        raise InputError(f"cannot read {role} file {path}: an HDF5 file that HDF5 cannot open ({failure}; "
                         "a truncated or damaged file?)")


def has_envi_header(path) -> bool:
    """Whether a header GDAL's ENVI driver would read lies beside ``path`` (``x.hdr`` or
    ``x.img.hdr``): a file without one is no ENVI image, and need not be opened to tell."""
    path = Path(path)
    return any(Path(f"{stem}{suffix}").is_file() for stem in (path.with_suffix(""), path)
               for suffix in (".hdr", ".HDR"))


def refuse_short_envi(path, role: str) -> None:
    """Refuse an ENVI file cut short (:func:`brdfcorr.io.commit.short_envi`): GDAL would read the
    missing rows as zeros, reflectance 0 or a sun at the zenith, without an error."""
    if not has_envi_header(path):  # a GeoTIFF, ...: no second open
        return
    try:
        with warnings.catch_warnings(), rasterio.Env():
            warnings.simplefilter("ignore")  # NotGeoreferencedWarning: open_raster says what matters
            with rasterio.open(path) as dataset:
                short = short_envi(dataset)
    except (rasterio.errors.RasterioError, CPLE_BaseError, OSError, ValueError):
        return  # the reader says why it cannot open it
    if short is not None:
        raise InputError(f"cannot read {role} file {path}: {short} (a truncated or damaged file?)")


def open_layer(path, role: str, chunks=None) -> xr.DataArray:
    """Any raster (band, y, x), lazily, nodata as NaN and the values scaled by the file's own scale
    and offset (a DEM stored as decimetres with a scale of 0.1 reads as metres); ``role`` names it
    in errors ("DEM")."""
    return open_raster(path, role, chunk_spec(chunks), masked=True, mask_and_scale=True)


@contextlib.contextmanager
def opened(path, role: str):
    """The rasterio dataset of ``path``; an unreadable file is an InputError naming ``role``."""
    _refuse_broken_hdf5(path, role)
    try:
        with rasterio.open(path) as dataset:
            yield dataset
    except rasterio.errors.RasterioError as error:
        raise InputError(f"cannot read {role} file {path}: {error}") from None


@contextlib.contextmanager
def reading(what: str):
    """A pass over lazily opened layers: a read that fails (a truncated or damaged file: GDAL opens
    it, and a block read fails later) is an InputError ``cannot read {what}: {GDAL's reason}``."""
    messages = GdalLog()  # GDAL's log lines of a failed read: into the one error
    try:
        with messages:
            yield
    except BrdfcorrError:
        raise
    except (OSError, rasterio.errors.RasterioError, CPLE_BaseError) as error:
        raise InputError(f"cannot read {what}: {read_failure(error, messages.messages)}") from None
    except Exception as error:  # noqa: BLE001 (one kind is ours: a worker's failure, handed back plain)
        remote = remote_failure(error)
        if remote is None:
            raise
        raise InputError(f"cannot read {what}: {remote}") from None


def read_failure(error: BaseException, messages: Sequence[str] = ()) -> str:
    """GDAL's reason of a failed read, from its log lines and the exception's causes (rasterio's own
    "Read failed. See previous exception" names none): the first (file and band) and the last (the
    root cause, e.g. a tile that ends early) of them."""
    reasons = list(messages)
    cause: BaseException | None = error
    while cause is not None:
        reasons.append(str(cause).strip())
        cause = cause.__cause__ or cause.__context__
    reasons = [reason for reason in dict.fromkeys(reasons) if reason and "See previous exception" not in reason]
    if not reasons:
        return type(error).__name__
    return "; ".join(dict.fromkeys([reasons[0], reasons[-1]])) + " (a truncated or damaged file?)"


def chunk_spec(chunks):
    """Dask chunks of a (band, y, x) raster: an int is the spatial chunk size, all bands in one chunk."""
    if chunks is None:
        chunks = DEFAULT_CHUNK
    if isinstance(chunks, int):
        return {"band": -1, "y": chunks, "x": chunks}
    return chunks


