"""Committing the outputs of a writing pass (:func:`brdfcorr.io.writer.write_rasters`): each output
once, after it was verified.

GDAL reports a tile it could not write, or a TIFF directory it could not rewrite at close, as a
logged error and rasterio raises nothing for it (a full disk gave files that read as NaN, with
exit 0). :class:`brdfcorr.io.gdal_log.GdalLog` collects those errors while outputs are written; :func:`verify`
reopens each temporary file and checks what a full disk or a file size limit breaks;
:meth:`Target.commit` renames the temporaries into place, the data file last. :func:`write_cause`
(:mod:`brdfcorr.io.files`) names the cause: the file size limit, a full device, GDAL's message.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rasterio
import rasterio.enums
from rasterio._err import CPLE_BaseError  # GDAL errors rasterio passes on as they are

from brdfcorr.errors import BrdfcorrError, InputError, OutputError
from brdfcorr.io.files import write_cause
from brdfcorr.io.gdal_log import OUT_OF_MEMORY
from brdfcorr.io.paths import stale_sidecars

if TYPE_CHECKING:
    import xarray as xr

__all__ = ["Target", "check_complete", "verify", "io_failure", "remote_failure", "write_error", "written_files"]


def io_failure(error: Exception, targets: list, messages: list[str], written: list[Path]) -> BrdfcorrError:
    """A failed read or write as one message: what failed, and why (the OS or GDAL reason; the file
    size limit or a full disk where ``written``, the temporary files, show it: :func:`write_cause`)."""
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
    return write_error(targets, write_cause(error if isinstance(error, OSError) else None, written, reason))


#: What dask.distributed hands back for an exception it cannot send from a worker (rasterio's
#: chained GDAL errors): a plain ``Exception`` whose one argument is the original's repr.
_REMOTE_ERROR = re.compile(r"^(Rasterio\w*Error|CPLE_\w+|OSError|FileNotFoundError|PermissionError)\((['\"])(.*)\2\)$",
                           re.S)


def remote_failure(error: BaseException) -> str | None:
    """The reason of an input or output error raised on a dask.distributed worker and handed back
    as a plain ``Exception`` (:data:`_REMOTE_ERROR`), with a hint; None for any other error."""
    if type(error) is not Exception or len(error.args) != 1:
        return None
    match = _REMOTE_ERROR.match(str(error.args[0]))
    if match is None:
        return None
    reason = match.group(3).replace("Read failed. See previous exception for details.", "a read failed")
    return (f"{reason} (on a dask.distributed worker: a truncated or damaged file, or a path the workers "
            "cannot reach)")


def write_error(targets: list, cause: str) -> OutputError:
    """One :class:`OutputError` for failed outputs: the targets, the cause and what to check."""
    folders = ", ".join(dict.fromkeys(str(Path(target).parent) for target in targets))
    if cause.startswith(OUT_OF_MEMORY):  # a tile too large for memory (--chunk), not the disk
        hint = "nothing was written (a smaller tile size, --chunk, needs less memory)"
    else:
        hint = f"nothing was written (check the free space, file size limit and permissions of {folders})"
    return OutputError(f"cannot write {', '.join(map(str, targets))}: {cause}; {hint}")


@dataclass
class Target:
    """One output of a writing pass: its final path, the temporary file GDAL writes (``written``:
    the data file, or the GeoTIFF a COG is copied from), the temporary renamed onto ``final``, and
    the temporary sidecars (ENVI header, ``.aux.xml``) with their final names."""

    final: Path
    array: xr.DataArray
    layout: object | None
    temporary: Path
    written: Path
    sidecars: list[tuple[Path, Path]]

    def files(self) -> list[Path]:
        """Every temporary file of this output."""
        return list(dict.fromkeys([self.temporary, self.written, *(written for written, _ in self.sidecars)]))

    def kept(self) -> list[Path]:
        """The temporary files renamed into place (not a COG's intermediate GeoTIFF)."""
        return [self.temporary, *(written for written, _ in self.sidecars)]

    def discard(self) -> None:
        for path in self.files():
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)

    def commit(self) -> None:
        """Rename the temporaries into place, the data file last: an ENVI output's old data file is
        removed first, so a process killed in between leaves no data file beside new sidecars (a
        resumed chain redoes it); a stale ``.aux.xml``, overview, mask or second ENVI header of an
        earlier output (:func:`~brdfcorr.io.paths.stale_sidecars`) is removed."""
        if self.layout is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.final)
        for written, final in self.sidecars:
            if written.exists():
                os.replace(written, final)
            else:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(final)
        stale = stale_sidecars(self.final, envi=self.layout is not None)  # GDAL would read them with it
        for path in stale + ([Path(f"{self.final}.aux.xml")] if self.layout is None else []):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)
        os.replace(self.temporary, self.final)
        if self.written != self.temporary:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.written)



def written_files(targets: list[Target]) -> list[Path]:
    return [path for target in targets for path in target.files()]



def verify(target: Target, tags: Mapping[str, str], written: list[Path]) -> None:
    """Reopen a written temporary output and check what a full disk or a file size limit breaks:
    the file opens, has the array's size and bands and the tags written, every tile of a GeoTIFF
    lies within the file, an ENVI data file has its full length. Raises :class:`OutputError`."""
    path, array = target.temporary, target.array
    try:
        with rasterio.open(path) as dataset:
            problem = _mismatch(dataset, array, tags)
            if problem is None and dataset.driver in ("GTiff", "COG"):
                problem = _missing_tile(dataset, os.path.getsize(path))
    except (rasterio.errors.RasterioError, CPLE_BaseError) as error:
        problem = f"the file written does not read back ({error})"
    if problem is not None:
        cause = write_cause(None, written, "")
        raise write_error([target.final], f"{cause} ({problem})" if cause != "unknown reason" else problem)


def check_complete(path: str | os.PathLike) -> str | None:
    """What is wrong with an existing output raster, or None where it is whole: the checks of
    :func:`verify` that need no array (it opens; every GeoTIFF tile lies within the file; an ENVI
    data file has its full length). A resumed run (:mod:`brdfcorr.chain.resume`) reopens what it
    would skip: a file cut short or damaged after it was written is redone, not reported complete.
    Reads the header and the tile index only."""
    try:
        with rasterio.open(path) as dataset:
            problem = short_envi(dataset)
            if problem is None and dataset.driver in ("GTiff", "COG"):
                problem = _missing_tile(dataset, os.path.getsize(path))
    except (rasterio.errors.RasterioError, CPLE_BaseError, OSError) as error:
        problem = f"it does not read ({error})"
    return problem


def short_envi(dataset) -> str | None:
    """An ENVI data file shorter than its header offset, bands, rows and columns need (GDAL reads
    the missing part as zeros, and refuses only a file under about half its size)."""
    if dataset.driver != "ENVI":
        return None
    offset = int(float(dataset.tags(ns="ENVI").get("header_offset", 0) or 0))
    expected = offset + dataset.count * dataset.height * dataset.width * np.dtype(dataset.dtypes[0]).itemsize
    size = os.path.getsize(dataset.name)
    return f"its data file holds {size} of {expected} bytes" if size < expected else None


def _mismatch(dataset, array: xr.DataArray, tags: Mapping[str, str]) -> str | None:
    bands = array.shape[0] if array.ndim == 3 else 1
    if (dataset.count, dataset.height, dataset.width) != (bands, *array.shape[-2:]):
        return f"it reads back as {dataset.count} x {dataset.height} x {dataset.width}, not {array.shape}"
    short = short_envi(dataset)
    if short is not None:
        return short
    found = dataset.tags()
    lost = [key for key, value in tags.items() if found.get(key) != str(value)]
    return f"its tags {', '.join(lost[:3])} did not read back" if lost else None


def _missing_tile(dataset, size: int) -> str | None:
    """A GeoTIFF tile that was never written (offset or byte count 0) or lies beyond the file's end."""
    bands = [1] if dataset.interleaving == rasterio.enums.Interleaving.pixel else list(dataset.indexes)
    for band in bands:
        for (row, column), _ in dataset.block_windows(band):
            offset = dataset.get_tag_item(f"BLOCK_OFFSET_{column}_{row}", "TIFF", bidx=band)
            count = dataset.get_tag_item(f"BLOCK_SIZE_{column}_{row}", "TIFF", bidx=band)
            if not offset or not count or int(offset) == 0 or int(count) == 0:
                return f"tile ({row}, {column}) of band {band} was not written"
            if int(offset) + int(count) > size:
                return f"tile ({row}, {column}) of band {band} ends beyond the file's {size} bytes"
    return None
