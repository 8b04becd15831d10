"""Figures of ``brdfcorr assess`` (:mod:`brdfcorr.analysis.assess`): did the correction work?

:func:`profile_figure` draws the across-track profiles per class before and after and the
relative slope per class and band; :func:`overlap_figure` the difference of two overlapping lines
(histograms and maps). Both return matplotlib Figures (no pyplot state, Agg);
:func:`write_assessment_figures` writes them as PNGs, atomically.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from brdfcorr.errors import InputError
from brdfcorr.io.files import atomic_path
from brdfcorr.plot._display import display_name

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.figure import Figure

__all__ = ["profile_figure", "overlap_figure", "figure_paths", "write_assessment_figures", "default_band"]


class Assessment(Protocol):
    """What the figures read of an assessment (:class:`brdfcorr.tasks.assess.Assessment` has it; plot
    sits below tasks and does not import it)."""

    @property
    def view(self) -> xr.Dataset:
        """:func:`brdfcorr.analysis.view_angles.assess_view_angles` of the scene."""

    @property
    def overlap(self) -> xr.Dataset | None:
        """:func:`brdfcorr.analysis.overlap.assess_overlap` with the other line, or None."""


def default_band(dataset: xr.Dataset) -> int:
    """Index of the band shown by default: the one nearest 660 nm (red) where wavelengths are
    known, else the middle band."""
    if "wavelength" in dataset.coords:
        return int(np.argmin(np.abs(dataset["wavelength"].values - 660.0)))
    return dataset.sizes["band"] // 2


def _band_label(dataset: xr.Dataset, index: int) -> str:
    number = int(dataset["band"].values[index])
    if "wavelength" in dataset.coords:
        return f"band {number}, {float(dataset['wavelength'].values[index]):g} nm"
    return f"band {number}"


def profile_figure(view: xr.Dataset, *, band: int | None = None, title: str = "") -> Figure:
    """Across-track profiles per class before (dashed) and after (solid), and the relative slope
    per class and band.

    Parameters
    ----------
    view : xarray.Dataset
        :func:`brdfcorr.analysis.assess.assess_view_angles`.
    band : int, optional
        0-based index of the band of the profiles (default :func:`default_band`).
    title : str
        Prefix of the panel titles (the scene name).

    Notes
    -----
    Left: mean reflectance per bin of signed view zenith over the class mean of the same stage
    [-], so that 1 is a flat profile. Right: the slope relative to the class mean [%/10 deg]
    against wavelength [nm] (or band number); 0 is a correction that removed the view-angle
    signal.
    """
    band = default_band(view) if band is None else int(band)
    if not 0 <= band < view.sizes["band"]:
        raise InputError(f"band index {band} is outside 0..{view.sizes['band'] - 1}")
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(13, 5.5), layout="constrained")
    left, right = figure.subplots(1, 2, width_ratios=(3, 2))
    centres = view["vza_bin"].values
    spectral = "wavelength" in view.coords
    x_bands = view["wavelength"].values if spectral else view["band"].values
    for index in range(view.sizes["class"]):
        one = view.isel({"class": index})
        name = display_name(str(one["class_name"].values))
        for stage, style in (("before", "--"), ("after", "-")):
            values = one.sel(stage=stage)
            relative = values["profile"].isel(band=band).values / float(values["mean"].isel(band=band))
            # Markers: a bin between empty ones (a composite's few orbits) is a point, not a gap.
            left.plot(centres, relative, style, marker=".", markersize=4, color=f"C{index}", label=f"{name} {stage}")
            # The slope's 1-sigma (cluster-robust, as the report and the table print it) as bars.
            sigma = values["relative_slope_error"].values if "relative_slope_error" in values else None
            right.errorbar(x_bands, values["relative_slope"].values, yerr=sigma, linestyle=style, marker=".",
                           color=f"C{index}", capsize=2, elinewidth=0.8, label=f"{name} {stage}")
    positive, negative = view.attrs.get("positive_side", ""), view.attrs.get("negative_side", "")
    left.axhline(1.0, color="0.6", linewidth=0.8)
    left.axvline(0.0, color="0.8", linewidth=0.8)
    left.set_xlabel("signed view zenith [deg]")
    left.set_ylabel("bin mean / class mean [-]")
    left.set_title(f"{title} across-track profile ({_band_label(view, band)}; dashed: before, solid: after)".strip(),
                   fontsize="medium")
    left.text(0.99, 0.02, f"+: {positive.split(':')[0]}\n−: {negative.split(':')[0]}", transform=left.transAxes,
              ha="right", va="bottom", fontsize="small", color="0.3")
    figure.legend(*left.get_legend_handles_labels(), loc="outside lower center", ncols=min(6, 2 * view.sizes["class"]),
                  fontsize="small")
    right.axhline(0.0, color="0.6", linewidth=0.8)
    right.set_xlabel("wavelength [nm]" if spectral else "band")
    right.set_ylabel("slope / class mean [%/10 deg]")
    bars = "; bars: ±1σ" if "relative_slope_error" in view else ""
    right.set_title(f"{title} view-angle slope per class and band{bars}".strip(), fontsize="medium")
    return figure


def overlap_figure(overlap: xr.Dataset, *, title: str = "") -> Figure:
    """The band-mean difference of two overlapping lines (other − this) before and after:
    histograms, and maps with one diverging colour scale.

    Parameters
    ----------
    overlap : xarray.Dataset
        :func:`brdfcorr.analysis.assess.assess_overlap`.
    title : str
        Prefix of the titles.
    """
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(13, 4.5), layout="constrained")
    histogram_axis, *map_axes = figure.subplots(1, 3, width_ratios=(2, 1.5, 1.5))
    edges = overlap["difference_bin_edges"].values
    for stage, style in (("before", "--"), ("after", "-")):
        counts = overlap["histogram"].sel(stage=stage).values
        median = float(np.nanmedian(overlap["relative_rmse"].sel(stage=stage).values))
        histogram_axis.stairs(counts, np.append(edges[:, 0], edges[-1, 1]), linestyle=style,
                              label=f"{stage} (median relative RMSE {median:.2f} %)")
    histogram_axis.set_xlabel("band-mean difference, other − this [reflectance, 1]")
    histogram_axis.set_ylabel("pixels")
    histogram_axis.set_title(f"{title} overlap difference ({int(overlap['pixels'])} pixels)".strip(),
                             fontsize="medium")
    histogram_axis.legend(fontsize="small")
    maps = overlap["difference_map"].values
    reach = float(np.nanmax(np.abs(maps))) if np.isfinite(maps).any() else 1.0
    norm = TwoSlopeNorm(0.0, -reach or -1.0, reach or 1.0)
    image = None
    for axis, stage in zip(map_axes, ("before", "after"), strict=True):
        image = axis.imshow(overlap["difference_map"].sel(stage=stage).values, cmap="RdBu_r", norm=norm,
                            interpolation="nearest")
        axis.set_title(f"difference {stage}", fontsize="medium")
        axis.set_xticks([])
        axis.set_yticks([])
    figure.colorbar(image, ax=map_axes, label="other − this [reflectance, 1]", shrink=0.8)
    return figure


def figure_paths(directory: str | os.PathLike, *, prefix: str = "assess", overlap: bool = False) -> list[Path]:
    """The PNGs :func:`write_assessment_figures` writes: ``{prefix}_profiles.png`` and, with an
    overlap, ``{prefix}_overlap.png`` (for an output guard before anything is computed)."""
    directory = Path(directory)
    return [directory / f"{prefix}_profiles.png"] + [directory / f"{prefix}_overlap.png"] * bool(overlap)


def write_assessment_figures(assessment: Assessment, directory: str | os.PathLike, *, prefix: str = "assess",
                             band: int | None = None, dpi: int = 100, title: str = "") -> list[Path]:
    """Write ``{prefix}_profiles.png`` (:func:`profile_figure`) and, with an overlap,
    ``{prefix}_overlap.png`` (:func:`overlap_figure`) into ``directory`` (created), each
    atomically; ``title`` (the scene name) heads their panels, so that a figure read alone says
    which scene it shows. Returns the paths written."""
    Path(directory).mkdir(parents=True, exist_ok=True)
    figures = [profile_figure(assessment.view, band=band, title=title)]
    if assessment.overlap is not None:
        figures.append(overlap_figure(assessment.overlap, title=title))
    targets = figure_paths(directory, prefix=prefix, overlap=assessment.overlap is not None)
    written = []
    for target, figure in zip(targets, figures, strict=True):
        with atomic_path(target) as temporary:
            figure.savefig(temporary, dpi=dpi, format="png")
        written.append(target)
    return written
