"""An image product identified once (:func:`identify_image`: its kind, layout and band count, one
look at the file), and what follows from that: the chunk size of its reading (:func:`auto_chunk`)
and GDAL's block cache for it (:func:`gdal_cache_bytes`), and the peak memory of a correction.

The :class:`ImageFile` is carried to whatever opens or sizes the image
(:func:`brdfcorr.io.rasters.open_image`, :func:`brdfcorr.io.scene.open_scene`) instead of each
looking at the file again (issue 42: a correction looked up its HDF5 product kind on every call).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import rasterio
from rasterio._err import CPLE_BaseError  # GDAL errors rasterio passes on as they are
from rasterio.enums import MaskFlags

from brdfcorr.errors import InputError
from brdfcorr.io.opening import container_message, has_envi_header, opened
from brdfcorr.io.sensors.envi import bad_band_flags
from brdfcorr.io.sensors.products import hdf5_product

__all__ = [
    "Layout",
    "ImageFile",
    "identify_image",
    "image_layout",
    "choose_chunk",
    "auto_chunk",
    "cache_bytes",
    "gdal_cache_bytes",
    "bounded_gdal_cache",
    "peak_memory_terms",
]

#: Bounds of GDAL's block cache [bytes] while brdfcorr reads and writes (:func:`gdal_cache_bytes`).
MIN_GDAL_CACHE, MAX_GDAL_CACHE = 64 * 2**20, 512 * 2**20


#: Bytes of one chunk of all bands (as float32) that :func:`auto_chunk` aims at [bytes].
CHUNK_TARGET = 16 * 2**20
#: Copies of its chunk (all bands, float32) a dask thread holds at the peak of the correction:
#: the read, its masked copy, the corrected chunk, the encoded chunk being written (measured with
#: tracemalloc on a 64-band cube; ``docs/scaling.md``, "Memory").
CHUNK_COPIES = 4
#: Output tiles (one chunk each) that GDAL holds per compression thread: the tile queued and the
#: tile being compressed with its compressed buffer (``docs/scaling.md``, "Memory").
TILES_PER_COMPRESSOR = 2
#: What a correction holds beyond the imports, its threads, the cache and the compression, whatever
#: the image's size [bytes]: the opened scene (graph, coordinates, the checks' samples), GDAL's
#: drivers and glibc's per-thread arenas. Measured on the 1 GiB cube of ``benchmarks/bench_memory.py``
#: (the other cubes' peaks then test the model).
RUN_OVERHEAD = 200 * 2**20


class Layout(NamedTuple):
    """How an image is stored, as the chunk choice needs it: bands, size [pixels], GDAL's block
    (tile or strip) size [pixels] and the bytes per stored value."""

    bands: int
    height: int
    width: int
    block_rows: int
    block_columns: int
    itemsize: int = 4


class ImageFile(NamedTuple):
    """An image file identified once (:func:`identify_image`), to be carried to what sizes its
    chunks and cache (:func:`auto_chunk`, :func:`gdal_cache_bytes`) and what opens it
    (:func:`open_image`, :func:`brdfcorr.io.scene.open_scene`) instead of each looking again.

    Attributes
    ----------
    path : path-like
        The file.
    product : {"neon", "emit"} or None
        The HDF5 product it is (:func:`brdfcorr.io.sensors.products.hdf5_product`), None for a
        raster GDAL reads.
    layout : Layout or None
        How GDAL stores it (None for a product).
    bands : int
        Its band count.
    plain : bool
        Whether its stored values are what a masked and scaled read gives (:func:`_read_as_stored`).
    envi_header : tuple of str or None
        For an ENVI file the fields of its header that GDAL keeps in its ENVI metadata domain;
        None for another format.
    header_scale : float or None
        The scale [1 per stored unit] its ENVI header's ``reflectance scale factor`` gives
        (:func:`header_scale`); None without one.
    bad_bands : numpy.ndarray of bool or None
        The bands its ENVI header's ``bbl`` marks bad
        (:func:`brdfcorr.io.sensors.envi.envi_bad_bands`); None without one.
    """

    path: object
    product: str | None
    layout: Layout | None
    bands: int
    plain: bool = False
    envi_header: tuple[str, ...] | None = None
    header_scale: float | None = None
    bad_bands: np.ndarray | None = None


def identify_image(path) -> ImageFile:
    """The :class:`ImageFile` of an image: its product kind, layout, band count and ENVI header
    fields, read once.

    Raises
    ------
    InputError
        A missing or unreadable file (:func:`brdfcorr.io.opening.opened`).
    """
    product = hdf5_product(path)
    if product is not None:
        from brdfcorr.io.sensors import emit, neon

        count = neon.neon_band_count(path) if product == "neon" else emit.emit_band_count(path)
        return ImageFile(path, product, None, count)
    with opened(path, "image") as dataset:
        if dataset.count == 0:  # a container of subdatasets (NetCDF, HDF): open_raster's refusal, first
            raise InputError(container_message("image", path))
        rows, columns = dataset.block_shapes[0]
        layout = Layout(dataset.count, dataset.height, dataset.width, rows, columns,
                        np.dtype(dataset.dtypes[0]).itemsize)
        if dataset.driver != "ENVI":
            return ImageFile(path, None, layout, layout.bands, _stored_as_read(dataset))
        envi = dataset.tags(ns="ENVI")
        return ImageFile(path, None, layout, layout.bands, _stored_as_read(dataset), tuple(envi),
                         _header_scale(dataset), bad_band_flags(envi, dataset.count, path))


def _identified(image) -> ImageFile:
    """``image`` if it is an :class:`ImageFile` already, else :func:`identify_image` of the path."""
    return image if isinstance(image, ImageFile) else identify_image(image)


def image_layout(path) -> Layout | None:
    """The :class:`Layout` of an image file (path or :class:`ImageFile`); None for a NEON or EMIT
    product (not read by GDAL)."""
    return _identified(path).layout


def _chunk_bytes(bands: int, chunk: int) -> int:
    return bands * chunk * chunk * 4


def _budget_chunk(bands: int, target_bytes: int) -> int:
    """The largest of 512, 256, 128, 64 whose chunk of all bands (float32) holds at most ``target_bytes``."""
    return next((size for size in (512, 256, 128) if _chunk_bytes(bands, size) <= target_bytes), 64)


def _alignment(layout: Layout) -> int:
    """The smallest chunk size [pixels] that is a multiple of 16 (GeoTIFF tiles) and of the input's
    block in y and x; a block spanning the whole image in a dimension (a strip's width) asks nothing there."""
    rows = layout.block_rows if layout.block_rows < layout.height else 1
    columns = layout.block_columns if layout.block_columns < layout.width else 1
    return math.lcm(16, rows, columns)


def choose_chunk(layout: Layout, target_bytes: int = CHUNK_TARGET) -> int:
    """Spatial chunk (and output tile) size [pixels] for an image stored as ``layout``.

    The largest multiple of the input's blocks (:func:`_alignment`: tiles in y and x, strips in y,
    and 16) whose chunk of all bands (float32) holds at most ``target_bytes``: each input tile is
    then decompressed once, by one dask thread, whatever the number of threads. Where one block of
    all bands holds more (512-pixel tiles of 64 bands, 256-pixel tiles of 425 bands): the largest of
    512, 256, 128, 64 within ``target_bytes`` (it divides a tile whose size is a power of two), and
    :func:`cache_bytes` keeps the row of input blocks that a row of chunks touches in GDAL's cache,
    so that each is decompressed once as long as that row fits (:data:`MAX_GDAL_CACHE`). Chunks of
    one large tile would cost more: each dask thread and compression thread holds several chunks
    (``docs/scaling.md``, "Memory": 1309 MiB against 830 MiB for 512-pixel tiles of 64 bands).
    """
    budget = _budget_chunk(layout.bands, target_bytes)
    unit = _alignment(layout)
    aligned = unit * max(1, budget // unit)
    return aligned if _chunk_bytes(layout.bands, aligned) <= target_bytes else budget


def auto_chunk(path, target_bytes: int = CHUNK_TARGET) -> int:
    """Spatial chunk (and tile) size [pixels] for an image file (a path or its :class:`ImageFile`;
    :func:`choose_chunk`): aligned to its tiles, about ``target_bytes`` of all bands (as float32),
    so memory stays flat for hyperspectral cubes. A NEON or EMIT product (HDF5, no GDAL tiles): the
    largest of 512, 256, 128, 64 within ``target_bytes``."""
    image = _identified(path)
    if image.layout is None:
        return _budget_chunk(image.bands, target_bytes)
    return choose_chunk(image.layout, target_bytes)


def cache_bytes(layout: Layout, chunk: int) -> int:
    """GDAL block cache [bytes] for reading an image stored as ``layout`` in chunks of ``chunk``
    pixels (:func:`gdal_cache_bytes`).

    Room for two decompressed input blocks (all bands: GDAL decompresses a pixel-interleaved tile
    once for all its bands only if the cache holds them) and four chunks; where chunks are not
    multiples of the blocks (strips, tiles larger than a chunk), room for the full-width rows of
    blocks that one row of chunks touches, so that each block is decompressed once. Between
    :data:`MIN_GDAL_CACHE` and :data:`MAX_GDAL_CACHE`.
    """
    rows, columns = min(layout.block_rows, layout.height), min(layout.block_columns, layout.width)
    need = max(2 * layout.bands * rows * columns * layout.itemsize, 4 * _chunk_bytes(layout.bands, chunk))
    if chunk % rows or chunk % columns:
        band_rows = min(math.lcm(rows, chunk), layout.height)
        need = max(need, band_rows * layout.width * layout.bands * layout.itemsize)
    return int(np.clip(need, MIN_GDAL_CACHE, MAX_GDAL_CACHE))


def gdal_cache_bytes(path, chunk: int) -> int:
    """A GDAL block cache [bytes] for reading ``path`` (or its :class:`ImageFile`) in chunks of
    ``chunk`` pixels (:func:`cache_bytes`). GDAL's default (5 % of RAM) would let the cache, and so
    the peak memory, grow with the image. A NEON or EMIT image is not read through GDAL: room for
    four chunks (the class map's reads) suffices."""
    image = _identified(path)
    if image.layout is None:
        return int(np.clip(4 * _chunk_bytes(image.bands, chunk), MIN_GDAL_CACHE, MAX_GDAL_CACHE))
    return cache_bytes(image.layout, chunk)


def bounded_gdal_cache(path, chunk: int) -> rasterio.Env:
    """GDAL's block cache bounded to :func:`gdal_cache_bytes` while the returned environment is
    active: for a whole run (the checks and passes that read before the write as well), since GDAL's
    default (5 % of RAM) keeps every tile read in memory, and rioxarray keeps the files open."""
    return rasterio.Env(GDAL_CACHEMAX=gdal_cache_bytes(path, chunk))


def peak_memory_terms(layout: Layout, chunk: int, threads: int, cores: int) -> dict[str, int]:
    """The peak-memory model of a correction of an image stored as ``layout`` beyond the imports
    [bytes] (``docs/scaling.md``, "Memory"): per dask thread its file handle's decompressed input
    block (all bands) and :data:`CHUNK_COPIES` chunks; GDAL's block cache (:func:`cache_bytes`);
    per compression thread (one per core) :data:`TILES_PER_COMPRESSOR` output tiles of one chunk;
    and :data:`RUN_OVERHEAD`."""
    chunk_bytes = _chunk_bytes(layout.bands, chunk)
    block = min(layout.block_rows, layout.height) * min(layout.block_columns, layout.width)
    return {"threads": threads * (layout.bands * block * layout.itemsize + CHUNK_COPIES * chunk_bytes),
            "cache": cache_bytes(layout, chunk), "compression": cores * TILES_PER_COMPRESSOR * chunk_bytes,
            "overhead": RUN_OVERHEAD}


def header_scale(path) -> float | None:
    """The scale [reflectance factor per stored unit] an ENVI image's header gives in its
    ``reflectance scale factor``: 1 / that factor, which by ENVI's definition divided into the data
    gives reflectance 0-1 (HyTools and many ENVI cubes store reflectance x 10 000 so). None for
    another format, without the field, with a factor of 1, or where GDAL applies a scale of its
    own. A factor that is no positive finite number is an :class:`InputError`. None where GDAL
    cannot open the file (the reader says why)."""
    if not has_envi_header(path):  # no ENVI image: not opened to tell
        return None
    try:
        with opened(path, "image") as dataset:
            text = _header_factor(dataset)
    except (InputError, rasterio.errors.RasterioError, CPLE_BaseError):
        return None
    return _scale_of_factor(text, path)


def _header_scale(dataset) -> float | None:
    """:func:`header_scale` of an open dataset."""
    return _scale_of_factor(_header_factor(dataset), dataset.name)


def _header_factor(dataset) -> str | None:
    """The ENVI header's ``reflectance scale factor`` as written, where GDAL applies no scale."""
    if dataset.driver != "ENVI" or any(value != 1 for value in dataset.scales):
        return None
    return dataset.tags(ns="ENVI").get("reflectance_scale_factor")


def _scale_of_factor(text: str | None, path) -> float | None:
    """1 / the factor ``text`` of :func:`header_scale` (None for none or 1)."""
    if text is None:
        return None
    try:
        factor = float(text.strip("{} "))
    except ValueError:
        factor = math.nan
    if not (math.isfinite(factor) and factor > 0):
        raise InputError(f"image {path}: its ENVI header's reflectance scale factor {text!r} is no positive number")
    return None if factor == 1 else 1.0 / factor


def _read_as_stored(path) -> bool:
    """Whether the stored values of ``path`` are what a masked and scaled read gives: float bands
    whose nodata is NaN or none, without a mask band, a scale or an offset. Such an image is read
    without rioxarray's masking, which reads GDAL's mask and copies every chunk (a fifth of the
    read time of a float cube). False where GDAL cannot open it (:func:`open_raster` says why)."""
    try:
        with opened(path, "image") as dataset:
            return _stored_as_read(dataset)
    except (InputError, rasterio.errors.RasterioError, CPLE_BaseError):
        return False


def _stored_as_read(dataset) -> bool:
    """:func:`_read_as_stored` of an open dataset."""
    try:
        return (all(np.dtype(dtype).kind == "f" for dtype in dataset.dtypes)
                and all(value is None or math.isnan(value) for value in dataset.nodatavals)
                and all(flags in ([MaskFlags.all_valid], [MaskFlags.nodata]) for flags in dataset.mask_flag_enums)
                and all(value == 1 for value in dataset.scales) and all(value == 0 for value in dataset.offsets))
    except (rasterio.errors.RasterioError, CPLE_BaseError):
        return False
