"""Two-way cluster-robust errors: samples that share their errors within a pixel (or block, patch)
*and* within a scene (a date's atmosphere and calibration, a line's own view of the ground).

A fit's one-way errors (:mod:`brdfcorr.fit.sandwich`) sum the scores within each spatial cluster:
they allow for errors correlated within a pixel's views, or a block's pixels, but take the scenes
as independent, while an error shared by every pixel of one date (its aerosol, its calibration)
is correlated across all clusters. Cameron, Gelbach and Miller (2011, eq. 2.11) cluster over both
dimensions at once::

    V = V_1 + V_2 - V_12

with ``V_1`` the sandwich clustered over the first dimension (pixels, blocks), ``V_2`` over the
second (scenes) and ``V_12`` over their intersection (a pixel's view in one scene): the pairs
correlated in either dimension are counted once. Each term here is the one-way sandwich with its
small-sample adjustment (CR2, :func:`brdfcorr.fit.sandwich._joint_covariance`). ``V`` need not be
positive semi-definite; negative eigenvalues are set to zero (Cameron, Gelbach and Miller 2011,
section 2.3). The degrees of freedom of each error are those of the dimension with the fewer
clusters (their section 2.4: inference with ``min(G_1, G_2)``), usually the scenes: with a handful
of dates, two-way errors are rightly flagged unreliable. With a single scene the second dimension
has one cluster and the formula degenerates (``V_2 = 0``, ``V_12 = V_1``): the errors are then the
one-way ones.

References
----------
.. [1] A. C. Cameron, J. B. Gelbach, D. L. Miller (2011): Robust inference with multiway
   clustering. Journal of Business & Economic Statistics 29(2), 238-249.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from brdfcorr.fit.sandwich import Sandwich
from brdfcorr.fit.within import cluster_mean_variance

__all__ = ["TwoWayClusters", "clustered_covariance", "clustered_mean_variance", "nearest_psd"]


def _codes(labels) -> np.ndarray:
    _, codes = np.unique(np.asarray(labels).reshape(-1), return_inverse=True)
    return codes.reshape(-1)


@dataclass(frozen=True)
class TwoWayClusters:
    """Two cluster ids per sample: ``first`` (N,; pixels, blocks or a cluster layer) and
    ``second`` (N,; the scene)."""

    first: np.ndarray
    second: np.ndarray

    @classmethod
    def of(cls, first, second) -> TwoWayClusters:
        """Clusters from labels (any integers); ``first`` None: each sample its own cluster."""
        second = _codes(second)
        return cls(np.arange(second.size) if first is None else _codes(first), second)

    @property
    def intersection(self) -> np.ndarray:
        """Codes of the (first, second) pairs."""
        return self.first.astype(np.int64) * (int(self.second.max(initial=0)) + 1) + self.second

    @property
    def single_scene(self) -> bool:
        """Whether the second dimension holds one cluster only (the errors are one-way)."""
        return np.unique(self.second).size < 2


def nearest_psd(covariance: np.ndarray) -> np.ndarray:
    """Each symmetric matrix of ``covariance`` (..., q, q) with its negative eigenvalues set to 0
    (Cameron, Gelbach and Miller 2011, section 2.3)."""
    values, vectors = np.linalg.eigh(0.5 * (covariance + np.swapaxes(covariance, -1, -2)))
    return (vectors * np.maximum(values, 0.0)[..., None, :]) @ np.swapaxes(vectors, -1, -2)


def clustered_covariance(sandwich_of: Callable[[np.ndarray | None], Sandwich], clusters) -> Sandwich:
    """The sandwich ``sandwich_of(clusters)`` for one-way ``clusters`` (N,) or None, and for
    :class:`TwoWayClusters` ``V_1 + V_2 - V_12`` (module docstring), made positive
    semi-definite, with the degrees of freedom of the dimension with fewer clusters."""
    if not isinstance(clusters, TwoWayClusters):
        return sandwich_of(clusters)
    first = sandwich_of(clusters.first)
    if clusters.single_scene:
        return first
    second, both = sandwich_of(clusters.second), sandwich_of(clusters.intersection)
    covariance = nearest_psd(first.covariance + second.covariance - both.covariance)
    fewer = second if second.n_clusters <= first.n_clusters else first
    return Sandwich(covariance, np.minimum(first.dof, second.dof), fewer.n_clusters,
                    max(first.max_leverage, second.max_leverage), scenes=fewer is second)


def clustered_mean_variance(values: np.ndarray, clusters) -> np.ndarray:
    """Cluster-robust variance (B,) of the mean of ``values`` (N, B)
    (:func:`brdfcorr.fit.within.cluster_mean_variance`), two-way for :class:`TwoWayClusters`
    (``v_1 + v_2 - v_12``, at least 0)."""
    if not isinstance(clusters, TwoWayClusters):
        return cluster_mean_variance(values, clusters)
    first = cluster_mean_variance(values, clusters.first)
    if clusters.single_scene:
        return first
    combined = first + cluster_mean_variance(values, clusters.second) - cluster_mean_variance(
        values, clusters.intersection)
    return np.maximum(combined, 0.0)
