"""A coefficient set's kernel shape as a prior of an imagery fit (``fit-classes --prior``).

A scene fit of the RTLSR weights per class and band is unbiased but noisy where a class has few
pixels or a narrow range of view angles; a global coefficient set (Roy et al. 2016) is precise but
the same for every land cover. :func:`with_shape_prior` combines the two, band by band, as the
maximum a posteriori estimate of a linear Gaussian model. The prior is on the kernel *shape*, the
ratios ``f_vol / f_iso`` and ``f_geo / f_iso``, not on the weights themselves: a scene's albedo is
its own, and only the shape enters the correction factor.

For a band with fitted weights ``w = (f_iso, f_vol, f_geo)`` and their covariance ``C`` (the fit
record's), and the prior's ratios ``r_vol``, ``r_geo`` at the band's centre, the prior reads

    f_vol - r_vol f_iso ~ N(0, (s f_iso)^2),    f_geo - r_geo f_iso ~ N(0, (s f_iso)^2)

with ``s`` the spread (the prior's 1-sigma of either ratio, dimensionless) and ``f_iso`` the fit's.
With ``A = [[-r_vol, 1, 0], [-r_geo, 0, 1]]`` and ``t = s f_iso`` the posterior is

    Q = C^-1 + A^T A / t^2,    w' = Q^-1 C^-1 w,    C' = Q^-1

(the fit's likelihood approximated by its Gaussian, exact for the linear kernel model), computed
in the equal form ``w' = w - C A^T (A C A^T + t^2 I)^-1 A w`` that needs no inverse of ``C``.
``s`` to infinity gives the fit back, ``s`` to 0 the prior's ratios with the fit's brightness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdfcorr.errors import InputError
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.params import ParameterTable

__all__ = ["DEFAULT_PRIOR_SPREAD", "KERNEL_WEIGHTS", "PRIOR_MODEL", "ShapePrior", "prior_ratios", "shape_posterior",
           "with_shape_prior"]

#: The model whose classes a prior applies to, and its weights in the order of a fit's covariance.
PRIOR_MODEL = "ross_thick_li_sparse"
KERNEL_WEIGHTS = ("f_iso", "f_vol", "f_geo")

#: The smallest f_iso [sr^-1] the prior's width is scaled by: a fit at the bound f_iso = 0 keeps a
#: width whose square is a number (``tiny`` squared would be 0, and the 2 x 2 system singular).
MIN_ISO = 1e-12

#: ``fit-classes --prior``'s default spread: of 0.05, 0.1, 0.2 and 0.5, the one that left the
#: smallest held-out residual on the real MODIS subset (``benchmarks/bench_real.py --prior-spread``).
DEFAULT_PRIOR_SPREAD = 0.2


@dataclass(frozen=True)
class ShapePrior:
    """A coefficient set's kernel shape as the prior of an imagery fit (``--prior``).

    Attributes
    ----------
    coefficients : str
        Built-in coefficient set (:func:`brdfcorr.models.coefficients.load_coefficients`).
    spread : float, default DEFAULT_PRIOR_SPREAD
        The prior's 1-sigma of the ratios f_vol/f_iso and f_geo/f_iso [-] (> 0).

    Raises
    ------
    InputError
        ``spread`` is not a positive number.
    UnknownNameError
        ``coefficients`` names no built-in set.
    """

    coefficients: str
    spread: float = DEFAULT_PRIOR_SPREAD

    def __post_init__(self) -> None:
        if not (self.spread > 0 and np.isfinite(self.spread)):
            raise InputError(f"the prior's spread {self.spread} must be a positive number")
        load_coefficients(self.coefficients)

    @classmethod
    def given(cls, coefficients: str, spread: float | None = None) -> ShapePrior:
        """The prior of an option or a config key pair: ``spread`` None is the default spread."""
        return cls(coefficients) if spread is None else cls(coefficients, spread)

    @property
    def label(self) -> str:
        """``roy2016 (spread 0.2)``: how a fit record's source names it."""
        return f"{self.coefficients} (spread {self.spread:g})"


def prior_ratios(coefficients: str, wavelengths) -> np.ndarray:
    """(n, 2): ``f_vol / f_iso`` and ``f_geo / f_iso`` of the coefficient set ``coefficients``
    (:func:`brdfcorr.models.coefficients.load_coefficients`) at ``wavelengths`` [nm], linear in
    wavelength between its bands' centres and held at the end bands' values beyond them."""
    nodes, weights = load_coefficients(coefficients).wavelength_nodes()
    iso = np.asarray(weights["f_iso"], float)
    return np.column_stack([np.interp(np.asarray(wavelengths, float), nodes, np.asarray(weights[name], float) / iso)
                            for name in ("f_vol", "f_geo")])


def shape_posterior(weights: np.ndarray, covariance: np.ndarray, ratios: np.ndarray,
                    spread: float) -> tuple[np.ndarray, np.ndarray]:
    """The posterior weights (n, 3) and covariance (n, 3, 3) of fitted RTLSR ``weights`` (n, 3:
    f_iso, f_vol, f_geo per band) with ``covariance`` (n, 3, 3) under the shape prior of
    ``ratios`` (n, 2) with 1-sigma ``spread`` (module docstring); weights clipped at 0, the
    model's bound."""
    weights, covariance, ratios = (np.asarray(a, float) for a in (weights, covariance, ratios))
    n = weights.shape[0]
    design = np.zeros((n, 2, 3))
    design[:, :, 0] = -ratios
    design[:, 0, 1] = design[:, 1, 2] = 1.0
    width = spread * np.maximum(weights[:, 0], MIN_ISO)
    # The update form of the posterior (equal to the module's): no inverse of C, which a fit
    # without noise leaves singular; the 2 x 2 system is positive definite whatever C.
    gain = covariance @ np.swapaxes(design, 1, 2)  # C A^T, (n, 3, 2)
    system = design @ gain + width[:, None, None] ** 2 * np.eye(2)
    residual = design @ weights[:, :, None]  # A w: the fit's departure from the prior's shape
    estimate = weights - (gain @ np.linalg.solve(system, residual))[:, :, 0]
    posterior = covariance - gain @ np.linalg.solve(system, np.swapaxes(gain, 1, 2))
    return np.maximum(estimate, 0.0), 0.5 * (posterior + np.swapaxes(posterior, 1, 2))


def with_shape_prior(table: ParameterTable, prior: ShapePrior) -> ParameterTable:
    """``table`` with its fitted ``ross_thick_li_sparse`` classes moved to their posterior under
    ``prior`` (:func:`shape_posterior`; :func:`prior_ratios` at each class's wavelengths):
    parameters, covariance and errors; the record's source names the prior. Classes of other
    models, without a fit record (a fallback) or with weights held fixed are left as they are.
    For a table fitted before (the record keeps the fit's R^2 and chi^2: the samples are not at
    hand); ``fit-classes --prior`` applies the prior within the fit (:class:`brdfcorr.fit.ClassModels`),
    before the guard rails, which then judge the posterior.
    """
    result = table
    for entry in table.classes:
        fit = entry.fit
        if (entry.model != PRIOR_MODEL or fit is None or entry.wavelengths is None
                or tuple(fit.parameters) != KERNEL_WEIGHTS):
            continue
        wavelengths = np.asarray(entry.wavelengths, float)
        weights = np.column_stack([np.broadcast_to(np.asarray(entry.params[name], float), wavelengths.shape)
                                   for name in KERNEL_WEIGHTS])
        matrices = np.broadcast_to(fit.matrices(), (wavelengths.size, 3, 3))
        posterior, covariance = shape_posterior(weights, matrices, prior_ratios(prior.coefficients, wavelengths),
                                                prior.spread)
        errors = np.sqrt(np.diagonal(covariance, axis1=1, axis2=2))
        record = fit.model_dump() | {
            "source": f"{fit.source} + shape prior {prior.label}",
            "covariance": covariance.tolist(),
            "errors": {name: errors[:, j].tolist() for j, name in enumerate(KERNEL_WEIGHTS)},
        }
        for name, kind in (("n", int), ("chi2_dof", float), ("r2", float)):  # one per band, as the covariance
            record[name] = [kind(value) for value in np.broadcast_to(np.asarray(record[name]), wavelengths.shape)]
        result = result.with_class(entry.model_dump() | {
            "params": {name: posterior[:, j].tolist() for j, name in enumerate(KERNEL_WEIGHTS)}, "fit": record})
    return result
