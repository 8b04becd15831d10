"""One common grid for scenes on different grids (overlapping flight lines), so that free levels
per pixel or patch (:mod:`brdfcorr.fit.within`) can be fitted where the lines share ground.

Each line of an airborne survey has its own grid (shifted, another resolution, another CRS). The
common grid is the **first scene's CRS and pixel grid** (its resolution and pixel edges) extended
over the **union** of the scenes' extents: the first scene's pixels are common-grid pixels
unchanged, and every other scene is resampled onto it by **nearest neighbour** (values kept as
they are: no blend of two classes, no azimuth averaged across 0/360 deg).

The resampling is rioxarray's (:meth:`rioxarray.raster_array.RasterArray.reproject`, GDAL's
warper), applied to one layer per scene only: the flat index of each of the scene's own pixels.
Reprojected by nearest neighbour, it says which source pixel each common-grid pixel takes (-1
outside the scene). The class maps, the validity of the angles and the cluster layers (already
in memory for the sampler) are gathered through it, and the reflectance and the angles are read
lazily at the sampled pixels only, on the scenes' own grids: no resampled cube is ever formed.

Each scene's layers are held over its own **window** of the common grid only (the common-grid
pixels of its footprint's bounding box, :class:`Window`), not over the whole union: a survey of
many long lines over a large area holds about one integer layer per scene's own size, not one
per scene over the union (benchmarks/bench_lines_fit.py ``--layout survey``). Pixel indices
(``flat``) stay those of the whole common grid, so groups and blocks are numbered as if the
layers were whole; the windowed layers (:class:`WindowLayer`) answer as the whole ones would. A
scene in another CRS than the first keeps a window of the whole grid (:func:`_window` says why).

A common-grid pixel seen by a single scene carries no difference between views: it drops out of
a within fit (:func:`brdfcorr.fit.sampling.sample_classes` samples groups with two or more views).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from brdfcorr.errors import ParameterError

__all__ = ["CommonGrid", "Window", "WindowLayer", "common_grid"]

#: Tolerance [pixels] when the union's edges are snapped outwards to the first scene's pixel edges.
SNAP = 1e-6
#: Common-grid pixels [pixels] added around a scene's footprint for its window (the footprint's
#: bounds are those of its densified edges: a reprojected edge may bulge between their points).
MARGIN = 2


@dataclass(frozen=True)
class Window:
    """Rows ``row0`` ... ``row0 + rows - 1`` and columns ``col0`` ... of a common grid of ``shape``."""

    row0: int
    col0: int
    rows: int
    cols: int
    shape: tuple[int, int]

    def to_common(self, flat: np.ndarray) -> np.ndarray:
        """Flat indices into the window -> flat indices into the common grid (order kept)."""
        iy, ix = np.divmod(np.asarray(flat, dtype=np.int64), self.cols)
        return (iy + self.row0) * self.shape[1] + ix + self.col0

    def from_common(self, flat: np.ndarray) -> np.ndarray:
        """Flat indices into the common grid (inside the window) -> flat indices into the window."""
        iy, ix = np.divmod(np.asarray(flat, dtype=np.int64), self.shape[1])
        return (iy - self.row0) * self.cols + ix - self.col0


@dataclass(frozen=True)
class WindowLayer:
    """A layer of a common grid held over one window only (``values`` (rows, cols)); ``fill``
    elsewhere. ``shape`` is the whole grid's, and ``layer[iy, ix]`` at common-grid rows and
    columns inside the window is the whole layer's value there."""

    values: np.ndarray
    window: Window

    @property
    def shape(self) -> tuple[int, int]:
        return self.window.shape

    def __getitem__(self, key):
        iy, ix = key
        return self.values[np.asarray(iy) - self.window.row0, np.asarray(ix) - self.window.col0]

    def flat_where(self, mask: np.ndarray) -> np.ndarray:
        """The common grid's flat indices (ascending) where ``mask`` (window-shaped) holds."""
        return self.window.to_common(np.flatnonzero(mask))


@dataclass(frozen=True)
class CommonGrid:
    """The common grid (``shape`` (y, x)) and, per scene, its window (``windows``) and the flat
    index into the scene's own grid (of ``scene_shapes``) of the pixel each window pixel takes
    (``window_sources``, flat (rows * cols,), -1 where the scene does not cover it)."""

    shape: tuple[int, int]
    scene_shapes: tuple[tuple[int, int], ...]
    windows: tuple[Window, ...]
    window_sources: tuple[np.ndarray, ...]

    @property
    def sources(self) -> tuple[np.ndarray, ...]:
        """Per scene, the source index of every common-grid pixel (flat (ny * nx,), -1 outside
        the scene), over the whole grid: for inspection (one union-sized layer per scene)."""
        whole = []
        for window, source in zip(self.windows, self.window_sources):
            layer = np.full(self.shape, -1, dtype=np.int32)
            layer[window.row0:window.row0 + window.rows, window.col0:window.col0 + window.cols] = \
                source.reshape(window.rows, window.cols)
            whole.append(layer.reshape(-1))
        return tuple(whole)

    def gather(self, scene: int, values: np.ndarray, fill) -> WindowLayer:
        """A scene's layer ``values`` (y, x on its own grid) on the common grid, over the scene's
        window (``fill`` where the scene does not cover it)."""
        source, window = self.window_sources[scene], self.windows[scene]
        flat = np.asarray(values).reshape(-1)
        gathered = np.where(source >= 0, flat[np.maximum(source, 0)], fill)
        return WindowLayer(gathered.reshape(window.rows, window.cols), window)

    def source_pixels(self, scene: int, flat: np.ndarray) -> np.ndarray:
        """The flat indices into scene ``scene``'s own grid of common-grid pixels ``flat`` (inside
        the scene's window)."""
        return self.window_sources[scene][self.windows[scene].from_common(flat)]


def _crs_and_transform(image: xr.DataArray, scene: int):
    """The CRS and affine transform of a scene's image; ParameterError without a CRS."""
    crs = image.rio.crs if hasattr(image, "rio") else None
    if crs is None:
        raise ParameterError(f"scene {scene + 1} has no CRS: scenes on different grids are brought onto one "
                             "grid for free levels per pixel or patch, which needs georeferenced images (or "
                             "give scenes on one grid, or levels pooled)")
    return crs, image.rio.transform()


def _target(images: list[xr.DataArray]):
    """The common grid's CRS, transform and shape: the first image's pixel grid over the union
    of the images' extents (in its CRS), snapped outwards to its pixel edges."""
    crs, transform = _crs_and_transform(images[0], 0)
    if transform.b or transform.d:
        raise ParameterError("the first scene's grid is rotated: give a north-up first scene for the common grid")
    bounds = []
    for scene, image in enumerate(images):
        _crs_and_transform(image, scene)
        bounds.append(image.rio.transform_bounds(crs))
    left, bottom = min(b[0] for b in bounds), min(b[1] for b in bounds)
    right, top = max(b[2] for b in bounds), max(b[3] for b in bounds)
    columns = sorted(((left - transform.c) / transform.a, (right - transform.c) / transform.a))
    rows = sorted(((top - transform.f) / transform.e, (bottom - transform.f) / transform.e))
    col0, row0 = math.floor(columns[0] + SNAP), math.floor(rows[0] + SNAP)
    col1, row1 = math.ceil(columns[1] - SNAP), math.ceil(rows[1] - SNAP)
    from affine import Affine

    return crs, transform * Affine.translation(col0, row0), (row1 - row0, col1 - col0)


def _window(image: xr.DataArray, crs, transform, shape: tuple[int, int]) -> Window:
    """The common-grid pixels of the image's footprint's bounding box, with :data:`MARGIN` pixels
    around it, within the grid; the whole grid for an image in another CRS than the grid's.

    In the grid's CRS the warp from the window is the warp from the whole grid, pixel for pixel
    (an affine map, which GDAL's approximate transformer follows exactly); across CRSs that
    transformer interpolates along each destination row between points that depend on the row's
    extent, so a window could move a few pixels' nearest neighbour: such an image keeps the whole
    grid, and the fit stays that of the whole grid."""
    if image.rio.crs != crs:
        return Window(0, 0, shape[0], shape[1], shape)
    left, bottom, right, top = image.rio.transform_bounds(crs)
    columns = sorted(((left - transform.c) / transform.a, (right - transform.c) / transform.a))
    rows = sorted(((top - transform.f) / transform.e, (bottom - transform.f) / transform.e))
    col0, row0 = max(math.floor(columns[0]) - MARGIN, 0), max(math.floor(rows[0]) - MARGIN, 0)
    col1, row1 = min(math.ceil(columns[1]) + MARGIN, shape[1]), min(math.ceil(rows[1]) + MARGIN, shape[0])
    return Window(row0, col0, row1 - row0, col1 - col0, shape)


def _source_index(image: xr.DataArray, crs, transform, window: Window) -> np.ndarray:
    """Flat index (int32) of the image's own pixel that each pixel of the common grid's ``window``
    takes (nearest neighbour, rioxarray's reproject onto the window's pixels of the grid), -1
    outside the image; flat (rows * cols,)."""
    from affine import Affine
    from rasterio.enums import Resampling

    ny, nx = image.sizes["y"], image.sizes["x"]
    if ny * nx >= 2**31 - 1:
        raise ParameterError(f"a scene of {ny} x {nx} pixels is too large for the common grid's int32 index")
    index = xr.DataArray(np.arange(ny * nx, dtype=np.int32).reshape(ny, nx), dims=("y", "x"),
                         coords={"y": image["y"].values, "x": image["x"].values})
    index = index.rio.write_crs(image.rio.crs).rio.write_transform(image.rio.transform()).rio.write_nodata(-1)
    moved = index.rio.reproject(crs, shape=(window.rows, window.cols),
                                transform=transform * Affine.translation(window.col0, window.row0),
                                resampling=Resampling.nearest, nodata=-1)
    return np.asarray(moved.values, dtype=np.int32).reshape(-1)


def common_grid(images: list[xr.DataArray]) -> CommonGrid:
    """The common grid of scenes on different grids (module docstring): the first image's CRS
    and pixel grid over the union of the images' extents, and each image's source pixels on it.

    Parameters
    ----------
    images : list of DataArray (band, y, x)
        Georeferenced images (rioxarray CRS and transform; numpy- or dask-backed: only their
        coordinates are used).

    Raises
    ------
    ParameterError
        An image without a CRS, or a rotated first image.
    """
    crs, transform, shape = _target(images)
    windows = tuple(_window(image, crs, transform, shape) for image in images)
    sources = tuple(_source_index(image, crs, transform, window) for image, window in zip(images, windows))
    return CommonGrid(shape, tuple((image.sizes["y"], image.sizes["x"]) for image in images), windows, sources)
