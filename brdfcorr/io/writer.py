"""Writing GeoTIFFs (tiled, compressed, optionally COG) or ENVI files, chunk by chunk, atomically.

:func:`write_rasters` writes DataArrays to temporary names renamed when complete, computing any
extra lazy results (QA counts) in the same dask pass; a failed write (disk full, file size limit,
permissions), also one GDAL reports only in its log or at close, is one
:class:`~brdfcorr.errors.OutputError`, and every output is verified before it is renamed
(:mod:`brdfcorr.io.commit`). :func:`writing` is the same pass for a caller that computes it
itself (a correction computes its own chunks; the writer only stores them). rioxarray creates each
file (georeference, nodata, band descriptions, tags); the chunks then go

- on one machine (dask's threaded or synchronous scheduler) through *one* open GDAL handle per
  file, under a lock: each written tile is handed to GDAL's pool of compression threads
  (``NUM_THREADS=ALL_CPUS``) and the writing dask thread returns at once, so compression runs on
  all cores while dask computes the next chunks (GDAL bounds its queue of tiles waiting for a
  compressor, and dask's workers bound the chunks waiting for the lock);
- on a dask.distributed cluster through rioxarray's own writer, from the worker that computed the
  chunk, under a :class:`distributed.Lock` per file (each write reopens the file, so the lock and
  the writes travel between processes).
An ENVI target (:class:`EnviOutput`) is written by GDAL's ENVI driver: the data file, its header
(``.hdr``: map info, coordinate system, band names, data ignore value, wavelengths) and its
``.aux.xml`` (the tags) all under temporary names, renamed when complete, the data file last.
What a header cannot hold is refused (:func:`check_envi_georeference`: a sheared geotransform, no
CRS); its ``description`` names the output, and band names cannot add header fields (the header's
own work: :mod:`brdfcorr.io.envi_output`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import uuid
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import dask
import dask.threaded
import numpy as np
import rasterio
import rasterio.enums
import rasterio.shutil
import rasterio.windows
import rioxarray  # noqa: F401  (registers the .rio accessor the writer uses)
import xarray as xr
from rasterio._err import CPLE_BaseError  # GDAL errors rasterio passes on as they are
from xarray.conventions import encode_cf_variable

from brdfcorr.defaults import default_threads
from brdfcorr.errors import BrdfcorrError, InputError
from brdfcorr.io import COMPRESSIONS, EXTENSIONS, FORMATS
from brdfcorr.io.commit import Target, io_failure, remote_failure, verify, write_error, written_files
from brdfcorr.io.envi_output import (  # the ENVI layout and text of band centres, importable here too
    EnviOutput,
    check_envi_georeference,
    envi_safe,
    header_fields_in_header_only,
    wavelength_text,
    write_envi_header,
)
from brdfcorr.io.files import DISK_CAUSES, interrupts_held, sync_file, temporary_beside, write_cause
from brdfcorr.io.gdal_log import GdalLog
from brdfcorr.io.paths import (  # path checks and names, importable here too
    check_format,
    envi_header_path,
    envi_sidecars,
)

__all__ = ["write_rasters", "writing", "encode_integers", "local_scheduler", "pass_threads", "default_threads",
           "wavelength_text", "wavelength_tags", "GeoTiffOutput", "EnviOutput", "check_format", "envi_header_path",
           "envi_sidecars", "check_envi_georeference", "DEFAULT_CHUNK", "COMPRESSIONS", "FORMATS", "EXTENSIONS"]

#: Spatial chunk (and output tile) size [pixels].
DEFAULT_CHUNK = 512


def local_scheduler(scheduler):
    """``scheduler`` as :func:`dask.compute` takes it, a name or None resolved to a local
    scheduler's function where no dask.distributed Client can exist (distributed not imported).

    dask looks for a current Client on every pass with a name or None as the scheduler, and so
    imports dask.distributed (0.3 s, a third of a small correction) where it is installed; a
    function is taken as given. None is dask's ``scheduler`` setting, else the threaded scheduler
    of dask arrays. With distributed imported (a Client may be current), and for a Client,
    ``"distributed"`` or another object, ``scheduler`` is returned unchanged for dask to resolve.
    """
    if "distributed" in sys.modules or not (scheduler is None or isinstance(scheduler, str)):
        return scheduler
    name = scheduler if scheduler is not None else dask.config.get("scheduler", None)
    if name is None:
        return dask.threaded.get
    if not isinstance(name, str):
        return name
    return dask.base.named_schedulers.get(name.lower(), name)


def pass_threads(scheduler, num_workers: int | None) -> int | None:
    """The ``num_workers`` of a scene's dask pass (:func:`write_rasters` and the checks that read
    before it, :func:`brdfcorr.io.scale_check.check_reflectance_scale`): as given (or dask's
    ``num_workers`` setting), else :func:`default_threads` on dask's threaded scheduler; None
    leaves other schedulers be."""
    if num_workers is not None or dask.config.get("num_workers", None) is not None:
        return num_workers
    if dask.base.get_scheduler(scheduler=local_scheduler(scheduler)) not in (None, dask.threaded.get):
        return None
    return default_threads()


@dataclass(frozen=True)
class GeoTiffOutput:
    """How :func:`write_rasters` creates its GeoTIFF targets (GDAL creation settings, as a
    rasterio creation profile holds them).

    Attributes
    ----------
    compress : str, default "deflate"
        GDAL compression (``deflate``, ``lzw``, ``zstd``, ``none``; case-insensitive, None is
        ``none``).
    blocksize : int, default 512
        Tile size [pixels]; a positive multiple of 16. Chunks should be multiples of it.
    cog : bool, default False
        Write Cloud-Optimized GeoTIFFs (the finished GeoTIFF copied with overviews).
    """

    compress: str = "deflate"
    blocksize: int = DEFAULT_CHUNK
    cog: bool = False


def _tile_size(blocksize: int, array: xr.DataArray) -> tuple[int, int]:
    """The GeoTIFF tile (width, height) [pixels]: ``blocksize``, but no larger than the raster rounded
    up to a multiple of 16 (GDAL allocates whole tiles: a tile of 100 000 pixels square and 4 bands
    of float32 would be 160 GB, for any raster)."""
    height, width = array.shape[-2:]
    return tuple(min(blocksize, -(-size // 16) * 16) for size in (width, height))  # type: ignore[return-value]


def _write_options(compress: str, blocksize: int, array: xr.DataArray) -> dict:
    tile_width, tile_height = _tile_size(blocksize, array)
    options = {"driver": "GTiff", "tiled": True, "blockxsize": tile_width, "blockysize": tile_height,
               "compress": compress, "BIGTIFF": "IF_SAFER"}
    if compress.lower() in ("deflate", "lzw", "zstd"):
        options["predictor"] = 3 if array.dtype.kind == "f" else 2
        # GDAL compresses the tiles of each written window on all cores (the writer holds a lock
        # per file; without this one thread compressed every tile of a scene).
        options["num_threads"] = "ALL_CPUS"
    return options


def encode_integers(array: xr.DataArray, dtype, scale, offset, nodata: float | None = None):
    """Reflectance as stored integers, ``stored = round((reflectance - offset) / scale)``, for an output
    in the input's integer type.

    Parameters
    ----------
    array : xarray.DataArray (band, y, x)
        Reflectance factors, NaN as nodata; numpy or dask backed (stays lazy).
    dtype : numpy integer dtype
        The stored type (e.g. the input's ``int16``), of at most 32 bits: a 64-bit type is an
        :class:`~brdfcorr.errors.InputError` (GDAL keeps a raster's nodata as a double, and rasterio
        reads int64's lowest value back as -9; uint64's highest is refused when written).
    scale, offset : float or sequence of float
        Reflectance per stored unit and of a stored 0 [1]: one value, or one per band. Written as the
        file's GDAL scales and offsets (``attrs["scales"]``, ``attrs["offsets"]``), so that readers
        get reflectance back as ``stored * scale + offset``.
    nodata : number, optional
        Stored value of nodata; by default the type's lowest (signed) or highest (unsigned) value.

    Returns
    -------
    (xarray.DataArray, xarray.DataArray)
        The stored values (``dtype``, nodata written as the rioxarray nodata) and a (y, x) mask of the
        pixels that were valid but fell outside the type's range in some band (or on the nodata value):
        they are stored as nodata, never wrapped around or clipped silently.
    """
    dtype = np.dtype(dtype)
    if dtype.kind not in "iu":
        raise InputError(f"encode_integers needs an integer type, got {dtype}")
    if dtype.itemsize > 4:  # the nodata of a 64-bit raster goes through a double in GDAL and rasterio
        raise InputError(f"encode_integers: {dtype} cannot be written exactly (its nodata does not read back); "
                         "use a type of at most 32 bits, or floats")
    info = np.iinfo(dtype)
    if nodata is None:
        nodata = info.min if dtype.kind == "i" else info.max
    band = array.dims[0]
    per_band = {"dims": band, "coords": {band: array[band]}} if band in array.coords else {"dims": band}
    scales = xr.DataArray(np.broadcast_to(np.asarray(scale, float), array.shape[:1]), **per_band)
    offsets = xr.DataArray(np.broadcast_to(np.asarray(offset, float), array.shape[:1]), **per_band)
    # One task per chunk (lazy for dask input): the chunk is encoded as the write consumes it.
    encoded = xr.apply_ufunc(_encode_block, array, scales, offsets, kwargs={"dtype": dtype, "nodata": nodata},
                             dask="parallelized", output_dtypes=[dtype])
    # Stored as nodata although valid: outside the type's range or on the nodata value.
    out_of_range = ((encoded == nodata) & array.notnull()).any(dim=band)
    encoded.attrs = {**array.attrs, "scales": tuple(scales.values.tolist()), "offsets": tuple(offsets.values.tolist())}
    encoded.encoding = {}
    return encoded.rio.write_nodata(nodata, encoded=False), out_of_range


def _encode_block(values: np.ndarray, scales: np.ndarray, offsets: np.ndarray, dtype: np.dtype,
                  nodata: float) -> np.ndarray:
    """One (band, y, x) chunk of :func:`encode_integers`: ``round((values - offsets) / scales)`` in
    float64 (numpy's round half to even), ``nodata`` where that is NaN, outside ``dtype``'s range
    or equal to ``nodata``. ``scales`` and ``offsets`` are (band, 1, 1); float64 temporaries are
    made for one band at a time (a chunk of float64 values would be twice the float32 chunk)."""
    info = np.iinfo(dtype)
    encoded = np.full(values.shape, nodata, dtype=dtype)
    for index in range(values.shape[0]):
        stored = (values[index].astype(np.float64) - offsets[index]) / scales[index]
        np.round(stored, out=stored)
        fits = (stored >= info.min) & (stored <= info.max) & (stored != nodata)  # False for NaN
        np.copyto(encoded[index], stored, casting="unsafe", where=fits)
    return encoded


def write_rasters(
    rasters: Mapping[str | os.PathLike, xr.DataArray],
    *,
    geotiff: GeoTiffOutput = GeoTiffOutput(),
    tags: Mapping[str, str] | None = None,
    commit_tags: Mapping[str, str] | None = None,
    compute_with: object = None,
    callbacks: Sequence = (),
    gdal_cache: int | None = None,
    scheduler: str | None = None,
    num_workers: int | None = None,
    envi: Mapping[str | os.PathLike, EnviOutput] | None = None,
):
    """Write DataArrays to tiled, compressed GeoTIFFs (or ENVI files), chunk by chunk, atomically.

    All rasters (and ``compute_with``, any dask collection such as lazy QA counts) are computed in
    one dask pass, so shared inputs are read once. Each file is written under its own lock to a
    temporary name beside the target and renamed only when complete (with ``geotiff.cog``, the
    finished GeoTIFF is then copied to a Cloud-Optimized GeoTIFF with overviews, streaming by blocks).
    Nothing appears at a target when anything fails; a failed write (disk full, file size limit,
    permissions) raises :class:`~brdfcorr.errors.OutputError` naming the targets and the reason.

    Every output is committed once, after it was verified: GDAL's failures during the writes and
    at close are collected (rasterio raises none for a failed flush), each file is reopened and
    checked (size, bands, tags, every GeoTIFF tile present within the file, an ENVI data file of
    its full length), flushed to the device (``fsync``), and only then are the files renamed, the
    sidecars before their data file and the first target last.

    Parameters
    ----------
    rasters : mapping of path to DataArray
        Targets and their (band, y, x) or (y, x) arrays with georeference (``spatial_ref``);
        the array's ``rio.nodata`` (or ``_FillValue``) is written as nodata, ``long_name``
        tuples as band descriptions and attrs as dataset tags.
    geotiff : GeoTiffOutput, default GeoTiffOutput()
        Compression, tile size [pixels] and Cloud-Optimized GeoTIFF switch of the GeoTIFF targets
        (default: deflate, 512-pixel tiles, no COG).
    tags : mapping, optional
        Extra dataset tags for every file (provenance).
    commit_tags : mapping, optional
        Tags of the first target only, which is renamed into place last (a chain's fingerprint):
        whoever finds them finds every output of the pass complete.
    compute_with : optional
        Lazy results to compute in the same pass; returned computed.
    callbacks : sequence of dask callbacks
        E.g. a progress bar, active during the computation.
    gdal_cache : int, optional
        GDAL block cache [bytes] while reading and writing (:func:`gdal_cache_bytes`); GDAL's
        default otherwise.
    scheduler, num_workers : optional
        dask scheduler of the pass and its number of workers (as for :func:`dask.compute`;
        default: dask's). A ``dask.distributed`` client (or ``"distributed"``, or dask's default
        client) spreads the chunks over the cluster's workers, each writing under a
        :class:`distributed.Lock` of its file. On dask's threaded scheduler without a thread count
        (``num_workers`` or dask's ``num_workers`` setting) the pass uses one thread per
        :data:`brdfcorr.defaults.CORES_PER_THREAD` cores: GDAL compresses the tiles on all of them.
    envi : mapping of path to EnviOutput, optional
        Targets to write as ENVI (uncompressed, ``geotiff`` does not apply), with their
        header (``.hdr`` beside the data file, :func:`envi_header_path`) and ``.aux.xml`` (tags);
        all written to temporary names and renamed when complete, the data file last.

    Returns
    -------
    The computed ``compute_with`` (None if not given).
    """
    with writing(rasters, geotiff, tags=tags, commit_tags=commit_tags, callbacks=callbacks, gdal_cache=gdal_cache,
                 scheduler=scheduler, envi=envi) as writes:
        *_, extra = dask.compute(*writes, compute_with, scheduler=local_scheduler(scheduler),
                                 num_workers=pass_threads(scheduler, num_workers))
    return extra


@contextlib.contextmanager
def writing(rasters: Mapping, geotiff: GeoTiffOutput = GeoTiffOutput(), *, tags=None, commit_tags=None,
            callbacks: Sequence = (), gdal_cache: int | None = None, scheduler=None,
            envi: Mapping | None = None) -> Iterator[list]:
    """The writing pass of :func:`write_rasters` around a caller that computes it: every target
    created under a temporary name, the lazy writes of their chunks given to the ``with`` block,
    which computes them (in one :func:`dask.compute` with what else it needs: a task computes its
    own pass, so the writer does not drive the task's functions), with ``callbacks`` active;
    then the files closed, checked for GDAL's failures, verified, flushed and committed
    (:meth:`~brdfcorr.io.commit.Target.commit`), the first target last. Any failure, in the block
    as well, removes every temporary. Arguments as for :func:`write_rasters`.

    Yields
    ------
    list
        The lazy writes (dask; None for an array in memory, written when created).
    """
    geotiff, envi = _checked(rasters, geotiff, envi)
    targets: list[Target] = []
    # On a cluster the workers write the chunks; here, only this thread's own GDAL calls count.
    failures = GdalLog(thread=threading.get_ident() if _distributed_client(scheduler) is not None else None,
                       failures=True)
    settings = {"GDAL_CACHEMAX": int(gdal_cache)} if gdal_cache else {}
    try:
        with failures, rasterio.Env(**settings):
            for target, array in rasters.items():
                with interrupts_held():  # a Ctrl-C while a file is made arrives once ``targets`` holds it
                    targets.append(_target(Path(target), array, envi.get(Path(target)), geotiff.cog))
            handles: list = []
            writes = _stores(targets, geotiff, tags, commit_tags, _distributed_client(scheduler), handles)
            with contextlib.ExitStack() as active:
                for callback in callbacks:
                    active.enter_context(callback)
                try:  # one pass for everything: shared inputs are read and normalized once
                    yield writes
                except BaseException:
                    for handle in handles:  # the failure is the news; the files are discarded
                        with contextlib.suppress(Exception):
                            handle.close()
                    raise
            _finish(targets, handles, geotiff)
        if failures.failures:
            raise write_error(list(rasters), write_cause(None, written_files(targets), failures.cause()))
        _commit(targets, tags, commit_tags)
    except BaseException as error:
        problem = _problem(error, list(rasters), failures, targets)
        for target in targets:
            target.discard()
        if problem is not None:
            raise problem from error
        raise


def _checked(rasters: Mapping, geotiff: GeoTiffOutput, envi: Mapping | None) -> tuple[GeoTiffOutput, dict]:
    """The arguments of :func:`write_rasters` checked before anything is created: the tile size,
    the output folders, the compression (lower case), ENVI and COG apart, the ENVI targets'
    georeference. Returns ``geotiff`` with its compression in lower case and the ENVI targets by path."""
    blocksize = geotiff.blocksize
    if not (blocksize >= 16 and blocksize % 16 == 0):
        raise InputError(f"tile size {blocksize} must be a positive multiple of 16")
    for target in rasters:
        if not Path(target).parent.is_dir():
            raise InputError(f"output directory {Path(target).parent} does not exist")
    compress = "none" if geotiff.compress is None else str(geotiff.compress).lower()
    if compress not in COMPRESSIONS:  # GDAL would write uncompressed, silently
        raise InputError(f"unknown compression {compress!r}; choose one of {', '.join(COMPRESSIONS)}")
    geotiff = replace(geotiff, compress=compress)
    envi = {Path(target): layout for target, layout in (envi or {}).items()}
    if geotiff.cog and envi:
        raise InputError("Cloud-Optimized GeoTIFF (cog) and ENVI output exclude each other")
    for target in envi:
        if target in {Path(path) for path in rasters}:
            check_envi_georeference(rasters[next(path for path in rasters if Path(path) == target)], target)
    return geotiff, envi


def _commit(targets: list[Target], tags, commit_tags) -> None:
    """Verify and flush every target, then rename them into place, the first (with the commit tags) last."""
    for index, target in enumerate(targets):
        verify(target, _file_tags(tags, commit_tags, index, target), written_files(targets))
        for path in target.kept():
            if path.exists():
                sync_file(path)
    for target in reversed(targets):
        target.commit()


def _problem(error: BaseException, rasters: list, failures: GdalLog, targets: list[Target]) -> BrdfcorrError | None:
    """The :class:`OutputError` that a failed write is, or the :class:`InputError` of an input
    that could not be read during it (None: ``error`` says it itself)."""
    remote = remote_failure(error)
    if remote is not None:
        return InputError(f"reading or writing failed while writing {', '.join(map(str, rasters))}: {remote}")
    failed = isinstance(error, (OSError, rasterio.errors.RasterioError, CPLE_BaseError))
    if failed and not isinstance(error, BrdfcorrError):
        return io_failure(error, rasters, [failures.cause()] if failures.failures else [], written_files(targets))
    if isinstance(error, SystemError):  # rasterio: GDAL failed and said nothing (a full disk at creation)
        cause = write_cause(None, written_files(targets), "")
        return write_error(rasters, cause) if cause.startswith(DISK_CAUSES) else None
    return None


#: Tags an ENVI output's header holds (its ``wavelength``, ``wavelength units`` and ``fwhm`` fields:
#: :func:`wavelength_tags`), not written again into its ``.aux.xml``, whose tags GDAL and brdfcorr
#: would read over the header.
ENVI_HEADER_TAGS = ("wavelength", "wavelength_units", "fwhm")


def _file_tags(tags, commit_tags, index: int, target: Target) -> dict:
    """The tags of the ``index``-th target: ``tags``, and ``commit_tags`` on the first only; for an
    ENVI output, less those its header holds (:data:`ENVI_HEADER_TAGS`)."""
    found = {**(tags or {}), **((commit_tags or {}) if index == 0 else {})}
    if isinstance(target.layout, EnviOutput):
        found = {key: value for key, value in found.items() if key not in ENVI_HEADER_TAGS}
    return found


def _target(final: Path, array: xr.DataArray, layout: EnviOutput | None, cog: bool) -> Target:
    """A :class:`~brdfcorr.io.commit.Target` with its temporary files beside ``final`` (created here)."""
    temporary = temporary_beside(final)
    written = Path(f"{temporary}.gtiff") if cog else temporary
    if layout is None:
        return Target(final, array, None, temporary, written, [])
    return Target(final, envi_safe(array), layout, temporary, written, envi_sidecars(temporary, final))


def _stores(targets: list[Target], geotiff: GeoTiffOutput, tags, commit_tags, client, handles: list) -> list:
    """Create the files and return their lazy writes (:func:`_store`; open handles appended to ``handles``)."""
    writes = []
    for index, target in enumerate(targets):
        if isinstance(target.layout, EnviOutput):
            options = {"driver": "ENVI", "interleave": target.layout.interleave.upper(), "SUFFIX": "ADD"}
        else:
            options = _write_options(geotiff.compress, geotiff.blocksize, target.array)
        writes.append(_store(target.array, target.written, options, _file_tags(tags, commit_tags, index, target),
                             client, handles))
    return writes


def _overview_resampling(array: xr.DataArray) -> str:
    """How a COG's overviews are made: "nearest" for bit flags (a QA layer: CF ``flag_masks``) and
    class ids, whose means are other flags (nodata | no_class of [2, 2, 4, 4]) or classes, and
    "average" for values (reflectance, its 1-sigma)."""
    categorical = "flag_masks" in array.attrs or array.attrs.get("long_name") == "class id"
    return "nearest" if categorical else "average"


def _finish(targets: list[Target], handles: list, geotiff: GeoTiffOutput) -> None:
    """After the pass: close the files (a full disk often fails here), copy the COGs and complete
    the ENVI headers."""
    for handle in handles:  # waits for GDAL's last compressed tiles; a full disk fails here
        handle.close()
    for target in targets:
        if target.written != target.temporary:
            size = _tile_size(geotiff.blocksize, target.array)
            rasterio.shutil.copy(
                target.written, target.temporary, driver="COG", compress=geotiff.compress.upper(),
                blocksize=max(size), overview_resampling=_overview_resampling(target.array), BIGTIFF="IF_SAFER",
                **_cog_options(geotiff.compress),
            )
        if isinstance(target.layout, EnviOutput):
            write_envi_header(target.temporary, target.layout, target.final)
            header_fields_in_header_only(Path(f"{target.temporary}.aux.xml"))


def _cog_options(compress: str) -> dict:
    """The COG copy's predictor (``YES``: 2 for integers, 3 for floats, as the GeoTIFF written
    first) and compression threads, for the compressions that take them."""
    if compress in ("deflate", "lzw", "zstd"):
        return {"predictor": "YES", "num_threads": "ALL_CPUS"}
    return {}


def _distributed_client(scheduler):
    """The dask.distributed Client that ``dask.compute(scheduler=scheduler)`` would run on (a
    Client, its ``get``, ``"distributed"`` or dask's default), or None for a local scheduler."""
    get = dask.base.get_scheduler(scheduler=local_scheduler(scheduler))
    owner = getattr(get, "__self__", None)
    return owner if type(owner).__name__ == "Client" else None


def _store(array: xr.DataArray, path: Path, options: dict, tags: dict, client, handles: list):
    """The lazy write of ``array`` to ``path`` (created here by rioxarray: georeference, nodata,
    band descriptions, tags): through one open handle (:class:`_OpenRaster`, appended to
    ``handles``) on a local scheduler, through rioxarray's reopening writer under a
    :class:`distributed.Lock` on a cluster; None when ``array`` is in memory (written here)."""
    if client is None:
        lock = threading.Lock()
    else:
        from distributed import Lock  # only with a cluster: dask.distributed is then imported

        # The client's own connection: dask's default client may be another one, or none.
        lock = Lock(f"brdfcorr-write-{uuid.uuid4().hex}", scheduler_rpc=client.scheduler, loop=client.loop)
    write = array.rio.to_raster(path, tags=tags, lock=lock, compute=False, **options)
    if write is None or client is not None:
        return write
    with rasterio.open(path) as created:  # the data type rioxarray chose for the file
        dtype = created.dtypes[0]
    threads = {"num_threads": options["num_threads"]} if "num_threads" in options else {}
    handle = _OpenRaster(path, lock, threads)
    handles.append(handle)
    # rioxarray's own encoding of the data (nodata fill, CF encoding), stored through one handle.
    return dask.array.store(encode_cf_variable(array.variable).data.astype(dtype), handle, lock=False,
                            compute=False)


class _OpenRaster:
    """A :func:`dask.array.store` target that writes every chunk through one open dataset.

    rioxarray's writer reopens the file for every chunk, and closing a GeoTIFF waits until its
    tiles are compressed: compression then runs one tile at a time under the file's lock. Kept
    open, GDAL hands each finished tile to its compression threads (``num_threads``, an open
    option of the GTiff driver) and the write returns, so tiles are compressed in parallel.
    Datasets are not thread-safe: every use holds ``lock``.
    """

    def __init__(self, path: Path, lock, options: Mapping[str, str]):
        self.path, self.lock, self.options = path, lock, dict(options)
        self.dataset = None

    def __setitem__(self, key: tuple[slice, ...], chunk) -> None:
        *bands, rows, columns = key
        window = rasterio.windows.Window.from_slices(rows, columns)
        indexes = list(range(bands[0].start + 1, bands[0].stop + 1)) if bands else 1
        with self.lock, rasterio.Env():  # GDAL's errors in this thread go to rasterio's log, not stderr
            if self.dataset is None:
                self.dataset = rasterio.open(self.path, "r+", **self.options)
            self.dataset.write(chunk, window=window, indexes=indexes)

    def close(self) -> None:
        """Flush and close (waits for the tiles still being compressed)."""
        with self.lock:
            dataset, self.dataset = self.dataset, None
            if dataset is not None:
                dataset.close()


def wavelength_tags(values: Sequence[float], fwhm: Sequence[float] | None = None) -> dict[str, str]:
    """The ``wavelength`` and ``wavelength_units`` tags of an output's band centres [nm], and its
    ``fwhm`` tag where the bands' full widths at half maximum [nm] are given (:func:`wavelength_text`;
    an ENVI output's header holds them instead, :data:`ENVI_HEADER_TAGS`)."""
    tags = {"wavelength": ",".join(map(wavelength_text, values)), "wavelength_units": "nm"}
    if fwhm is not None:
        tags["fwhm"] = ",".join(map(wavelength_text, fwhm))
    return tags
