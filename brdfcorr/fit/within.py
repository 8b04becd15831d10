"""Free levels: the within (fixed-effects) transformation behind fits that tell BRDF from land cover.

A fit pooled over a class's pixels takes a pixel that is brighter because it holds more
vegetation for one that is brighter because it is seen towards the hot spot, wherever cover and
view angle are correlated (issue 24's scene A', a composite's orbits). Where the same ground is
seen more than once (a stack of dates on one grid, overlapping lines resampled to one grid) or
where neighbouring pixels were seen from different orbits (a composite), every pixel (or patch of
pixels) gets a free level of its own::

    f_nb = alpha_g(n),b + sum_j p_jb B_j(geometry_n; shape)        (one level alpha per group g)

and the levels are projected out (Frisch-Waugh-Lovell): the data and every design column less
their group means, the "within" transformation of panel regression (Wooldridge 2010, ch. 10.5).
The level is multiplicative (cover, albedo texture and a brighter roof scale the whole BRDF,
``f_nd = s_n g(geometry_nd)``), so each group's views are taken relative to their own mean and
brought back to the model's level at the group's own geometry, ``u_nd = f_nd gbar_n / fbar_n``
with ``gbar_n`` the mean of the current fit over the group's views (:meth:`Levels.relative`):
``u = g`` at the truth, so the within fit of ``u`` is consistent, and a pixel twice as bright
weighs in the shape as much as any other. The solver starts from ``gbar_n`` equal for every
group (the class's mean level) and iterates until the levels converge
(:data:`brdfcorr.fit.solver.LEVEL_TOLERANCE`).
The shape and the geometry-dependent intensities are then fitted to the differences between the
views of one group alone, so differences between groups never enter them. A second factor (the
scene: a date's or a line's own level, e.g. its atmosphere) is projected out as well by
alternating projections (the method of alternating projections of Gaure 2013), which converge to
the two-way within transformation; :func:`brdfcorr.fit.classes.fit_one_class` frees it only where
the geometry left within groups beside it still spreads as the guard rail asks (two lines that
see their overlap from opposite sides differ at every pixel by one step of the view, which a level
per line would absorb).

The constant term of the model (``t0``, ``f_iso``: the level itself) is not identified within
groups; it is restored afterwards from the class's mean (:func:`restored_constant`), so the table
describes the class's typical pixel and a correction by it (a ratio of the model at two geometries)
uses the shape fitted within groups.

References
----------
.. [1] J. M. Wooldridge (2010): Econometric Analysis of Cross Section and Panel Data, 2nd ed., MIT Press.
.. [2] S. Gaure (2013): OLS with multiple high dimensional category variables. Computational
   Statistics & Data Analysis 66, 8-18.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Levels",
    "cluster_mean_variance",
    "restored_constant",
    "with_level_variance",
    "with_constant",
]

#: Alternating projections stop when a sweep changes no value by more than this fraction of the
#: largest absolute value, or after :data:`MAX_SWEEPS` sweeps (two factors only).
TOLERANCE, MAX_SWEEPS = 1e-10, 200


@dataclass(frozen=True)
class Levels:
    """The groups whose levels are free: one or two factors of integer codes 0..n-1 per sample.

    Build with :meth:`from_labels`. ``factors[0]`` is the main one (pixel or patch); a second,
    optional one is the scene (date, line).
    """

    factors: tuple[np.ndarray, ...]
    counts: tuple[np.ndarray, ...]

    @classmethod
    def from_labels(cls, *labels: np.ndarray | None) -> Levels:
        """Levels of the given label arrays (any integers; None entries are skipped); a factor
        with a single value carries no level of its own beyond the mean and is dropped."""
        factors, counts = [], []
        for label in labels:
            if label is None:
                continue
            _, codes = np.unique(np.asarray(label).reshape(-1), return_inverse=True)
            codes = codes.reshape(-1)
            count = np.bincount(codes).astype(float)
            if count.size > 1 or not factors:
                factors.append(codes)
                counts.append(count)
        return cls(tuple(factors), tuple(counts))

    @property
    def n_groups(self) -> int:
        """Groups of the main factor."""
        return int(self.counts[0].size)

    def subset(self, rows: np.ndarray) -> Levels:
        """The levels of the samples ``rows`` (index or mask)."""
        return Levels.from_labels(*(codes[rows] for codes in self.factors))

    def _demean_once(self, values: np.ndarray, codes: np.ndarray, count: np.ndarray) -> np.ndarray:
        flat = values.reshape(values.shape[0], -1)
        return (flat - _means(flat, codes, count)).reshape(values.shape)

    def demean(self, values: np.ndarray) -> np.ndarray:
        """``values`` (N, ...) less their group means: the within transformation (one factor:
        exact in one pass; two: alternating projections to :data:`TOLERANCE`)."""
        values = np.asarray(values, dtype=float)
        result = self._demean_once(values, self.factors[0], self.counts[0])
        if len(self.factors) == 1:
            return result
        scale = max(float(np.max(np.abs(values))), 1e-300)
        for _ in range(MAX_SWEEPS):
            before = result
            for codes, count in zip(self.factors, self.counts):
                result = self._demean_once(result, codes, count)
            if np.max(np.abs(result - before)) <= TOLERANCE * scale:
                break
        return result

    def group_means(self, values: np.ndarray) -> np.ndarray:
        """Each sample's group mean (main factor) of ``values`` (N, B), shape (N, B)."""
        return _means(values, self.factors[0], self.counts[0])

    def usable(self, values: np.ndarray) -> np.ndarray:
        """Mask of the samples whose group (main factor) holds at least two, with a positive mean
        in every band: a group seen once has no difference between views, and one without a level
        has nothing to be relative to (:meth:`relative`)."""
        return (self.counts[0][self.factors[0]] >= 2) & np.all(self.group_means(values) > 0, axis=1)

    def relative(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``values`` (N, B) over their group's mean, and those means (N, B): the views of a
        pixel relative to its own level, so that a pixel twice as bright (more cover, a brighter
        roof) weighs in the shape as much as any other (the level is multiplicative)."""
        means = self.group_means(values)
        return values / means, means


def _means(values: np.ndarray, codes: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Each sample's group mean of ``values`` (N, k) for group ``codes`` of ``count`` samples
    (zero columns: a model whose only term is the level, Lambertian)."""
    if values.shape[1] == 0:
        return np.zeros(values.shape)
    sums = np.stack([np.bincount(codes, weights=column, minlength=count.size) for column in values.T], axis=1)
    return (sums / count[:, None])[codes]


def restored_constant(mean_data: np.ndarray, mean_terms: np.ndarray, coefficients: np.ndarray,
                      constant_mean: float) -> np.ndarray:
    """The constant intensity (per band) that gives the fit the data's mean: ``(mean(f) - sum_j
    p_j mean(B_j)) / mean(B_0)`` with ``mean_terms`` (m,) the samples' means of the fitted
    (non-constant) terms, ``coefficients`` (m, B) their intensities and ``constant_mean`` that of
    the constant term's column (1 for t0 and f_iso)."""
    return (np.asarray(mean_data, dtype=float) - np.asarray(mean_terms) @ np.asarray(coefficients)) / constant_mean


def with_constant(covariance: np.ndarray, jacobian: np.ndarray, level_variance: np.ndarray) -> np.ndarray:
    """The joint covariance (B, p + 1, p + 1) of the fitted parameters and the restored constant.

    The constant is ``c = (ybar - sum_j p_j mean(B_j)(shape)) / mean(B_0)``: a linear function,
    with ``jacobian`` (B, p), of the fitted parameters (covariance (B, p, p)), plus the class mean
    ``ybar``, whose variance ``level_variance`` (B,) comes from the spread of the groups' levels.
    The within estimate is orthogonal to the group means (Frisch-Waugh-Lovell), so ``ybar`` and
    the fitted parameters are taken as uncorrelated.
    """
    cross = np.einsum("bij,bj->bi", covariance, jacobian)  # (B, p)
    variance = np.einsum("bi,bi->b", jacobian, cross) + level_variance
    n_bands, p = jacobian.shape
    joint = np.empty((n_bands, p + 1, p + 1))
    joint[:, :p, :p] = covariance
    joint[:, :p, p] = joint[:, p, :p] = cross
    joint[:, p, p] = variance
    return joint


def with_level_variance(covariance: np.ndarray, intensities: np.ndarray, relative_variance: np.ndarray) -> np.ndarray:
    """The covariance (B, p, p) of a within fit with the uncertainty of the class's mean level
    ``L`` added: all intensities ``intensities`` (B, m; the last m of the p) [sr^-1] scale with it,
    ``p p^T var(L) / L^2`` (``relative_variance`` (B,); the level and the within fit taken as
    uncorrelated, Frisch-Waugh-Lovell)."""
    n_bands, p, _ = covariance.shape
    values = np.zeros((n_bands, p))
    values[:, p - intensities.shape[1]:] = intensities
    return covariance + values[:, :, None] * values[:, None, :] * relative_variance[:, None, None]


def cluster_mean_variance(values: np.ndarray, clusters: np.ndarray) -> np.ndarray:
    """Cluster-robust variance (CR1) of the mean of ``values`` (N, B) over samples that may be
    correlated within ``clusters`` (N,): ``G / (G - 1) sum_g (sum_(n in g) (v_n - vbar))^2 / N^2``."""
    values = np.asarray(values, dtype=float)
    _, codes = np.unique(np.asarray(clusters).reshape(-1), return_inverse=True)
    codes = codes.reshape(-1)
    n, groups = values.shape[0], int(codes.max()) + 1
    deviations = values - values.mean(axis=0)
    sums = np.stack([np.bincount(codes, weights=column, minlength=groups) for column in deviations.T], axis=1)
    correction = groups / (groups - 1) if groups > 1 else np.inf
    return correction * np.sum(sums**2, axis=0) / n**2
