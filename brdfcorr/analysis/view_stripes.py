"""Errors shared along the track at one view angle (a detector's stripes), which no square block
and no larger block holds: the check behind the stripe warning of
:func:`brdfcorr.analysis.view_angles.assess_view_angles`. The same check sees the errors of a
composite's days where each day's orbit sees the scene from its own view angles.

A push-broom detector sees its stripe of the scene at one view angle along the whole track; a
calibration error of the detector is shared by every pixel of the stripe. Square blocks cut the
stripe into pieces taken as independent, so the slope's cluster-robust 1-sigma over blocks is too
small, by about the square root of the pieces per stripe (4-20x on the scenes of
``benchmarks/bench_assess_coverage.py``), and it grows with the block only as the square root of
the block's side, so the block-growth check misses half of such scenes.

The check (:func:`stripe_ratio`) takes the pixels of one bin of signed view zenith (the profile's
bins, over the whole scene) as one cluster: per bin g, the mean residual of the slope's line
``e_g``, less a weighted cubic in the bin's mean view zenith fitted over the bins (so that a
smooth curvature of the profile, which a straight line leaves, does not count), ``d_g``; the
between-bin part of the cluster scores, ``u_g = n_g (theta_g - theta_bar) d_g``, gives the
1-sigma ``sqrt(G / (G - 1 - 3) sum_g u_g^2) / Sxx`` (CR1 over the G bins, with the cubic's
degrees of freedom; the within-bin part, small for narrow bins, left out). Under errors independent
between bins its ratio to the 1-sigma reported scatters about 1 (below it where the bins' errors
are correlated with each other); with stripes it is the factor by which the reported 1-sigma is too
small. Above :data:`STRIPE_LIMIT` :func:`stripe_warning` says so in one line.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from brdfcorr.analysis._assess_common import _divide

__all__ = ["CLUSTER_LAYER", "MIN_STRIPE_BINS", "STRIPE_DEGREE", "STRIPE_LIMIT", "class_stripe_ratios", "stripe_ratio",
           "stripe_warning"]

#: How a report names the clusters of its errors when they are a cluster layer's (``--clusters``).
CLUSTER_LAYER = "the cluster layer's ids"
#: The ratio of the 1-sigma over bins of view zenith to the one reported above which
#: :func:`stripe_warning` warns (``benchmarks/bench_assess_coverage.py`` counts how often
#: independent, patch- and stripe-correlated scenes pass it).
STRIPE_LIMIT = 2.0
#: Degree of the polynomial in view zenith taken out of the bins' mean residuals (the smooth
#: curvature of a profile that the slope's straight line leaves).
STRIPE_DEGREE = 3
#: Fewest occupied bins for the check: fewer leave too few degrees of freedom after the cubic.
MIN_STRIPE_BINS = 8


def _detrended(mean_theta: np.ndarray, residual: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The bins' mean residuals (M, C) less their weighted least-squares polynomial of degree
    :data:`STRIPE_DEGREE` in the bins' mean view zenith (M,) [deg], weights (M,) (pixels)."""
    centred = (mean_theta - np.average(mean_theta, weights=weights)) / max(np.ptp(mean_theta), 1e-12)
    design = np.vander(centred, STRIPE_DEGREE + 1)
    root = np.sqrt(weights)[:, None]
    coefficients = np.linalg.lstsq(design * root, residual * root, rcond=None)[0]
    return residual - design @ coefficients


def stripe_ratio(bin_n: np.ndarray, bin_s: np.ndarray, bin_r: np.ndarray, line: tuple, sxx: np.ndarray,
                 reported: np.ndarray) -> np.ndarray:
    """Per stage, band and class (2, B, K): the slope's 1-sigma with the bins of signed view zenith
    as clusters (module docstring) over the ``reported`` one (2, B, K) [1/deg] [-]; NaN for a class
    in fewer than :data:`MIN_STRIPE_BINS` bins.

    Parameters
    ----------
    bin_n, bin_s : ndarray (K, M)
        Pixels and sum of the signed view zenith [deg] per class and bin.
    bin_r : ndarray (2, B, K, M)
        Sum of reflectance per stage, band, class and bin.
    line : (slope, mean, mean_s)
        The slope [1/deg] and mean reflectance (2, B, K) and the mean signed view zenith (K,) [deg].
    sxx : ndarray (K,)
        Sum of squared deviations of the signed view zenith [deg^2].
    reported : ndarray (2, B, K)
        The 1-sigma of the slope reported [1/deg].
    """
    slope, mean, mean_s = line
    ratio = np.full(reported.shape, np.nan)
    for k in range(bin_n.shape[0]):
        occupied = bin_n[k] > 0
        count = int(occupied.sum())
        if count < MIN_STRIPE_BINS:
            continue
        n, theta = bin_n[k, occupied], bin_s[k, occupied] / bin_n[k, occupied]
        means = bin_r[..., k, :][..., occupied] / n  # (2, B, G)
        residual = means - (mean[..., k, None] + slope[..., k, None] * (theta - mean_s[k]))
        flat = residual.reshape(-1, count).T  # (G, 2B)
        deviations = _detrended(theta, flat, n)
        scores = (n * (theta - mean_s[k]))[:, None] * deviations
        variance = count / (count - 1 - STRIPE_DEGREE) * np.sum(scores**2, axis=0) / sxx[k] ** 2
        ratio[..., k] = _divide(np.sqrt(variance).reshape(reported.shape[:2]), reported[..., k])
    return ratio


def class_stripe_ratios(dataset: xr.Dataset) -> np.ndarray:
    """Per class the median over bands of ``stripe_ratio`` after the correction (NaN where none)."""
    values = dataset["stripe_ratio"].sel(stage="after").values
    finite = np.isfinite(values)
    return np.array([np.median(column[ok]) if ok.any() else np.nan for column, ok in zip(values.T, finite.T)])


def stripe_warning(dataset: xr.Dataset, limit: float = STRIPE_LIMIT) -> str | None:
    """One line where the slopes' 1-sigma of some class (median over its bands, after the
    correction) over bins of view zenith is more than ``limit`` times the one reported
    (:func:`stripe_ratio`): errors shared along the track at one view angle, which larger blocks do
    not hold; None otherwise."""
    ratios = class_stripe_ratios(dataset)
    if not np.isfinite(ratios).any() or np.nanmax(ratios) <= limit:
        return None
    worst = int(np.nanargmax(ratios))
    return (f"the slopes' 1-sigma over bins of view zenith is {ratios[worst]:.1f}x the one over "
            f"{dataset.attrs['error_clusters']} ({dataset['class_name'].values[worst]}; more than {limit:g}x): errors "
            "shared by the pixels seen at one view angle (a detector's stripe along the track, an orbit's day in a "
            "composite) make the 1-sigma too small and larger blocks do not hold them; " + (
                "the cluster layer does not hold them either: give ids that the pixels of one view angle share"
                if dataset.attrs["error_clusters"] == CLUSTER_LAYER else "give their ids as --clusters") +
            " (the detector ids, a push-broom line's column numbers; a composite's day-of-year band)")
