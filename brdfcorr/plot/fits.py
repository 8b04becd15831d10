"""Figures of a BRDF fit against goniometer measurements, in the layout of paper 003 figs. 2 and 3.

Both functions return a :class:`matplotlib.figure.Figure` (no pyplot state); saving is the
caller's choice. Measurements are drawn with their 1-sigma error bars, the fitted model as a
line; measurements that were not fitted (e.g. phi < 90 deg, as in paper 003) can be shown hollow.

References
----------
.. [1] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII, figs. 2 and 3.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from brdfcorr.fit.goniometer import FitResult
from brdfcorr.fit.measurements import Measurements

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["principal_plane_cuts", "azimuth_cuts", "plot_principal_plane", "plot_azimuth"]

_FITTED = {"fmt": "*", "color": "C0", "ecolor": "C0", "ms": 6, "capsize": 2, "lw": 1}
_EXCLUDED = {"fmt": "o", "mfc": "none", "color": "0.55", "ecolor": "0.7", "ms": 4, "capsize": 2, "lw": 1}


def _grid(count: int, panel: tuple[float, float] = (4.2, 3.4)):
    rows = math.ceil(count / 4)
    columns = math.ceil(count / rows)
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(panel[0] * columns, panel[1] * rows), layout="constrained")
    axes = np.atleast_1d(figure.subplots(rows, columns, squeeze=False).ravel())
    for axis in axes[count:]:
        axis.set_visible(False)
    return figure, axes[:count]


def _in_principal_plane(measurements: Measurements, tolerance: float) -> np.ndarray:
    return (
        (measurements.phi >= 180.0 - tolerance)
        | (measurements.phi <= tolerance)
        | (measurements.theta_r <= tolerance)  # at nadir view the azimuth is undefined
    )


def principal_plane_cuts(measurements: Measurements, tolerance: float = 0.5) -> list[float]:
    """Illumination zeniths [deg] with at least 3 principal-plane measurements (phi = 0 or 180 deg
    within ``tolerance``), sorted."""
    in_plane = _in_principal_plane(measurements, tolerance)
    zeniths, counts = np.unique(np.round(measurements.theta_i[in_plane], 1), return_counts=True)
    return [float(zenith) for zenith, count in zip(zeniths, counts) if count >= 3]


def azimuth_cuts(measurements: Measurements, min_points: int = 4) -> list[tuple[float, float]]:
    """(theta_i, theta_r) pairs [deg] measured at ``min_points`` or more distinct azimuths (the
    azimuthal scans of paper 003, fig. 3), sorted."""
    pairs = np.round(np.column_stack([measurements.theta_i, measurements.theta_r]), 1)
    cuts = []
    for pair in np.unique(pairs, axis=0):
        if pair[1] <= 0.0:
            continue
        same = np.all(pairs == pair, axis=1)
        if np.unique(np.round(measurements.phi[same], 1)).size >= min_points:
            cuts.append((float(pair[0]), float(pair[1])))
    return cuts


def _errorbar(axis, x, measurements: Measurements, mask, style, label):
    if not np.any(mask):
        return
    sigma = None if measurements.sigma is None else measurements.sigma[mask]
    axis.errorbar(x[mask], measurements.brdf[mask], yerr=sigma, ls="none", label=label, **style)


def plot_principal_plane(
    result: FitResult,
    measurements: Measurements,
    excluded: Measurements | None = None,
    *,
    tolerance: float = 0.5,
    yscale: str = "linear",
    title: str | None = None,
) -> Figure:
    """The fitted model and the measurements in the principal plane (paper 003, fig. 2).

    Parameters
    ----------
    result : FitResult
        The fit (:func:`brdfcorr.fit.goniometer.fit_brdf`).
    measurements : Measurements
        The fitted measurements, drawn as stars with 1-sigma error bars.
    excluded : Measurements, optional
        Measurements read but not fitted (e.g. phi < 90 deg), drawn hollow and grey.
    tolerance : float
        Azimuth tolerance [deg] around phi = 0 and 180 for a measurement to count as in-plane.
    yscale : {"linear", "log"}
        Scale of the BRDF axis ("log" for sharp peaks such as the aluminium sample).
    title : str, optional
        Figure title; default names the model, the fitted measurements drawn (those in the plane
        within ``tolerance``) out of all fitted, and the fit's chi^2/dof.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per illumination zenith: BRDF [sr^-1] against the signed view zenith [deg]
        (positive: forward scattering, phi = 180 deg; negative: backward, phi = 0 deg).
    """
    sets = [measurements] + ([excluded] if excluded is not None else [])
    zeniths = sorted({z for data in sets for z in principal_plane_cuts(data, tolerance)})
    if not zeniths:
        zeniths = sorted(set(np.round(measurements.theta_i, 1).tolist()))
    figure, axes = _grid(len(zeniths))
    shown = 0  # fitted measurements drawn: in the plane within the tolerance, at a panel's zenith
    for axis, zenith in zip(axes, zeniths):
        extent = 0.0
        for data, style, label in ((measurements, _FITTED, "fitted"), (excluded, _EXCLUDED, "not fitted")):
            if data is None:
                continue
            mask = _in_principal_plane(data, tolerance) & (np.round(data.theta_i, 1) == zenith)
            signed = np.where(data.phi >= 90.0, data.theta_r, -data.theta_r)
            _errorbar(axis, signed, data, mask, style, label)
            shown += int(np.count_nonzero(mask)) if data is measurements else 0
            if np.any(mask):
                extent = max(extent, float(np.max(data.theta_r[mask])))
        extent = max(extent, 10.0)
        view = np.linspace(-extent, extent, 401)
        model = result.predict(zenith, np.abs(view), np.where(view >= 0, 180.0, 0.0))
        axis.plot(view, model, color="k", lw=1.2, label=f"{result.model.name} fit")
        axis.axvline(zenith, color="0.6", lw=0.8, ls=":")
        axis.set_yscale(yscale)
        axis.set(
            title=f"θi = {zenith:g}°, principal plane",
            xlabel="view zenith θr [°] (< 0: backward, φ = 0°)",
            ylabel="BRDF [sr⁻¹]",
        )
    axes[0].legend(fontsize="small")
    figure.suptitle(title or _default_title(result, "principal plane", shown))
    return figure


def plot_azimuth(
    result: FitResult,
    measurements: Measurements,
    excluded: Measurements | None = None,
    *,
    min_points: int = 4,
    yscale: str = "linear",
    title: str | None = None,
) -> Figure:
    """The fitted model and the measurements against relative azimuth (paper 003, fig. 3).

    Parameters
    ----------
    result : FitResult
        The fit.
    measurements : Measurements
        The fitted measurements (stars with 1-sigma error bars).
    excluded : Measurements, optional
        Measurements read but not fitted, drawn hollow and grey.
    min_points : int
        A (theta_i, theta_r) pair measured at this many azimuths or more is an azimuthal cut.
    yscale : {"linear", "log"}
        Scale of the BRDF axes.
    title : str, optional
        Figure title; default names the model, the fitted measurements on the cuts drawn out of
        all fitted, and the fit's chi^2/dof.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per azimuthal cut, BRDF [sr^-1] against phi [deg] (180 = forward scattering);
        if the model has a Lambertian term t0, a last panel shows, as paper 003 does, the specular
        part only (BRDF - t0) of every cut, measured and modelled, divided by the model's maximum
        on that cut: the azimuthal narrowing of the peak with increasing zenith.
    """
    sets = [measurements] + ([excluded] if excluded is not None else [])
    cuts = sorted({cut for data in sets for cut in azimuth_cuts(data, min_points)})
    if not cuts:
        figure, axes = _grid(1)
        axes[0].text(0.5, 0.5, "no azimuthal scans in the measurements", ha="center", va="center",
                     transform=axes[0].transAxes)
        axes[0].set_axis_off()
        return figure
    normalized = "t0" in result.params
    figure, axes = _grid(len(cuts) + normalized)
    lowest, shown = 180.0, 0  # shown: fitted measurements on the cuts drawn
    for number, (axis, (zenith, view_zenith)) in enumerate(zip(axes, cuts)):
        for data, style, label in ((measurements, _FITTED, "fitted"), (excluded, _EXCLUDED, "not fitted")):
            if data is not None:
                mask = (np.round(data.theta_i, 1) == zenith) & (np.round(data.theta_r, 1) == view_zenith)
                _errorbar(axis, data.phi, data, mask, style, label)
                shown += int(np.count_nonzero(mask)) if data is measurements else 0
        # The azimuth range that was fitted (paper 003: 90-180 deg); the whole scan if none was.
        fitted = (np.round(measurements.theta_i, 1) == zenith) & (np.round(measurements.theta_r, 1) == view_zenith)
        low = float(np.min(measurements.phi[fitted])) if np.any(fitted) else 0.0
        lowest = min(lowest, low)
        azimuth = np.linspace(low, 180.0, 361)
        axis.set_xlim(low - 3.0, 183.0)
        model = result.predict(zenith, view_zenith, azimuth)
        axis.plot(azimuth, model, color="k", lw=1.2, label=f"{result.model.name} fit")
        axis.set_yscale(yscale)
        axis.set(
            title=f"θi = {zenith:g}°, θr = {view_zenith:g}°",
            xlabel="relative azimuth φ [°] (180 = forward)",
            ylabel="BRDF [sr⁻¹]",
        )
        if normalized:
            _normalized_panel(axes[-1], result, measurements, zenith, view_zenith, azimuth, number)
    axes[0].legend(fontsize="small")
    if normalized:
        axes[-1].set_xlim(lowest - 3.0, 183.0)
        axes[-1].set(
            title="specular part, normalized",
            xlabel="relative azimuth φ [°]",
            ylabel="(BRDF − t0) / max [-]",
        )
        axes[-1].legend(fontsize="x-small")
    figure.suptitle(title or _default_title(result, "azimuthal scans", shown))
    return figure


def _normalized_panel(axis, result, measurements, zenith, view_zenith, azimuth, number):
    t0 = result.params["t0"]
    color = f"C{number}"
    model = np.asarray(result.predict(zenith, view_zenith, azimuth)) - t0
    peak = float(np.max(model))
    if peak <= 0:
        return
    axis.plot(azimuth, model / peak, color=color, lw=1.0, label=f"θi = {zenith:g}°, θr = {view_zenith:g}°")
    mask = (np.round(measurements.theta_i, 1) == zenith) & (np.round(measurements.theta_r, 1) == view_zenith)
    axis.plot(measurements.phi[mask], (measurements.brdf[mask] - t0) / peak, "*", color=color, ms=5)


def _default_title(result: FitResult, what: str, shown: int) -> str:
    """The figure's title: the model, how many of the fitted measurements the panels show (those of
    the principal plane or of the azimuthal scans, not every one fitted) and chi^2/dof, which is
    the fit's, over all of them."""
    return (
        f"{result.model.name} fit, {what}: {shown} of {result.n_measurements} fitted measurements "
        f"(χ²/dof = {result.reduced_chi2:.3g} over all {result.n_measurements})"
    )
