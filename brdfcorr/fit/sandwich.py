"""The errors of a class fit: the joint sandwich covariance of its shape and intensities, with
small-sample corrections for few spatial blocks.

One covariance over the free shape parameters and every band's intensities
(:func:`_joint_covariance`): the Gauss-Newton Hessian of the whole weighted residual as the bread,
the outer products of per-cluster score sums as the meat (spatial blocks; each sample its own
cluster without them). It is valid for heteroscedastic noise (multiplicative sensor noise), for
noise correlated within blocks (albedo, texture) and across bands, and it keeps the covariance
between the intensities and the shape.

With few clusters the plain (CR0/CR1) cluster-robust sandwich is biased low and, worse, noisy: its
pulls ``(fit - truth) / error`` follow a t distribution with few degrees of freedom, whose standard
deviation exceeds 1 (issue 27: 1.3-1.7 with the 6 blocks of a 50 x 80-pixel scene). Two corrections,
after Bell and McCaffrey (2002) and Pustejovsky and Tipton (2018):

- **CR2** (bias-reduced linearization): each cluster's score sum is adjusted by the inverse square
  root of one minus its leverage, ``s~_g = (I - H_g H^-1)^(-1/2) s_g`` with ``H_g`` the cluster's part
  of the bread (:func:`_leverage`, :func:`_adjust`); exactly unbiased for a linear model with
  independent, equal-variance errors. Without clusters it is HC2 (MacKinnon and White 1985).
- **Effective degrees of freedom** per parameter, the Satterthwaite approximation of Bell and
  McCaffrey under that working model (:func:`_satterthwaite_dof`): G - 1 for balanced clusters,
  fewer where a few clusters carry the information. The solver turns them into calibrated errors
  and the ``errors_reliable`` flag (:mod:`brdfcorr.fit.solver`).

For the shape parameters the CR2 adjustment and the degrees of freedom are those of the profile
regression with the intensities projected out (Frisch-Waugh-Lovell: the efficient scores and the
Schur complement S), for the intensities those of the linear regression on the design; the
joint leverage across both is not formed (it would need a (k + mB)-square matrix per cluster).
On a linear model (kernel-driven models, no shape) the result is the exact CR2/HC2 sandwich.

Every sum runs over row blocks (:data:`ROW_BLOCK`) or sparse cluster indicators, so no (N, B)
array of residuals is formed without clusters. The fit itself is in :mod:`brdfcorr.fit.solver`.

References
----------
.. [1] H. White (1980): A heteroskedasticity-consistent covariance matrix estimator. Econometrica 48, 817-838.
.. [2] K.-Y. Liang, S. L. Zeger (1986): Longitudinal data analysis using generalized linear models.
   Biometrika 73, 13-22.
.. [3] J. G. MacKinnon, H. White (1985): Some heteroskedasticity-consistent covariance matrix estimators
   with improved finite sample properties. J. Econometrics 29, 305-325 (HC2).
.. [4] R. M. Bell, D. F. McCaffrey (2002): Bias reduction in standard errors for linear regression with
   multi-stage samples. Survey Methodology 28, 169-181 (CR2 and its degrees of freedom).
.. [5] J. E. Pustejovsky, E. Tipton (2018): Small-sample methods for cluster-robust variance estimation
   and hypothesis testing in fixed effects models. J. Business & Economic Statistics 36, 672-683.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse

if TYPE_CHECKING:
    from brdfcorr.fit.profile import _LinearProfile

#: Largest leverage eigenvalue used in the CR2 adjustment: a cluster that alone determines a
#: parameter combination (leverage 1) has no residual to estimate its variance from.
LEVERAGE_CLIP = 1.0 - 1e-9


@dataclass(frozen=True)
class Sandwich:
    """The joint covariance of a class fit with its small-sample diagnostics.

    Attributes
    ----------
    covariance : ndarray (B, k + m, k + m)
        Per band: the CR2 sandwich covariance of (free shape, band intensities).
    dof : ndarray (B, k + m)
        Effective (Bell-McCaffrey) degrees of freedom of each parameter's variance [-].
    n_clusters : int
        Number of clusters (samples without clusters).
    max_leverage : float
        Largest leverage eigenvalue of any cluster [-] (1: a cluster alone determines a parameter
        combination).
    scenes : bool
        The clusters counted are scenes (two-way errors, :mod:`brdfcorr.fit.two_way`, with fewer
        scenes than blocks), not spatial blocks.
    """

    covariance: np.ndarray
    dof: np.ndarray
    n_clusters: int
    max_leverage: float
    scenes: bool = False


@dataclass(frozen=True)
class _Leverage:
    """Per-cluster leverage of a regression with bread H (q, q) and cluster parts H_g (C, q, q):
    H^(1/2), H^(-1/2) and the eigen-decomposition of ``M_g = H^(-1/2) H_g H^(-1/2)``."""

    root: np.ndarray
    inverse_root: np.ndarray
    eigenvalues: np.ndarray  # (C, q), clipped to [0, LEVERAGE_CLIP]
    eigenvectors: np.ndarray  # (C, q, q)


def _leverage(bread: np.ndarray, parts: np.ndarray) -> _Leverage:
    """The leverage of every cluster (``parts`` (C, q, q) sum to ``bread``); directions the bread
    does not determine (zero eigenvalues) are left out through the pseudo-inverse root."""
    values, vectors = np.linalg.eigh(0.5 * (bread + bread.T))
    positive = values > values.max(initial=0.0) * 1e-12
    root = (vectors * np.sqrt(np.where(positive, values, 0.0))) @ vectors.T
    inverse_root = (vectors * np.where(positive, 1.0 / np.sqrt(np.where(positive, values, 1.0)), 0.0)) @ vectors.T
    leverage = inverse_root @ parts @ inverse_root  # (C, q, q), broadcast
    eigenvalues, eigenvectors = np.linalg.eigh(0.5 * (leverage + np.swapaxes(leverage, 1, 2)))
    return _Leverage(root, inverse_root, np.clip(eigenvalues, 0.0, LEVERAGE_CLIP), eigenvectors)


def _adjust(scores: np.ndarray, leverage: _Leverage) -> np.ndarray:
    """CR2-adjusted cluster score sums ``(I - H_g H^-1)^(-1/2) s_g = H^(1/2) (I - M_g)^(-1/2)
    H^(-1/2) s_g`` (Bell and McCaffrey 2002, eq. 7, written with the q x q leverage M_g of the
    cluster, which has the nonzero eigenvalues of its (n_g x n_g) hat block); ``scores`` (C, q) or
    (C, q, B)."""
    vectors, scale = leverage.eigenvectors, 1.0 / np.sqrt(1.0 - leverage.eigenvalues)
    trailing = scores.ndim == 2
    scores = scores[..., None] if trailing else scores
    normalized = leverage.inverse_root @ scores  # (C, q, B), broadcast
    adjusted = leverage.root @ (vectors @ (scale[:, :, None] * (np.swapaxes(vectors, 1, 2) @ normalized)))
    return adjusted[..., 0] if trailing else adjusted


def _satterthwaite_dof(leverage: _Leverage, contrasts: np.ndarray) -> np.ndarray:
    """Bell-McCaffrey degrees of freedom of the CR2 variance of each contrast ``c`` (columns of
    ``contrasts`` (q, J)): ``nu = (sum lambda)^2 / sum lambda^2`` over the eigenvalues lambda of
    ``G^T G``, the Gram matrix of the clusters' contributions under independent, equal-variance
    errors (Bell and McCaffrey 2002, section 5). With ``e = H^(-1/2) c``:
    ``(G^T G)_gh = delta_gh e^T M_g (I - M_g)^-1 e - q_g^T q_h``, ``q_g = M_g (I - M_g)^(-1/2) e``,
    so trace and Frobenius norm follow from q x q quantities per cluster. Balanced clusters give
    G - 1 (an intercept-only model exactly G - 1), one cluster 0."""
    vectors, values = leverage.eigenvectors, leverage.eigenvalues
    along = np.einsum("cqi,qj->cij", vectors, leverage.inverse_root @ contrasts)  # e in each eigenbasis
    diagonal = np.einsum("ci,cij->cj", values / (1.0 - values), along**2)  # (C, J)
    q = np.einsum("cqi,ci,cij->cqj", vectors, values / np.sqrt(1.0 - values), along)  # (C, q, J)
    trace = diagonal.sum(axis=0) - np.einsum("cqj,cqj->j", q, q)
    cross = np.einsum("cqj,crj->qrj", q, q)
    frobenius = (np.einsum("cj,cj->j", diagonal, diagonal) - 2.0 * np.einsum("cj,cqj,cqj->j", diagonal, q, q)
                 + np.einsum("qrj,qrj->j", cross, cross))
    # A degenerate Gram matrix (one cluster: its score sum is zero at the optimum) carries no
    # information on the variance: 0 degrees of freedom.
    usable = (frobenius > 0) & (trace > 0)
    return np.where(usable, trace**2 / np.where(usable, frobenius, 1.0), 0.0)


def _cluster_indicator(clusters: np.ndarray | None):
    """A sparse (clusters x samples) indicator matrix: one product sums every column per cluster
    (None without clusters: every sample its own cluster)."""
    if clusters is None:
        return None
    _, index = np.unique(clusters, return_inverse=True)
    index = index.reshape(-1)
    return scipy.sparse.csr_matrix(
        (np.ones(index.size), (index, np.arange(index.size))), shape=(index.max() + 1, index.size)
    )


def _cluster_sums(values: np.ndarray, indicator) -> np.ndarray:
    """Per-cluster sums of per-sample rows (the identity without clusters); any trailing shape."""
    if indicator is None:
        return values
    return (indicator @ values.reshape(values.shape[0], -1)).reshape(-1, *values.shape[1:])


#: Rows per block when a per-sample quantity of every band is needed: the temporaries stay small
#: instead of one (N, B) array per step.
ROW_BLOCK = 8192


def _row_blocks(n: int):
    return (slice(start, start + ROW_BLOCK) for start in range(0, n, ROW_BLOCK))


def _design_parts(design: np.ndarray, indicator) -> np.ndarray:
    """Each cluster's part of ``A^T A``, (C, m, m) (each sample's without clusters)."""
    return _cluster_sums(np.einsum("ni,nj->nij", design, design), indicator)


def _hat_scale(design: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """HC2's per-sample ``1 / (1 - h_p)``, ``h_p = a_p^T (A^T A)^-1 a_p`` (MacKinnon and White 1985)."""
    leverage = np.einsum("ni,ij,nj->n", design, inverse, design)
    return 1.0 / (1.0 - np.clip(leverage, 0.0, LEVERAGE_CLIP))


def _intensity_meat(design, coefficients, data, scale) -> np.ndarray:
    """Without clusters: the HC2 meat of the intensities per band, (B, m, m),
    ``sum_p a_pi a_pj r_pb^2 / (1 - h_p)``, block by block; no (N, B) residual array is formed."""
    m = design.shape[1]
    meat = np.empty((data.shape[1], m, m))
    pairs = [(i, j) for i in range(m) for j in range(i, m)]
    products = np.column_stack([design[:, i] * design[:, j] * scale for i, j in pairs])
    values = np.zeros((len(pairs), data.shape[1]))
    for rows in _row_blocks(data.shape[0]):
        residuals = data[rows] - design[rows] @ coefficients
        values += np.einsum("np,nb->pb", products[rows], residuals**2)
    for (i, j), value in zip(pairs, values):
        meat[:, i, j] = meat[:, j, i] = value
    return meat


def _intensity_scores(design, coefficients, data, indicator) -> np.ndarray:
    """With clusters: the intensity score sums ``u_gib = sum_(p in g) a_pi r_pb``, (C, m, B), one
    sparse pass over the data per term (``W_i y - (W_i A) c``, W_i the indicator weighted by a_i)."""
    summed = []
    for i in range(design.shape[1]):
        weighted = indicator.multiply(design[:, i][None, :]).tocsr()
        summed.append(weighted @ data - (weighted @ design) @ coefficients)  # (C, B)
    return np.stack(summed, axis=1)


def _design_derivatives(profile: _LinearProfile, shape: Mapping[str, float]) -> list[np.ndarray]:
    """``d design / d theta_i`` for each free shape parameter, (N, m) each, by central differences
    (steps 1e-3 relative); 0 in the columns that do not depend on the shape."""
    derivatives = []
    for name, value in shape.items():
        step = 1e-3 * max(abs(value), 1e-2)
        plus = profile.design({**shape, name: value + step})
        minus = profile.design({**shape, name: value - step})
        derivatives.append((plus - minus) / (2 * step))
    return derivatives


def _efficient_scores(profile, design, coefficients, derivatives, jacobian) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample efficient scores of the shape, (N, k), and each sample's part of the Schur
    complement, (N, k, k): with the efficient Jacobian ``g~_pb = g_pb - J_b^T a_p`` (``g_pb,i =
    (D_i c_b)_p`` the shape columns of the Jacobian, ``J_b`` (m, k) the Gauss-Newton derivative of
    the band's intensities with respect to the shape: the intensity columns projected out),
    ``e_p = sum_b w_b r_pb g~_pb`` and ``S_p = sum_b w_b g~_pb g~_pb^T``. Row blocks keep the
    (rows, B, k) temporaries small."""
    k = len(derivatives)
    scores, parts = np.empty((profile.n, k)), np.empty((profile.n, k, k))
    for rows in _row_blocks(profile.n):
        efficient = np.stack([d[rows] @ coefficients - design[rows] @ jacobian[:, :, i]
                              for i, d in enumerate(derivatives)], axis=-1)  # (rows, B, k)
        weighted = (profile.data[rows] - design[rows] @ coefficients) * profile.weights  # w_b r_pb
        scores[rows] = np.einsum("nb,nbk->nk", weighted, efficient)
        parts[rows] = np.einsum("nbk,nbl->nkl", efficient * profile.weights[:, None], efficient)
    return scores, parts


def _cross_scores(design, coefficients, data, influence) -> np.ndarray:
    """Without clusters: ``X_b = sum_p a_p r_pb psi_p^T`` per band, (B, m, k), the cross products
    of the intensity scores with the (HC2-scaled) shape influence ``psi`` (N, k), over row blocks."""
    m, k = design.shape[1], influence.shape[1]
    total = np.zeros((m * k, data.shape[1]))
    for rows in _row_blocks(data.shape[0]):
        residuals = data[rows] - design[rows] @ coefficients
        products = (design[rows][:, :, None] * influence[rows][:, None, :]).reshape(-1, m * k)
        total += np.einsum("np,nb->pb", products, residuals)  # einsum: see profile._LinearProfile.products
    return total.T.reshape(data.shape[1], m, k)


def _intensity_part(design, coefficients, data, indicator, small_sample: bool):
    """The intensities' own sandwich: ``(A^T A)^-1`` (m, m), the meat per band (B, m, m), the
    cluster scores (C, m, B; None without clusters), the per-sample HC2 scale (N,; None with
    clusters) and the leverage of the linear regression."""
    gram = np.einsum("nk,nl->kl", design, design)
    bread = np.linalg.pinv(gram)
    leverage = _leverage(gram, _design_parts(design, indicator))
    if indicator is None:
        scale = _hat_scale(design, bread) if small_sample else np.ones(design.shape[0])
        return bread, _intensity_meat(design, coefficients, data, scale), None, scale, leverage
    scores = _intensity_scores(design, coefficients, data, indicator)
    if small_sample:
        scores = _adjust(scores, leverage)
    return bread, np.einsum("cib,cjb->bij", scores, scores), scores, None, leverage


def _combined_dof(shape_dof: np.ndarray, linear_dof: np.ndarray, propagated, own) -> np.ndarray:
    """Degrees of freedom of an intensity's variance, which has an own part (the linear
    regression's, ``own`` (B, m), dof ``linear_dof`` (m,)) and a part propagated from the shape
    (``propagated`` (B, m), dof the smallest of ``shape_dof``): ``1/sqrt(nu) = s/sqrt(nu_shape) +
    (1 - s)/sqrt(nu_linear)`` with s the propagated share, the rule for two fully correlated
    variance estimates (their standard deviations add); an approximation, as the joint leverage is
    not formed."""
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(propagated + own > 0, propagated / (propagated + own), 0.0)
        inverse_root = share / np.sqrt(shape_dof.min()) + (1.0 - share) / np.sqrt(linear_dof)
        return 1.0 / inverse_root**2


def _joint_matrix(shape_block: np.ndarray, shape_intensity: np.ndarray, intensities_block: np.ndarray) -> np.ndarray:
    """The joint covariance per band, (B, k + m, k + m), from its blocks: the shape's (k, k), shared
    by the bands, the shape-intensity cross terms (B, k, m) and the intensities' (B, m, m)."""
    n_bands, k, m = shape_intensity.shape
    covariance = np.empty((n_bands, k + m, k + m))
    covariance[:, :k, :k] = shape_block
    covariance[:, :k, k:] = shape_intensity
    covariance[:, k:, :k] = np.swapaxes(shape_intensity, 1, 2)
    covariance[:, k:, k:] = intensities_block
    return covariance


def _joint_covariance(profile: _LinearProfile, shape, design, intensities, clusters=None,
                      small_sample: bool = True) -> Sandwich:
    """Joint sandwich covariance of (free shape, band intensities) per band, (B, k + m, k + m),
    with the effective degrees of freedom of each parameter (:class:`Sandwich`).

    The estimator minimizes ``Q = sum_b w_b sum_p r_pb^2`` over all free parameters phi (the shape
    theta, shared, and the intensities c_b of every band), ``r_pb = y_pb - a_p(theta) . c_b``. Its
    sandwich covariance is ``H^-1 M H^-1`` (White 1980; Liang and Zeger 1986 for clusters) with
    the bread ``H = J^T W J``, the Gauss-Newton Hessian over *all* free parameters (J the Jacobian
    of the model, W the band weights), and the meat ``M = sum_c s_c s_c^T``, the outer products of
    the per-cluster sums of the scores ``s_p = J_p^T W r_p`` (each sample its own cluster without
    ``clusters``), CR2-adjusted (:func:`_adjust`; module docstring) unless ``small_sample`` is
    False (then the plain CR0 sandwich, for checks). It holds for heteroscedastic noise and for
    noise correlated within clusters (spatial blocks) and across bands.

    H is block-arrow shaped (the intensity blocks ``w_b A^T A`` are diagonal across bands), so the
    influence ``psi_p = H^-1 s_p`` is solved by the Schur complement of the intensities,
    ``S = sum_b w_b G_b^T (I - A (A^T A)^-1 A^T) G_b`` (G_b the shape columns of the band's
    Jacobian): ``psi_theta = S^-1 e_p`` with the efficient scores e (:func:`_efficient_scores`), and
    ``psi_c_b = (A^T A)^-1 a_p r_pb - J_b psi_theta``, ``J_b = (A^T A)^-1 A^T G_b``. Every band's block of
    ``sum_c psi_c psi_c^T`` follows from cluster sums (C, k) and (C, m) per band; band weights cancel in its blocks.
    """
    coefficients = np.asarray(intensities)  # (m, B)
    n, n_bands = profile.data.shape
    m, k = design.shape[1], len(shape)
    indicator = _cluster_indicator(clusters)
    n_clusters = n if indicator is None else indicator.shape[0]
    bread, meat, scores, scale, linear = _intensity_part(design, coefficients, profile.data, indicator, small_sample)
    intensity_block = np.einsum("ij,bjk,kl->bil", bread, meat, bread)
    linear_dof = _satterthwaite_dof(linear, np.eye(m))
    if not k:
        return Sandwich(intensity_block, np.broadcast_to(linear_dof, (n_bands, m)).copy(), n_clusters,
                        float(linear.eigenvalues.max(initial=0.0)))
    derivatives = _design_derivatives(profile, shape)
    cross = [np.einsum("nk,nl->kl", design, d) for d in derivatives]  # A^T D_i (m, m)
    jacobian = np.stack([bread @ c @ coefficients for c in cross], axis=-1)  # J_b as (m, B, k)
    efficient, parts = _efficient_scores(profile, design, coefficients, derivatives, jacobian)
    schur = parts.sum(axis=0)
    shape_leverage = _leverage(schur, _cluster_sums(parts, indicator))
    summed = _cluster_sums(efficient, indicator)
    if small_sample:
        summed = _adjust(summed, shape_leverage)
    influence = summed @ np.linalg.pinv(schur)  # (C, k); S symmetric
    shape_block = influence.T @ influence  # (k, k)
    if scores is None:  # each sample its own cluster: HC2 scales a_p r_pb by 1 / sqrt(1 - h_p)
        x = _cross_scores(design, coefficients, profile.data, influence * np.sqrt(scale)[:, None])
    else:
        x = np.einsum("cmb,ck->bmk", scores, influence)  # (B, m, k)
    j = np.moveaxis(jacobian, 1, 0)  # (B, m, k)
    bread_x_jt = np.einsum("ml,blk,bnk->bmn", bread, x, j)
    propagated = np.einsum("bmk,kl,bnl->bmn", j, shape_block, j)
    intensities_block = intensity_block - bread_x_jt - np.swapaxes(bread_x_jt, 1, 2) + propagated
    shape_intensity = np.einsum("bmk,ml->bkl", x, bread) - np.einsum("kl,bml->bkm", shape_block, j)
    covariance = _joint_matrix(shape_block, shape_intensity, intensities_block)
    shape_dof = _satterthwaite_dof(shape_leverage, np.eye(k))
    dof = np.concatenate([np.broadcast_to(shape_dof, (n_bands, k)), _combined_dof(
        shape_dof, linear_dof, np.diagonal(propagated, axis1=1, axis2=2),
        np.diagonal(intensity_block, axis1=1, axis2=2))], axis=1)
    leverage = max(float(linear.eigenvalues.max(initial=0.0)), float(shape_leverage.eigenvalues.max(initial=0.0)))
    return Sandwich(covariance, dof, n_clusters, leverage)
