"""Figures of the papers' analyses: paper 000 fig. 2, polar BRDF plots, azimuthal widths.

Every function returns a :class:`matplotlib.figure.Figure`; saving is the caller's choice.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from brdfcorr.analysis.papers import WIDTH_GEOMETRIES
from brdfcorr.analysis.simulate import NORMALIZATION_GEOMETRY, simulate_vcavity
from brdfcorr.models import empirical, torrance_sparrow
from brdfcorr.models.materials import Material

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FIGURE2_ROUGHNESSES", "FIGURE2_CUTS", "plot_figure2", "plot_polar", "plot_azimuthal_widths"]

#: Roughnesses c = w of the three columns of paper 000, fig. 2 [deg^-1].
FIGURE2_ROUGHNESSES = (0.01, 0.05, 0.15)
#: (theta_i, phi) of the four rows of paper 000, fig. 2 [deg].
FIGURE2_CUTS = ((10.0, 180.0), (45.0, 180.0), (75.0, 180.0), (45.0, 150.0))


def _normalized(function):
    return lambda ti, tr, ph: function(ti, tr, ph) / function(*NORMALIZATION_GEOMETRY)


def plot_figure2(
    simulated_view: Sequence[float] = tuple(np.arange(0.0, 86.0, 5.0)),
    roughnesses: Sequence[float] = FIGURE2_ROUGHNESSES,
    **simulation,
) -> Figure:
    """Paper 000, fig. 2: TS model, V-cavity simulation and empirical model, normalized.

    Parameters
    ----------
    simulated_view : sequence of float
        View zeniths [deg] at which the simulation is run (the rhombs of the paper).
    roughnesses : sequence of float
        c = w [deg^-1] of the columns (paper: 0.01, 0.05, 0.15).
    **simulation
        Settings passed to :func:`brdfcorr.analysis.simulate.simulate_vcavity` (``grid``, a
        :class:`~brdfcorr.analysis.simulate.FacetGrid`; ``sigma``, ...).

    Notes
    -----
    Rows: principal plane (phi = 180) at theta_i = 10, 45, 75 deg, and phi = 150 at 45 deg. All
    curves are divided by their value at theta_i = theta_r = 45, phi = 180 deg. TS with constant
    Fresnel reflectance (n very large), the empirical model (paper 000 eq. 5) with b = 1 rad^-4 and
    c = w.
    """
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(12, 12), layout="constrained")
    axes = figure.subplots(len(FIGURE2_CUTS), len(roughnesses), squeeze=False)
    view = np.linspace(0.0, 89.0, 357)
    simulated_view = np.asarray(simulated_view, dtype=float)
    for column, w in enumerate(roughnesses):
        ts = _normalized(lambda ti, tr, ph, w=w: torrance_sparrow(ti, tr, ph, 0.0, 1.0, w, 1e9, 0.0))
        emp = _normalized(lambda ti, tr, ph, w=w: empirical(ti, tr, ph, a=1.0, b=1.0, c=w))
        for row, (theta_i, phi) in enumerate(FIGURE2_CUTS):
            axis = axes[row, column]
            axis.plot(view, ts(theta_i, view, phi), "k-", lw=1.2, label="TS model")
            axis.plot(
                simulated_view,
                simulate_vcavity(theta_i, simulated_view, phi, w, normalize=True, **simulation),
                "D", ms=4, mfc="none", color="tab:blue", label="V-cavity simulation",
            )
            axis.plot(simulated_view, emp(theta_i, simulated_view, phi), "x", color="tab:red", label="empirical")
            axis.set(title=f"c = {w:g}°⁻¹, θi = {theta_i:g}°, φ = {phi:g}°", xlim=(0, 90))
            if row == len(FIGURE2_CUTS) - 1:
                axis.set_xlabel("view zenith θr [°]")
            if column == 0:
                axis.set_ylabel("BRDF / BRDF(45°, 45°, 180°)")
    axes[0, 0].legend(fontsize="small")
    figure.suptitle("Specular peak: TS model, V-cavity simulation, empirical model (Meister et al. 1998, fig. 2)")
    return figure


def plot_polar(material: Material, zeniths: Sequence[float] = (30.0, 50.0, 65.0), max_zenith: float = 85.0) -> Figure:
    """Polar plots of a material's BRDF over the view hemisphere, one per illumination zenith.

    The angle is the relative azimuth (0 = backscatter towards the sun, 180 = forward) and the
    radius the view zenith [deg]; colour is the BRDF [sr^-1] on a log scale.
    """
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(4.6 * len(zeniths), 4.4), layout="constrained")
    axes = figure.subplots(1, len(zeniths), subplot_kw={"projection": "polar"}, squeeze=False)[0]
    azimuth = np.linspace(0.0, 360.0, 181)
    view = np.linspace(0.0, max_zenith, 86)
    folded = np.minimum(azimuth, 360.0 - azimuth)  # relative azimuth is folded into [0, 180]
    values = [np.asarray(material.brdf(t, view[:, None], folded[None, :])) for t in zeniths]
    norm = LogNorm(min(v.min() for v in values), max(v.max() for v in values))
    for axis, theta_i, value in zip(axes, zeniths, values):
        mesh = axis.pcolormesh(np.radians(azimuth), view, value, norm=norm, shading="gouraud", cmap="viridis")
        axis.set(title=f"θi = {theta_i:g}°", theta_zero_location="N")
        axis.set_rticks([30.0, 60.0], labels=["θr = 30°", "60°"])
        axis.set_rlabel_position(90)
        axis.tick_params(axis="y", colors="white")  # the radial labels sit on the dark colour map
        axis.set_xlabel("relative azimuth φ (angle) and view zenith θr (radius)", fontsize="small")
    figure.colorbar(mesh, ax=list(axes), label="BRDF [sr⁻¹]", shrink=0.8)
    figure.suptitle(f"{material.label}: {material.model.name}, {material.wavelength:g} nm (φ = 0: towards the sun)")
    return figure


def plot_azimuthal_widths(materials: Sequence[Material], geometries=WIDTH_GEOMETRIES) -> Figure:
    """Specular part (BRDF - t0) against relative azimuth, normalized to its peak (paper 003, fig. 3)."""
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(4.2 * len(materials), 3.8), layout="constrained")
    axes = figure.subplots(1, len(materials), squeeze=False)[0]
    phi = np.linspace(0.0, 180.0, 721)
    styles = ("-", "--", ":")
    for axis, material in zip(axes, materials):
        params = {**material.params, "t0": 0.0}
        for (theta_i, theta_r), style in zip(geometries, styles):
            values = np.asarray(material.model(theta_i, theta_r, phi, **params))
            axis.plot(phi, values / values.max(), style, label=f"θi = {theta_i:g}°, θr = {theta_r:g}°")
        axis.axhline(0.5, color="0.6", lw=0.8)
        axis.set(title=material.label, xlabel="relative azimuth φ [°]", xlim=(90, 180))
    axes[0].set_ylabel("(BRDF − t0) / max")
    axes[0].legend(fontsize="small")
    return figure
