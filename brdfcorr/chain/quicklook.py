"""The chain's ``quicklook`` step: read an input and its corrected image small, draw them
(:func:`brdfcorr.plot.quicklook.quicklook_figure`) and write the PNG atomically."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from brdfcorr.io import rasters
from brdfcorr.io.files import atomic_path
from brdfcorr.io.overview import raster_summary, read_small
from brdfcorr.io.wavelengths import file_wavelengths
from brdfcorr.plot._display import is_north_up, scene_sun_azimuth, true_colour_bands
from brdfcorr.plot.quicklook import band_label, quicklook_figure

__all__ = ["write_quicklook"]


def write_quicklook(image: str | os.PathLike, corrected: str | os.PathLike, target: str | os.PathLike, *,
                    classes: str | os.PathLike | None = None, bands: Sequence[int] | None = None,
                    percentiles=(1.0, 99.9), max_size: int = 800, title: str = "",
                    class_names: Mapping[int, str] | None = None, prepare_classes: Callable | None = None) -> Path:
    """Write the before/after PNG of :func:`~brdfcorr.plot.quicklook.quicklook_figure`.

    Parameters
    ----------
    image, corrected : path-like
        Input and corrected rasters (same grid).
    target : path-like
        PNG to write (atomically).
    classes : path-like, optional
        Class map for per-class profiles (the most frequent classes, named by ``class_names``);
        without it one profile of all valid pixels.
    bands : sequence of int, optional
        1-based bands for red, green, blue, or one band (grey). Default: by wavelength
        (:func:`brdfcorr.plot._display.true_colour_bands`, from the corrected image's tags).
    percentiles : (float, float)
        Stretch [%] per band of both images together, applied to both panels.
    max_size : int
        Longest side of the panels [pixels].
    title : str
        Prefix of the panel titles.
    class_names : mapping of int to str, optional
        Names of the classes in the legend (the parameter table's).
    prepare_classes : callable, optional
        ``prepare_classes(classes, image)`` -> the class map on the image grid, as the correct step
        prepared it (:func:`brdfcorr.tasks.classmaps.class_preparation`: an aligned land-cover
        map, its codes remapped): the profiles are those of its classes, not of the file's codes
        on its own grid.
    """
    count, transform, tags = raster_summary(corrected)
    wavelengths = file_wavelengths(corrected)
    bands = list(bands) if bands else true_colour_bands(wavelengths, count)
    before = _stored_as_read(read_small(image, bands, max_size), tags, bands)
    after = read_small(corrected, bands, max_size, scaled=True)  # an output of the input's type: scaled
    class_map = None if classes is None else _small_class_map(image, classes, before.shape[1:], max_size,
                                                               prepare_classes)
    figure = quicklook_figure(before, after, class_map=class_map, band_label=band_label(bands, wavelengths),
                              percentiles=percentiles, title=title, class_names=class_names,
                              north_up=is_north_up(transform), sun_azimuth=scene_sun_azimuth(tags))
    target = Path(target)
    with atomic_path(target) as temporary:
        figure.savefig(temporary, dpi=90, format="png")
    return target


def _stored_as_read(values: np.ndarray, tags: Mapping[str, str], bands: Sequence[int]) -> np.ndarray:
    """The input's stored ``values`` (band, y, x) of ``bands`` (1-based) as the reflectance factors
    the correction read: times the scale plus the offset the corrected output's tags record
    (``brdf_input_scale``, ``brdf_input_offset``: one value, or one per band), so that both panels
    share one stretch in one unit (scaled counts beside reflectance left the "after" panel black)."""
    def per_band(key: str, default: float) -> np.ndarray:
        text = tags.get(key)
        values_of_bands = np.array([float(v) for v in text.split(",")]) if text else np.array([default])
        return values_of_bands[[band - 1 for band in bands]] if values_of_bands.size > 1 else values_of_bands

    return values * per_band("brdf_input_scale", 1.0)[:, None, None] + per_band("brdf_input_offset", 0.0)[:, None, None]


def _small_class_map(image, classes, shape: tuple[int, int], max_size: int,
                     prepare: Callable | None) -> np.ndarray:
    """The class map decimated to ``shape`` (the panels'), nearest neighbour: the file's own
    (:func:`brdfcorr.io.overview.read_small`), or ``prepare(classes, image)`` sampled at the
    centres of the panels' pixels (an aligned map is computed there only, chunk by chunk)."""
    if prepare is None:
        return read_small(classes, [1], max_size, average=False)[0]
    reflectance = rasters.open_image(image)
    prepared = prepare(rasters.open_classes(classes, chunks=rasters.auto_chunk(image)), reflectance)
    rows, columns = (((np.arange(n) + 0.5) * size / n).astype(int)
                     for n, size in zip(shape, (prepared.sizes["y"], prepared.sizes["x"])))
    small = prepared.isel(y=rows, x=columns).values.astype(np.float64)
    return np.where(small > 0, small, np.nan)  # 0: no class
