"""Figures of BRDF models: principal-plane and azimuthal cuts, in the layout of paper 003.

Every function returns a :class:`matplotlib.figure.Figure`; saving is the caller's choice.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from brdfcorr.models import get_model
from brdfcorr.models.materials import Material
from brdfcorr.plot._display import display_name, representative_bands

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: The illumination geometries of paper 003, fig. 3: (theta_i, theta_r) of each azimuthal cut [deg].
AZIMUTH_CUTS = ((30.0, 30.0), (50.0, 50.0), (65.0, 70.0))
#: Illumination zeniths of the principal-plane cuts [deg].
PRINCIPAL_PLANE_ZENITHS = (30.0, 50.0, 65.0)


def principal_plane(theta_r_signed):
    """Split signed view zeniths into (theta_r, phi): positive is forward (phi = 180) [deg]."""
    theta_r_signed = np.asarray(theta_r_signed, dtype=float)
    return np.abs(theta_r_signed), np.where(theta_r_signed >= 0, 180.0, 0.0)


def plot_materials(materials: Sequence[Material], max_zenith: float = 80.0) -> Figure:
    """BRDF of materials in the principal plane (top row) and in azimuth (bottom row).

    Top: BRDF [sr^-1] against signed view zenith (positive = forward scattering, phi = 180 deg;
    negative = backward, phi = 0) for theta_i = 30, 50, 65 deg, as paper 003 fig. 2.
    Bottom: BRDF against relative azimuth 90-180 deg at the geometries of paper 003 fig. 3.
    """
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(13, 7.5), layout="constrained")
    axes = figure.subplots(2, 3)
    view = np.linspace(-max_zenith, max_zenith, 321)
    theta_r, phi = principal_plane(view)
    azimuth = np.linspace(90.0, 180.0, 181)
    for axis, theta_i in zip(axes[0], PRINCIPAL_PLANE_ZENITHS):
        for material in materials:
            axis.semilogy(view, material.brdf(theta_i, theta_r, phi), label=material.label)
        axis.axvline(theta_i, color="0.6", lw=0.8, ls=":")
        axis.set(
            title=f"principal plane, θi = {theta_i:g}°",
            xlabel="view zenith θr [°] (negative: backward, φ = 0°)",
            ylabel="BRDF [sr⁻¹]",
        )
    for axis, (theta_i, theta_r_cut) in zip(axes[1], AZIMUTH_CUTS):
        for material in materials:
            axis.semilogy(azimuth, material.brdf(theta_i, theta_r_cut, azimuth), label=material.label)
        axis.set(
            title=f"azimuth, θi = {theta_i:g}°, θr = {theta_r_cut:g}°",
            xlabel="relative azimuth φ [°] (180 = forward)",
            ylabel="BRDF [sr⁻¹]",
        )
    # Below the panels, one row: on the right it covered the last panel's view-zenith label, which
    # is wider than its axes (the layout reserves room for the legend beside the axes, not the label).
    figure.legend(*axes[0, 0].get_legend_handles_labels(), loc="outside lower center", ncols=min(len(materials), 5),
                  fontsize="small")
    figure.suptitle(
        "Torrance–Sparrow model with the fits of Meister et al. (2000), Table 1 (550 nm)"
    )
    return figure


def sun_zenith_groups(theta_i, gap: float = 1.0, max_groups: int = 6) -> list[tuple[np.ndarray, str]]:
    """The samples of each sun zenith, for a figure: (indices, label suffix) per group of sun
    zeniths [deg] separated by more than ``gap`` degrees (a line's sun varies less along it; two
    lines flown at other times are two groups). One group, with an empty suffix, where all share a
    sun or there are more than ``max_groups`` (a composite of many orbits)."""
    theta_i = np.asarray(theta_i, dtype=float)
    order = np.argsort(theta_i, kind="stable")
    breaks = np.flatnonzero(np.diff(theta_i[order]) > gap) + 1
    if breaks.size == 0 or breaks.size >= max_groups:
        return [(np.arange(theta_i.size), "")]
    groups = []
    for members in np.split(order, breaks):
        low, high = theta_i[members].min(), theta_i[members].max()
        sun = f"{low:.0f}°" if round(low) == round(high) else f"{low:.0f}–{high:.0f}°"
        groups.append((np.sort(members), f", sun zenith {sun}"))
    return groups


def plot_class_fit(fit, samples, wavelengths=None, max_panels: int = 4) -> Figure:
    """Observed and modelled reflectance of one class against signed view zenith.

    Parameters
    ----------
    fit : brdfcorr.fit.classes.ClassFit
        The class's fit (per-band parameters).
    samples : brdfcorr.fit.classes.ClassSamples
        The class's samples (BRDF = reflectance / pi).
    wavelengths : sequence of float, optional
        Band centres [nm] for the panel titles.
    max_panels : int, default 4
        Number of bands shown: with wavelengths those nearest the blue, green, red, NIR and SWIR
        centres the image has (:func:`brdfcorr.plot._display.representative_bands`; not the noisy
        edge bands of an imaging spectrometer), else bands evenly spread.

    Notes
    -----
    The view zenith is signed by the side of the sun: positive for forward scattering
    (relative azimuth > 90 deg), negative for backward scattering, so that the across-track
    brightness gradient of a wide field-of-view line reads left to right. Samples of lines flown
    under different suns (:func:`sun_zenith_groups`) are drawn in one colour per sun, with the
    model's values labelled per line.
    """
    model = get_model(fit.model)
    n_bands = samples.brdf.shape[1]
    bands = representative_bands(wavelengths, n_bands, max_panels)
    signed = np.where(samples.phi > 90.0, samples.theta_r, -samples.theta_r)
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(4.2 * len(bands), 3.8), layout="constrained")
    axes = np.atleast_1d(figure.subplots(1, len(bands), sharey=False))
    groups = sun_zenith_groups(samples.theta_i)
    for axis, band in zip(axes, bands):
        params = {name: values[band] for name, values in fit.params.items()}
        modelled = np.pi * model(samples.theta_i, samples.theta_r, samples.phi, **params)
        # One colour per sun zenith (a line, or lines flown at the same time of day): each line's
        # model is its own curve, and its observations are drawn in its colour, lighter.
        for number, (members, sun) in enumerate(groups):
            color = f"C{number}" if len(groups) > 1 else "C3"
            axis.plot(signed[members], np.pi * samples.brdf[members, band], ".", ms=2, color=color, alpha=0.3,
                      label=f"observed{sun}")
            axis.plot(signed[members], modelled[members], ".", ms=2, color=color, label=f"{fit.model} fit{sun}")
        label = f"{wavelengths[band]:g} nm" if wavelengths is not None else f"band {band + 1}"
        axis.set(
            title=f"{label}: R² = {fit.r2[band]:.2f}",
            xlabel="view zenith θr [°] (+ forward, − backward)",
            ylabel="reflectance factor [-]",
        )
    figure.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=min(6, 2 * len(groups)),
                  fontsize="small", markerscale=4)
    figure.suptitle(
        f"class {fit.class_id} ({display_name(fit.name)}): {fit.status}, N = {fit.n_samples}, "
        f"view zenith spread {fit.vza_spread:.0f}°"
    )
    return figure
