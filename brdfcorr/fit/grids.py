"""One common grid for scenes on different grids (overlapping flight lines), so that free levels
per pixel or patch (:mod:`brdfcorr.fit.within`) can be fitted where the lines share ground.

Each line of an airborne survey has its own grid (shifted, another resolution, another CRS). The
common grid is the **first scene's CRS and pixel grid** (its resolution and pixel edges) extended
over the **union** of the scenes' extents: the first scene's pixels are common-grid pixels
unchanged, and every other scene is resampled onto it by **nearest neighbour** (values kept as
they are: no blend of two classes, no azimuth averaged across 0/360 deg).

The resampling is rioxarray's (:meth:`rioxarray.raster_array.RasterArray.reproject`, GDAL's
warper), applied to one layer per scene only: the flat index of each of the scene's own pixels.
Reprojected by nearest neighbour, it says which source pixel each common-grid pixel takes
(:attr:`CommonGrid.sources`, -1 outside the scene). The class maps, the validity of the angles
and the cluster layers (already in memory for the sampler) are gathered through it, and the
reflectance and the angles are read lazily at the sampled pixels only, on the scenes' own
grids: no resampled cube is ever formed, so memory stays that of one integer layer per scene.

A common-grid pixel seen by a single scene carries no difference between views: it drops out of
a within fit (:func:`brdfcorr.fit.sampling.sample_classes` samples groups with two or more views).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from brdfcorr.errors import ParameterError

__all__ = ["CommonGrid", "common_grid"]

#: Tolerance [pixels] when the union's edges are snapped outwards to the first scene's pixel edges.
SNAP = 1e-6


@dataclass(frozen=True)
class CommonGrid:
    """The common grid (``shape`` (y, x)) and, per scene, the flat index into the scene's own
    grid (of ``scene_shapes``) of the pixel each common-grid pixel takes (``sources``, flat
    (ny * nx,), -1 where the scene does not cover it)."""

    shape: tuple[int, int]
    scene_shapes: tuple[tuple[int, int], ...]
    sources: tuple[np.ndarray, ...]

    def gather(self, scene: int, values: np.ndarray, fill) -> np.ndarray:
        """A scene's layer ``values`` (y, x on its own grid) on the common grid, ``fill`` where
        the scene does not cover it."""
        source = self.sources[scene]
        flat = np.asarray(values).reshape(-1)
        gathered = np.where(source >= 0, flat[np.maximum(source, 0)], fill)
        return gathered.reshape(self.shape)

    def source_pixels(self, scene: int, flat: np.ndarray) -> np.ndarray:
        """The flat indices into scene ``scene``'s own grid of common-grid pixels ``flat``."""
        return self.sources[scene][flat]


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

    return crs, transform @ Affine.translation(col0, row0), (row1 - row0, col1 - col0)


def _source_index(image: xr.DataArray, crs, transform, shape: tuple[int, int]) -> np.ndarray:
    """Flat index (int32) of the image's own pixel that each common-grid pixel takes (nearest
    neighbour, rioxarray's reproject), -1 outside the image; flat (ny * nx,)."""
    from rasterio.enums import Resampling

    ny, nx = image.sizes["y"], image.sizes["x"]
    if ny * nx >= 2**31 - 1:
        raise ParameterError(f"a scene of {ny} x {nx} pixels is too large for the common grid's int32 index")
    index = xr.DataArray(np.arange(ny * nx, dtype=np.int32).reshape(ny, nx), dims=("y", "x"),
                         coords={"y": image["y"].values, "x": image["x"].values})
    index = index.rio.write_crs(image.rio.crs).rio.write_transform(image.rio.transform()).rio.write_nodata(-1)
    moved = index.rio.reproject(crs, shape=shape, transform=transform, resampling=Resampling.nearest, nodata=-1)
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
    sources = tuple(_source_index(image, crs, transform, shape) for image in images)
    return CommonGrid(shape, tuple((image.sizes["y"], image.sizes["x"]) for image in images), sources)
