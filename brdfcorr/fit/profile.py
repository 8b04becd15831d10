"""The linear profile of a class fit (:class:`_LinearProfile`): the sums of the data that the
per-band linear solve of the intensity terms needs for a trial shape, computed once per class.

For a trial shape the intensities of all bands are solved at once by (non-negative) linear least
squares from ``B^T B`` and ``B^T y``; the profile objective (the weighted sum of squared residuals
left) is what the shape search minimizes (:mod:`brdfcorr.fit.shape_search`). With free levels
(:mod:`brdfcorr.fit.within`) the data and the design are taken within groups.
"""

from __future__ import annotations

import copy
import functools
import itertools
import math
from collections.abc import Mapping

import numpy as np
import scipy.sparse

from brdfcorr.errors import ParameterError
from brdfcorr.fit.shapes import _free_shape, intensity_terms, search_range
from brdfcorr.fit.within import Levels, restored_constant
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import Model

__all__ = ["geometry_bins"]


@functools.cache
def _faces(m: int) -> tuple[dict[int, tuple[np.ndarray, np.ndarray]], int]:
    """The faces of the constraint box of ``m`` linear terms (the non-empty sets of free terms), in
    the order of ``itertools.product((False, True), repeat=m)``, by size k: their positions in
    that order and their (F_k, k) term indices; and how many there are."""
    order = [np.flatnonzero(free) for free in itertools.product((False, True), repeat=m) if any(free)]
    return {k: (np.array([i for i, face in enumerate(order) if face.size == k]),
                np.array([face for face in order if face.size == k])) for k in range(1, m + 1)}, len(order)


class _LinearProfile:
    """Sums of the data that the per-band linear solve needs, computed once per class.

    With ``levels`` (:class:`brdfcorr.fit.within.Levels`) every group has a free level: the data
    are taken relative to their group's mean, times the model's level at the group's geometry
    (``group_model``, (N, B) [sr^-1]; default the class's mean level ``scale`` everywhere), and
    like the design within groups (less their group means); the model's constant term
    (``constant``; t0, f_iso) drops out of the design (``terms`` are the others) and is restored
    by :meth:`full_intensities`.
    """

    def __init__(self, model: Model, geometry: ScatteringGeometry, data: np.ndarray, fixed: dict,
                 levels: Levels | None = None, group_model: np.ndarray | None = None):
        self.model = model
        self.geometry = geometry
        self.fixed = fixed
        self.levels = levels
        self.ranges = {name: search_range(model, name) for name in _free_shape(model, fixed)}
        lower = [model.parameter(name).lower for name in intensity_terms(model)]
        if any(bound not in (0.0, -math.inf) for bound in lower):
            raise ParameterError(f"{model.name}: linear parameters need a lower bound of 0 or none")
        self.raw_data, self.level, self.scale = data, None, None  # (N, B) BRDF [sr^-1]
        if levels is not None:  # relative to each group's level (N, B), and the class's mean level (B,)
            relative, self.level = levels.relative(data)
            self.scale = self.level.mean(axis=0)
            self.raw_data = relative * (self.scale if group_model is None else group_model)
        self.constant = self._constant_terms() if levels is not None else ()
        self.terms = tuple(name for name in intensity_terms(model) if name not in self.constant)
        # Columns of the raw design: those of ``terms``, and of the constant (with free levels).
        self.kept = [j for j, name in enumerate(intensity_terms(model)) if name in self.terms]
        self.constant_index = intensity_terms(model).index(self.constant[0]) if self.constant else None
        self.data = data if levels is None else levels.demean(self.raw_data)
        self.nonnegative = np.array([bound == 0.0 for name, bound in zip(intensity_terms(model), lower)
                                     if name in self.terms])
        self.n = data.shape[0]
        self.sum_y = self.data.sum(axis=0)
        self.sum_yy = np.einsum("nb,nb->b", self.data, self.data)
        variance = self.sum_yy / self.n - (self.sum_y / self.n) ** 2
        # Inverse-variance band weights; a constant band carries no shape information.
        self.weights = np.where(variance > 0, 1.0 / np.where(variance > 0, variance, 1.0), 0.0)

    def holding(self, name: str, value: float) -> _LinearProfile:
        """This profile with the free shape parameter ``name`` held at ``value`` (the same data
        and sums; one free shape parameter fewer)."""
        held = copy.copy(self)
        held.fixed = {**self.fixed, name: value}
        held.ranges = {key: search for key, search in self.ranges.items() if key != name}
        return held

    def residuals(self, design: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
        """The (N, B) residuals of the data the profile fits (within groups where the levels are
        free) from ``design @ coefficients`` [sr^-1]."""
        return self.data - design @ coefficients

    def raw_design(self, shape: Mapping[str, float]) -> np.ndarray:
        """The (N, m) design matrix of every linear term of the model at a trial shape."""
        terms = self.model.terms(self.geometry, {**self.fixed, **shape})
        n = self.geometry.theta_i.size
        return np.column_stack([np.broadcast_to(np.asarray(t, dtype=float), (n,)) for t in terms])

    def design(self, shape: Mapping[str, float]) -> np.ndarray:
        """The (N, m) design matrix: one column per linear term of :attr:`terms`, at a trial
        shape (within groups where the levels are free)."""
        design = self.raw_design(shape)
        if self.levels is None:
            return design
        return self.levels.demean(design[:, self.kept])

    def _constant_terms(self) -> tuple[str, ...]:
        """The linear terms whose column is the same at every sample (the level: t0, f_iso), at
        the middle of the shape's search ranges."""
        middle = {name: (math.sqrt(low * high) if logarithmic else 0.5 * (low + high))
                  for name, (low, high, logarithmic) in self.ranges.items()}
        design = self.raw_design(middle)
        return tuple(name for name, column in zip(intensity_terms(self.model), design.T)
                     if np.ptp(column) == 0 and column[0] != 0)

    def full_intensities(self, shape: Mapping[str, float], coefficients: np.ndarray) -> np.ndarray:
        """Every linear term's intensities (model order; (m_all, B)) from those of :attr:`terms`
        (m, B): with free levels the constant term restored from the data's mean
        (:func:`brdfcorr.fit.within.restored_constant`; kept >= 0 if its lower bound is 0; one
        constant at most)."""
        if self.constant_index is None:
            return coefficients
        index, kept = self.constant_index, self.kept
        raw_means = self.raw_design(shape).mean(axis=0)
        constant = restored_constant(self.raw_data.mean(axis=0), raw_means[kept], coefficients, raw_means[index])
        if self.model.parameter(self.constant[0]).lower == 0.0:
            constant = np.maximum(constant, 0.0)
        full = np.empty((len(raw_means), coefficients.shape[1]))
        full[kept], full[index] = coefficients, constant
        return full

    def products(self, design: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``design.T @ design`` (m, m) and ``design.T @ data`` (m, B): the one pass over the data.

        By einsum, not BLAS: the tall-skinny products are memory-bound, so BLAS threads gain
        nothing, and on a loaded machine they stall at every one of their many barriers.
        """
        return np.einsum("nk,nl->kl", design, design), np.einsum("nk,nb->kb", design, self.data)

    def solve(self, design: np.ndarray):
        """Per-band linear coefficients (m, B) and sums of squared residuals (B,).

        Least squares with the terms whose lower bound is 0 kept >= 0 (those with lower bound -inf
        are free), exactly: where the unconstrained solution keeps them >= 0 in every band it is
        the answer; else every face of the constraint box (which terms are free) is solved from
        the normal equations and the best feasible one kept per band (2^m - 1 small solves, all
        faces of a size and all bands at once). Terms the geometry cannot tell apart (a
        near-singular face) are left at 0. The data enter through one product ``design.T @ data``.
        """
        gram, cross = self.products(design)
        m, n_bands = cross.shape
        by_size, count = _faces(m)
        everything = by_size[m][1]
        full = self._solved(gram, cross, everything)
        if full[1].all():  # the unconstrained optimum is feasible in every band: the optimum
            return full[0][0], np.maximum(full[2][0], 0.0)
        coefficients = np.zeros((count, m, n_bands))
        feasible, ssr = np.zeros((count, n_bands), dtype=bool), np.empty((count, n_bands))
        for size, (positions, faces) in by_size.items():
            values, feasible[positions], ssr[positions] = full if size == m else self._solved(gram, cross, faces)
            coefficients[positions[:, None], faces] = values
        # Per band the first face (in itertools.product order) of least ssr, by more than rounding.
        winner, best_ssr = np.full(n_bands, -1), self.sum_yy.copy()  # -1: every coefficient 0
        for face in range(count):
            better = feasible[face] & (ssr[face] < best_ssr - 1e-12 * np.abs(best_ssr))
            winner, best_ssr = np.where(better, face, winner), np.where(better, ssr[face], best_ssr)
        best = np.where(winner >= 0, coefficients[winner, :, np.arange(n_bands)].T, 0.0)
        return best, np.maximum(best_ssr, 0.0)

    def _solved(self, gram: np.ndarray, cross: np.ndarray, faces: np.ndarray):
        """For faces of k terms each ((F, k) term indices; the others 0): their least-squares
        coefficients (F, k, B), whether they are feasible per band (F, B) and the sums of squared
        residuals left (F, B). A face whose terms are (nearly) collinear (condition number of the
        scaled Gram matrix > 1e12) is never feasible."""
        sub = gram[faces[:, :, None], faces[:, None, :]]  # (F, k, k)
        scale = np.sqrt(np.diagonal(sub, axis1=1, axis2=2))
        usable = np.all(scale > 0, axis=1)
        usable[usable] = ~(np.linalg.cond(sub[usable] / (scale[usable, :, None] * scale[usable, None, :])) > 1e12)
        values = np.zeros(faces.shape + cross.shape[1:])
        if usable.any():
            values[usable] = np.linalg.solve(sub[usable], cross[faces[usable]])
        feasible = usable[:, None] & np.all((values >= 0) | ~self.nonnegative[faces][:, :, None], axis=1)
        return values, feasible, self.sum_yy - np.einsum("fkb,fkb->fb", values, cross[faces])  # at each face's optimum

    def objective(self, shape: Mapping[str, float]) -> float:
        return float(self.solve(self.design(shape))[1] @ self.weights)

    def angular_r2(self, design: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
        """How much of the *angular* signal the fit explains, per band (NaN where there is none).

        The samples are binned by geometry (:func:`geometry_bins`); the bin means average out
        albedo texture and noise, which are independent of the geometry, and leave the angular
        signal. This is R^2 of the bin means of the fit against those of the data, weighted by the
        bin counts: ~1 for a model that follows the angular signal however textured the class is,
        ~0 for one that explains none of it (plain R^2 is small for both on textured surfaces).
        The scatter the bin means keep (within-bin variance / count) is subtracted from both sums
        of squares, as in an adjusted R^2, so that few samples per bin do not read as misfit; NaN
        where no angular signal stands out of that scatter. The fit's bin means are those of the
        design columns times the coefficients (linear), so no (N, B) prediction is formed.
        """
        index = geometry_bins(self.geometry.theta_i, self.geometry.theta_r, self.geometry.phi)
        count = np.bincount(index).astype(float)
        keep = count >= MIN_BIN_COUNT
        if not keep.any():  # too few samples per geometry bin to tell the angular signal
            return np.full(self.data.shape[1], np.nan)
        indicator = scipy.sparse.csr_matrix(
            (np.ones(index.size), (index, np.arange(index.size))), shape=(count.size, index.size)
        )[keep]
        count = count[keep]
        observed = (indicator @ self.data) / count[:, None]  # (K, B)
        fitted = ((indicator @ design) / count[:, None]) @ coefficients  # (K, B)
        kept = keep[index]
        sum_yy = self.sum_yy if kept.all() else np.einsum("nb,nb->b", self.data[kept], self.data[kept])
        n_bins, n_kept = count.size, count.sum()
        scatter = np.maximum(sum_yy - count @ observed**2, 0.0) / max(n_kept - n_bins, 1.0)  # within-bin variance
        mean = count @ observed / n_kept
        total = count @ (observed - mean) ** 2 - (n_bins - 1) * scatter
        residual = np.maximum(count @ (observed - fitted) ** 2 - (n_bins - design.shape[1]) * scatter, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(total > 0, 1.0 - residual / np.where(total > 0, total, 1.0), np.nan)

    def r2(self, ssr: np.ndarray) -> np.ndarray:
        """Coefficient of determination per band (NaN for a constant band)."""
        total = self.sum_yy - self.sum_y**2 / self.n
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(total > 0, 1.0 - ssr / np.where(total > 0, total, 1.0), np.nan)


#: Geometry bins of :func:`geometry_bins` [deg] and the fewest samples a bin needs to count.
SUN_ZENITH_STEP, VIEW_ZENITH_STEP, MIN_BIN_COUNT = 5.0, 2.0, 10


def geometry_bins(theta_i, theta_r, phi) -> np.ndarray:
    """A bin number per sample: sun zenith in 5 deg steps, view zenith in 2 deg steps, and the
    half of the azimuth circle (backward phi < 90 deg or forward), the across-track geometry of a
    flight line."""
    sun = np.floor(np.asarray(theta_i) / SUN_ZENITH_STEP).astype(np.int64)
    view = np.floor(np.asarray(theta_r) / VIEW_ZENITH_STEP).astype(np.int64)
    forward = (np.asarray(phi) >= 90.0).astype(np.int64)
    _, index = np.unique(np.stack([sun, view, forward]), axis=1, return_inverse=True)
    return index.reshape(-1)


def _profile(model, theta_i, theta_r, phi, brdf, fixed, subset=None, levels: Levels | None = None,
             group_model: np.ndarray | None = None) -> _LinearProfile:
    angles = [np.asarray(a, dtype=float).reshape(-1) for a in (theta_i, theta_r, phi)]
    data = np.asarray(brdf, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    if subset is not None:
        angles, data = [a[subset] for a in angles], data[subset]
        levels = None if levels is None else levels.subset(subset)
    return _LinearProfile(model, ScatteringGeometry(*angles), data, fixed, levels, group_model)
