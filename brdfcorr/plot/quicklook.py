"""Before/after quicklook of a corrected scene (a chain's ``quicklook`` step).

:func:`quicklook_figure` draws decimated arrays it is given (no file access, no pyplot state):
the two images with one contrast stretch, nodata in its own colour, west and east marked on a
north-up image, and the across-track profile per class before and after.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from brdfcorr.plot._display import NODATA_COLOUR, NODATA_NAME, display_name, sun_side

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["quicklook_figure", "band_label"]


def quicklook_figure(before: np.ndarray, after: np.ndarray, *, class_map: np.ndarray | None = None,
                     band_label: str = "", percentiles=(1.0, 99.9), title: str = "",
                     class_names: Mapping[int, str] | None = None, max_classes: int = 6,
                     north_up: bool = False, sun_azimuth: float | None = None) -> Figure:
    """Input and corrected image with the *same* contrast stretch, and the across-track profile
    (column means relative to the class mean) per class before and after.

    Parameters
    ----------
    before, after : ndarray, (band, y, x)
        Input and corrected reflectance (one or three bands, nodata NaN) on the same grid.
    class_map : ndarray, (y, x), optional
        Class ids (0 or NaN: no class) for per-class profiles (the ``max_classes`` most frequent
        classes); without it, or on another grid, one profile of all valid pixels.
    band_label : str
        What the bands are (``"R, G, B = 665, 560, 490 nm"``), for the titles.
    percentiles : (float, float)
        Stretch [%] per band of both images together, applied to both panels.
    title : str
        Prefix of the panel titles (the scene name).
    class_names : mapping of int to str, optional
        Names for the legend (the parameter table's), else "class ID".
    max_classes : int, default 6
        Most profiles drawn.
    north_up : bool
        Columns run west to east (the image's transform): the panels and the profile say so.
    sun_azimuth : float, optional
        Azimuth [deg, clockwise from north] towards the sun: on a north-up image an arrow points
        to the sun, and the profile says which side looks into forward scattering (the sun's side:
        the sensor looks away from the sun there) and which into backscatter (the hotspot side).
    """
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(12, 8), layout="constrained")
    grid = figure.add_gridspec(2, 2, height_ratios=(3, 2))
    display = _stretch(np.concatenate([before, after], axis=2), percentiles)
    for column, (cube, name) in enumerate(((before, "before"), (after, "after (BRDF-normalized)"))):
        axis = figure.add_subplot(grid[0, column])
        axis.imshow(display(cube), cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        axis.set_title(f"{title} {name}".strip())
        axis.set_xticks([])
        axis.set_yticks([])
        if north_up:
            axis.set_xlabel("west  ←  →  east")
            if sun_azimuth is not None:
                _sun_arrow(axis, sun_azimuth)
    axis = figure.add_subplot(grid[1, :])
    _draw_profiles(axis, np.nanmean(before, axis=0), np.nanmean(after, axis=0), class_map, class_names or {},
                   max_classes)
    axis.set_xlabel(_profile_label(north_up, sun_azimuth))
    axis.set_ylabel("column mean / class mean [-]")
    axis.set_title("across-track profile, mean of the bands shown (dashed: before, solid: after)", fontsize="medium")
    figure.legend(*axis.get_legend_handles_labels(), loc="outside lower center", ncols=6, fontsize="small")
    notes = [band_label] if band_label else []
    figure.suptitle("; ".join(notes + [f"nodata: {NODATA_NAME}", "same stretch in both images"]),
                    fontsize="small", color="0.3")
    return figure


def _profile_label(north_up: bool, sun_azimuth: float | None) -> str:
    if not north_up:
        return "column (across track)"
    if sun_azimuth is None:
        return "column (across track, west → east)"
    side = sun_side(sun_azimuth)
    other = "west" if side == "east" else "east"
    return (f"column (across track, west → east); sun from the {side} (azimuth {sun_azimuth:.0f}°): "
            f"{side} side forward scattering, {other} side backscatter")


def _sun_arrow(axis, azimuth: float) -> None:
    """An arrow from the panel's top-left corner towards the sun (north up, east right)."""
    east, north = np.sin(np.radians(azimuth)), np.cos(np.radians(azimuth))
    start = (0.09, 0.88)
    axis.annotate("", xy=(start[0] + 0.07 * east, start[1] + 0.07 * north), xytext=start,
                  xycoords="axes fraction", arrowprops={"arrowstyle": "->", "color": "gold", "lw": 2})
    axis.text(start[0], start[1] - 0.06, f"sun {azimuth:.0f}°", transform=axis.transAxes, color="gold",
              ha="center", va="top", fontsize="small")


def _draw_profiles(axis, before: np.ndarray, after: np.ndarray, class_map, names, most: int) -> None:
    columns = np.arange(before.shape[1])
    for index, (name, mask) in enumerate(_profile_groups(before, class_map, names, most)):
        for brightness, style, when in ((before, "--", "before"), (after, "-", "after")):
            axis.plot(columns, _relative_profile(brightness, mask), style, color=f"C{index}", label=f"{name} {when}")
    axis.axhline(1.0, color="0.6", linewidth=0.8)


def _stretch(reference: np.ndarray, percentiles):
    """A function cube -> displayable image in [0, 1]: the percentile stretch of ``reference``
    per band, nodata in :data:`NODATA_COLOUR`."""
    low = np.nanpercentile(reference, percentiles[0], axis=(1, 2), keepdims=True)
    high = np.nanpercentile(reference, percentiles[1], axis=(1, 2), keepdims=True)
    span = np.where(high > low, high - low, 1.0)

    def display(cube: np.ndarray) -> np.ndarray:
        scaled = np.clip((cube - low) / span, 0.0, 1.0)
        rgb = np.moveaxis(scaled, 0, -1) if len(cube) == 3 else np.repeat(scaled[0][..., None], 3, axis=-1)
        missing = np.isnan(cube).any(axis=0)
        rgb[missing] = NODATA_COLOUR
        return rgb

    return display


def _profile_groups(brightness: np.ndarray, class_map: np.ndarray | None, names: Mapping[int, str],
                    most: int) -> list[tuple[str, np.ndarray]]:
    """(label, pixel mask) of the profiles: the ``most`` most frequent classes, else all pixels."""
    groups = [("all pixels", np.isfinite(brightness))]
    if class_map is None or class_map.shape != brightness.shape:
        return groups
    ids, counts = np.unique(class_map[np.isfinite(class_map) & (class_map > 0)], return_counts=True)
    top = ids[np.argsort(counts)[::-1][:most]]
    return [(display_name(names.get(int(i), f"class {int(i)}")), class_map == i) for i in sorted(top)] or groups


def _relative_profile(cube: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Column means of the masked pixels over their overall mean [-]."""
    values = np.where(mask, cube, np.nan)
    with warnings.catch_warnings():  # columns without the class: NaN, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        profile = np.nanmean(values, axis=0)
        return profile / np.nanmean(values)


def band_label(bands: Sequence[int], wavelengths: Sequence[float] | None) -> str:
    """``"R, G, B = 665, 560, 490 nm"`` (or ``"bands 3, 2, 1"``, ``"band 4, 865 nm"``) for 1-based ``bands``."""
    names = "R, G, B" if len(bands) == 3 else "band"
    if wavelengths is not None:
        return f"{names} = {', '.join(f'{wavelengths[b - 1]:g}' for b in bands)} nm"
    return f"{'bands' if len(bands) > 1 else 'band'} {', '.join(map(str, bands))}"
