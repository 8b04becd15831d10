"""Before/after quicklook of a corrected scene (a chain's ``quicklook`` step).

:func:`quicklook_figure` draws decimated arrays (no file access, no pyplot state);
:func:`write_quicklook` reads the rasters small with GDAL's resampling (:func:`read_small`),
draws them and writes the PNG atomically.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import rasterio
from matplotlib.figure import Figure
from rasterio.enums import Resampling

from brdfcorr.errors import InputError
from brdfcorr.io.files import atomic_path

__all__ = ["quicklook_figure", "read_small", "write_quicklook"]


def read_small(path, bands: Sequence[int], max_size: int, average: bool = True) -> np.ndarray:
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

    Returns
    -------
    ndarray of float64, (band, y, x)
        Nodata as NaN.
    """
    with rasterio.open(path) as dataset:
        for band in bands:
            if band > dataset.count:
                raise InputError(f"steps.quicklook.bands: band {band} does not exist in {path} ({dataset.count} bands)")
        scale = max(1.0, max(dataset.height, dataset.width) / max_size)
        shape = (len(bands), max(1, round(dataset.height / scale)), max(1, round(dataset.width / scale)))
        data = dataset.read(list(bands), out_shape=shape, masked=True,
                            resampling=Resampling.average if average else Resampling.nearest)
    return np.ma.filled(data.astype(np.float64), np.nan)


def quicklook_figure(before: np.ndarray, after: np.ndarray, *, class_map: np.ndarray | None = None,
                     bands: Sequence[int] = (3, 2, 1), percentiles=(2.0, 98.0), title: str = "",
                     class_names: Mapping[int, str] | None = None, max_classes: int = 6) -> Figure:
    """Input and corrected image with the *same* contrast stretch, and the across-track profile
    (column means relative to the class mean) per class before and after.

    Parameters
    ----------
    before, after : ndarray, (band, y, x)
        Input and corrected reflectance (one or three bands, nodata NaN) on the same grid.
    class_map : ndarray, (y, x), optional
        Class ids (0 or NaN: no class) for per-class profiles (the ``max_classes`` most frequent
        classes); without it, or on another grid, one profile of all valid pixels.
    bands : sequence of int
        The band numbers shown (labels only).
    percentiles : (float, float)
        Stretch [%] of the input image, per band, applied to both panels.
    title : str
        Prefix of the panel titles (the scene name).
    class_names : mapping of int to str, optional
        Names for the legend (the parameter table's), else "class ID".
    max_classes : int, default 6
        Most profiles drawn.
    """
    figure = Figure(figsize=(12, 7.5), layout="constrained")
    grid = figure.add_gridspec(2, 2, height_ratios=(3, 2))
    display = _stretch(before, percentiles)
    for column, (cube, name) in enumerate(((before, "before"), (after, "after (BRDF-normalized)"))):
        axis = figure.add_subplot(grid[0, column])
        axis.imshow(display(cube), cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        axis.set_title(f"{title} {name}".strip())
        axis.set_xticks([])
        axis.set_yticks([])
    brightness_before, brightness_after = np.nanmean(before, axis=0), np.nanmean(after, axis=0)
    axis = figure.add_subplot(grid[1, :])
    columns = np.arange(brightness_before.shape[1])
    groups = _profile_groups(brightness_before, class_map, class_names or {}, max_classes)
    for index, (name, mask) in enumerate(groups):
        for cube, style, when in ((brightness_before, "--", "before"), (brightness_after, "-", "after")):
            axis.plot(columns, _relative_profile(cube, mask), style, color=f"C{index}", label=f"{name} {when}")
    axis.axhline(1.0, color="0.6", linewidth=0.8)
    axis.set_xlabel("column (across track)")
    axis.set_ylabel("column mean / class mean [-]")
    label = "bands " + ",".join(map(str, bands))
    axis.set_title(f"across-track profile ({label}; dashed: before, solid: after)")
    axis.legend(ncols=3, fontsize="small")
    return figure


def write_quicklook(image, corrected, target, *, classes=None, bands=(3, 2, 1), percentiles=(2.0, 98.0),
                    max_size: int = 800, title: str = "", class_names: Mapping[int, str] | None = None) -> Path:
    """Write the before/after PNG of :func:`quicklook_figure` for an input and corrected raster.

    Parameters
    ----------
    image, corrected : path-like
        Input and corrected rasters (same grid).
    target : path-like
        PNG to write (atomically).
    classes : path-like, optional
        Class map for per-class profiles (the most frequent classes, named by ``class_names``);
        without it one profile of all valid pixels.
    bands : sequence of int
        1-based bands for red, green, blue, or one band (grey).
    percentiles : (float, float)
        Stretch [%] of the input image, per band, applied to both panels.
    max_size : int
        Longest side of the panels [pixels].
    title : str
        Prefix of the panel titles.
    """
    bands = list(bands)
    before = read_small(Path(image), bands, max_size)
    after = read_small(Path(corrected), bands, max_size)
    class_map = None if classes is None else read_small(Path(classes), [1], max_size, average=False)[0]
    figure = quicklook_figure(before, after, class_map=class_map, bands=bands, percentiles=percentiles, title=title,
                              class_names=class_names)
    target = Path(target)
    with atomic_path(target) as temporary:
        figure.savefig(temporary, dpi=90, format="png")
    return target


def _stretch(reference: np.ndarray, percentiles):
    """A function cube -> displayable image in [0, 1]: the percentile stretch of ``reference``."""
    low = np.nanpercentile(reference, percentiles[0], axis=(1, 2), keepdims=True)
    high = np.nanpercentile(reference, percentiles[1], axis=(1, 2), keepdims=True)
    span = np.where(high > low, high - low, 1.0)

    def display(cube: np.ndarray) -> np.ndarray:
        rgb = np.clip((cube - low) / span, 0.0, 1.0)
        rgb = np.where(np.isnan(rgb), 1.0, rgb)  # nodata shown white
        return np.moveaxis(rgb, 0, -1) if len(cube) == 3 else rgb[0]

    return display


def _profile_groups(brightness: np.ndarray, class_map: np.ndarray | None, names: Mapping[int, str],
                    most: int) -> list[tuple[str, np.ndarray]]:
    """(label, pixel mask) of the profiles: the ``most`` most frequent classes, else all pixels."""
    groups = [("all pixels", np.isfinite(brightness))]
    if class_map is None or class_map.shape != brightness.shape:
        return groups
    ids, counts = np.unique(class_map[np.isfinite(class_map) & (class_map > 0)], return_counts=True)
    top = ids[np.argsort(counts)[::-1][:most]]
    return [(names.get(int(i), f"class {int(i)}"), class_map == i) for i in sorted(top)] or groups


def _relative_profile(cube: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Column means of the masked pixels over their overall mean [-]."""
    values = np.where(mask, cube, np.nan)
    with warnings.catch_warnings():  # columns without the class: NaN, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        profile = np.nanmean(values, axis=0)
        return profile / np.nanmean(values)
