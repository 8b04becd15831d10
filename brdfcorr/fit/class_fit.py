"""The fit of one class from imagery, with its diagnostics (:class:`ClassFit`): what
:func:`brdfcorr.fit.classes.fit_one_class` reports, :func:`brdfcorr.fit.entries.class_entry` turns
into a parameter-table class and the fit report summarizes (:meth:`ClassFit.summary`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from brdfcorr.fit.selection import ModelChoice

__all__ = ["ClassFit", "compact"]


def compact(values: np.ndarray):
    """A scalar when all bands share the value, else a list."""
    values = np.asarray(values, dtype=float)
    if values.size and np.all(values == values.flat[0]):
        return float(values.flat[0])
    return values.tolist()


@dataclass
class ClassFit:
    """The fit of one class, with its diagnostics.

    Attributes
    ----------
    class_id, name : int, str
        Class id and name.
    model : str
        Registered model name.
    n_samples : int
        Number of pixels fitted.
    vza_spread, phi_spread : float
        5th-95th percentile range of view zenith and relative azimuth among the samples [deg].
        With free levels, ``vza_spread`` is the geometry's spread within groups instead
        (:func:`brdfcorr.fit.classes._within_spread`): how differently each pixel or patch was seen.
    condition : float
        Condition number of the column-normalized linear design at the fitted shape.
    params : dict of str to ndarray
        Every model parameter, one value per band (shape parameters repeated).
    errors : dict of str to ndarray
        1-sigma errors of the free parameters, per band (0 for fixed ones).
    free : tuple of str
        The free parameters (shape and intensities), in the model's signature order.
    covariance : ndarray
        Joint sandwich covariance of ``free`` per band, shape (n_bands, p, p)
        (:func:`brdfcorr.fit.solver.fit_class_samples`).
    chi2_dof : ndarray
        Per band: sum of squared residuals / (N - p) [sr^-2].
    r2, rmse : ndarray
        Per band: coefficient of determination, and residual RMS of the BRDF [sr^-1].
    angular_r2 : ndarray
        Per band: R^2 of the fit against the data's means in bins of geometry (texture averaged
        out): how much of the angular signal the model explains.
    fixed : dict
        The shape parameters held fixed.
    status : str
        ``"fitted"``, ``"fallback"`` (a built-in material replaces the fit) or ``"uncorrected"``.
    reasons : list of str
        Why the class failed its guard rails (empty when fitted).
    notes : list of str
        What is worth knowing about a fit that passed (a poorly determined shape parameter).
    fallback : str or None
        The built-in material used instead, if any.
    better_model : str or None
        For a class whose fit failed or is poor (median R^2 < :data:`brdfcorr.fit.classes.POOR_R2`):
        another surface model that explains clearly more of its data (see
        :data:`brdfcorr.fit.classes.BETTER_GAIN`), if any. Not tried for a class that fails only for
        its sample (too few pixels, too narrow a range of views), which no model mends.
    better_r2 : float or None
        That model's held-out median R^2 (cross-validated over spatial blocks, on a subsample).
    errors_reliable : bool or None
        Whether the errors can be trusted (None before a fit): False with few spatial blocks
        (effective degrees of freedom below :data:`brdfcorr.fit.identifiability.MIN_ERROR_DOF`), a
        strongly non-linear fit (an error above half a parameter's distance to the end of its
        range), a shape parameter at the edge of its search range or an intensity at its bound
        (:func:`brdfcorr.fit.identifiability.error_reliability`).
    errors_reason : str
        Why they cannot (empty when they can).
    prior : str or None
        The shape prior the weights and covariance are the posterior of (``roy2016 (spread 0.2)``),
        if any (:mod:`brdfcorr.fit.prior`).
    model_choice : ModelChoice or None
        For a class fitted with ``model="auto"``: every candidate's held-out error and the model
        chosen (:func:`brdfcorr.fit.selection.choose_class_model`).
    levels : str
        Whose brightness levels were free (:data:`brdfcorr.fit.sampling.LEVELS`): ``pooled`` (one
        for the class), ``pixel`` or ``patch`` (the shape fitted to each group's own views; R^2,
        angular R^2, RMS and chi^2/dof are then those of the differences within groups).
    n_groups : int or None
        Pixels or patches with two or more views that the fit used (None when pooled).
    """

    class_id: int
    name: str
    model: str
    n_samples: int
    vza_spread: float
    phi_spread: float
    condition: float = math.nan
    params: dict[str, np.ndarray] = field(default_factory=dict)
    errors: dict[str, np.ndarray] = field(default_factory=dict)
    free: tuple[str, ...] = ()
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    chi2_dof: np.ndarray = field(default_factory=lambda: np.array([]))
    r2: np.ndarray = field(default_factory=lambda: np.array([]))
    rmse: np.ndarray = field(default_factory=lambda: np.array([]))
    angular_r2: np.ndarray = field(default_factory=lambda: np.array([]))
    fixed: dict[str, float] = field(default_factory=dict)
    status: str = "fitted"
    reasons: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    fallback: str | None = None
    better_model: str | None = None
    better_r2: float | None = None
    errors_reliable: bool | None = None
    errors_reason: str = ""
    prior: str | None = None
    model_choice: ModelChoice | None = None
    levels: str = "pooled"
    n_groups: int | None = None

    @property
    def median_r2(self) -> float:
        """Median over bands of R^2 (NaN before a fit)."""
        return _finite_median(self.r2)

    @property
    def median_angular_r2(self) -> float:
        """Median over bands of the angular R^2 (NaN before a fit)."""
        return _finite_median(self.angular_r2)

    def summary(self) -> dict[str, object]:
        """JSON-friendly summary (medians over bands for per-band quantities)."""
        median = lambda values: float(np.median(values)) if np.size(values) else None  # noqa: E731
        return {
            "class_id": self.class_id,
            "name": self.name,
            "model": self.model,
            "status": self.status,
            "reasons": list(self.reasons),
            "fallback": self.fallback,
            "n_samples": self.n_samples,
            "vza_spread_deg": round(self.vza_spread, 3),
            "phi_spread_deg": round(self.phi_spread, 3),
            "condition": None if math.isnan(self.condition) else float(self.condition),
            "median_r2": median(self.r2),
            "median_angular_r2": None if math.isnan(self.median_angular_r2) else self.median_angular_r2,
            "notes": list(self.notes),
            "median_rmse": median(self.rmse),
            "better_model": self.better_model,
            "better_model_median_r2": self.better_r2,
            "params": {k: compact(v) for k, v in self.params.items()},
            "errors": {k: compact(v) for k, v in self.errors.items()},
            "errors_reliable": self.errors_reliable,
            "errors_reason": self.errors_reason,
            "prior": self.prior,
            "model_choice": None if self.model_choice is None else self.model_choice.summary(),
            "levels": self.levels,
            "n_groups": self.n_groups,
        }


def _finite_median(values) -> float:
    finite = np.asarray(values, dtype=float)[np.isfinite(values)]
    return float(np.median(finite)) if finite.size else math.nan
