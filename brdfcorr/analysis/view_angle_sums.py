"""The chunk-wise sums behind :func:`brdfcorr.analysis.view_angles.assess_view_angles`: per block
of the before and after cubes, the sums of reflectance, signed view zenith and their products per
class and band (:class:`_Sums`), by bin of view zenith, by side of nadir and by spatial block
(:class:`_ClusterSums`, for the cluster-robust errors); dask adds the blocks' sums in a tree and
computes them in one pass (:func:`_scene_sums`). Square blocks and clusters are placed in the
scene, not in a dask block: one cut by a dask block's edge is summed over the scene before its outer
products are taken, so no statistic depends on the chunking.

The blocks' sums v = (n, Σθ, Σθ², ΣR, ΣθR) are taken about a pivot, each class's means in the
dask block (the signed zenith centred per pixel, the reflectance per square block: :func:`_shift`),
moved to their weighted mean as two blocks' sums are added, and the scene's outer products end
about the scene's class means. Uncentred, a class far from nadir (θ̄ = 52°) with small residuals lost its
1-sigma to cancellation (5x too large at noise 1e-5).
"""

from __future__ import annotations

import dataclasses
import operator
from dataclasses import dataclass
from typing import Literal

import dask
import dask.array as da
import numpy as np

from brdfcorr.analysis.signed_view import signed_view_zenith

__all__: list[str] = []


@dataclass
class _Sums:
    """Sums over valid pixels from which every statistic follows: K classes, B bands, 2 stages,
    M bins of signed view zenith, 2 sides (negative, positive)."""

    n: np.ndarray       # (K,) pixels
    s: np.ndarray       # (K,) sum of the signed zenith [deg]
    ss: np.ndarray      # (K,) sum of its square [deg^2]
    r: np.ndarray       # (2, B, K) sum of reflectance
    sr: np.ndarray      # (2, B, K) sum of signed zenith times reflectance
    bin_n: np.ndarray   # (K, M)
    bin_s: np.ndarray   # (K, M) sum of the signed zenith per bin [deg]
    bin_r: np.ndarray   # (2, B, K, M)
    side_n: np.ndarray  # (K, 2)
    side_r: np.ndarray  # (2, B, K, 2)
    squares: _SquareSums  # square blocks of the block size, for the slope's cluster-robust error
    squares2: _SquareSums  # the same for blocks of twice the size
    clusters: _ClusterSums  # v per (class, cluster id) of the cluster layer, added over the whole scene
    pivot: tuple[np.ndarray, np.ndarray]  # θ (K,) [deg], R (2, B, K) about which those three are taken

    def __add__(self, other: _Sums) -> _Sums:
        added = {name: getattr(self, name) + getattr(other, name) for name in _PLAIN_SUMS}
        weights = [np.where(added["n"] > 0, part.n / np.where(added["n"] > 0, added["n"], 1), 0.5)
                   for part in (self, other)]
        pivot = tuple(weights[0] * first + weights[1] * second for first, second in zip(self.pivot, other.pivot))
        moves = [_shift(part.pivot, pivot) for part in (self, other)]
        for name in _PIVOTED:
            added[name] = getattr(self, name).moved(moves[0]) + getattr(other, name).moved(moves[1])
        return _Sums(**added, pivot=pivot)

    def centred(self) -> _Sums:
        """The sums with those of :data:`_PIVOTED` about the class means (what
        :func:`brdfcorr.analysis.view_angles._cluster_error` takes), every square block closed."""
        count = np.where(self.n > 0, self.n, 1.0)
        means = (np.where(self.n > 0, self.s / count, 0.0), np.where(self.n > 0, self.r / count, 0.0))
        move = _shift(self.pivot, means)
        moved = {name: getattr(self, name).moved(move) for name in _PIVOTED}
        return dataclasses.replace(self, squares=moved["squares"].closed(), squares2=moved["squares2"].closed(),
                                   clusters=moved["clusters"], pivot=means)


#: The fields of :class:`_Sums` that two blocks' sums add as they are, and those taken about its pivot.
_PLAIN_SUMS = ("n", "s", "ss", "r", "sr", "bin_n", "bin_s", "bin_r", "side_n", "side_r")
_PIVOTED = ("squares", "squares2", "clusters")


def _shift(old: tuple[np.ndarray, np.ndarray], new: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(2, B, K, 5, 5): the matrix T that takes a block's v = (n, Σθ, Σθ², ΣR, ΣθR) about the
    pivot ``old`` (per class θ (K,) [deg] and R (2, B, K) [1]) to v about ``new``: with
    d = θ_old − θ_new and e = R_old − R_new, Σ(θ + d) = Σθ + n d, Σ(θ + d)² = Σθ² + 2 d Σθ + n d², Σ(R + e) = ΣR + n e
    and Σ(θ + d)(R + e) = ΣθR + e Σθ + d ΣR + n d e."""
    d_r = old[1] - new[1]
    d = np.broadcast_to(old[0] - new[0], d_r.shape)
    shift = np.zeros((*d_r.shape, 5, 5))
    shift[..., np.arange(5), np.arange(5)] = 1.0
    shift[..., 1, 0], shift[..., 2, 0], shift[..., 2, 1] = d, d * d, 2 * d
    shift[..., 3, 0] = d_r
    shift[..., 4, 0], shift[..., 4, 1], shift[..., 4, 3] = d * d_r, d_r, d
    return shift


@dataclass
class _ClusterSums:
    """Per (class index, cluster id) of a cluster layer, or per (class index, square block's number
    in the scene) (``keys``, (L, 2)), the sums v = (n, Σθ,
    Σθ², ΣR, ΣθR) of each stage and band (``vectors``, (L, 2, B, 5)). A cluster or block may
    span dask blocks, so the sums are added over the scene before their outer products are taken."""

    keys: np.ndarray
    vectors: np.ndarray

    def __add__(self, other: _ClusterSums) -> _ClusterSums:
        keys, member = np.unique(np.concatenate([self.keys, other.keys]), axis=0, return_inverse=True)
        vectors = np.zeros((keys.shape[0], *self.vectors.shape[1:]))
        np.add.at(vectors, member.reshape(-1), np.concatenate([self.vectors, other.vectors]))
        return _ClusterSums(keys, vectors)

    def moved(self, shift: np.ndarray) -> _ClusterSums:
        """The sums about other class means (``shift``: :func:`_shift`)."""
        return _ClusterSums(self.keys, np.einsum("sblij,lsbj->lsbi", shift[:, :, self.keys[:, 0]], self.vectors))

    def moments(self, n_classes: int) -> tuple[np.ndarray, np.ndarray]:
        """Per class the clusters holding its pixels, (K,), and Σ_g v_g v_gᵀ over them, (2, B, K, 5, 5)."""
        owner = _one_hot(self.keys[:, 0], n_classes)
        return owner.sum(axis=0), _moments(self.vectors, owner)


@dataclass
class _SquareSums:
    """The sums over square blocks of one size behind the slope's cluster-robust error: of the
    blocks that lie wholly within one dask block, per class their number (``blocks``, (K,)) and
    Σ_g v_g v_gᵀ (``moments``, (2, B, K, 5, 5), v = (n, Σθ, Σθ², ΣR, ΣθR) of a block); those cut
    by a dask block's edge are kept as sums keyed by their place in the scene (``cut``) until the
    whole scene's are added (:meth:`closed`), so that the blocks do not depend on the chunking."""

    blocks: np.ndarray
    moments: np.ndarray
    cut: _ClusterSums

    def __add__(self, other: _SquareSums) -> _SquareSums:
        return _SquareSums(self.blocks + other.blocks, self.moments + other.moments, self.cut + other.cut)

    def moved(self, shift: np.ndarray) -> _SquareSums:
        """The sums about other class means (``shift``: :func:`_shift`): T M Tᵀ, T v."""
        return _SquareSums(self.blocks, np.einsum("...ij,...jl,...ml->...im", shift, self.moments, shift),
                           self.cut.moved(shift))

    def closed(self) -> _SquareSums:
        """Every block counted and in the moments, none left cut (once the whole scene is added)."""
        blocks, moments = self.cut.moments(self.blocks.shape[0])
        empty = _ClusterSums(self.cut.keys[:0], self.cut.vectors[:0])
        return _SquareSums(self.blocks + blocks, self.moments + moments, empty)


def _class_index(classes: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Index of each pixel's class in ``ids`` (sorted), -1 for other values (0, nodata, NaN)."""
    position = np.clip(np.searchsorted(ids, classes), 0, max(len(ids) - 1, 0))
    found = (ids[position] == classes) if len(ids) else np.zeros(classes.shape, bool)
    return np.where(found, position, -1)


@dataclass(frozen=True, eq=False)
class _SumOptions:
    """How :func:`_block_sums` sums a block.

    Attributes
    ----------
    ids : numpy.ndarray
        The class ids assessed, sorted.
    edges : numpy.ndarray
        Edges of the bins of signed view zenith [deg], increasing.
    by, heading :
        The sign convention and the flight direction [deg] (:func:`signed_view_zenith`).
    min_vza : float
        The smallest |signed view zenith| [deg] that counts for a side of nadir.
    flip_view_azimuth : bool
        ``vaa`` is stored as seen from the sensor: add 180 deg.
    block_size : int
        Side [pixels] of the square blocks of the slope's cluster-robust error, counted from the
        scene's first pixel (a block may span dask blocks); the sums are also taken over blocks of
        twice the size.
    cluster_nodata : float, optional
        The cluster layer's nodata value: pixels holding it (or a non-finite id) are left out.
    """

    ids: np.ndarray
    edges: np.ndarray
    by: Literal["sun", "track"]
    heading: float | None
    min_vza: float
    flip_view_azimuth: bool
    block_size: int
    cluster_nodata: float | None = None


@dataclass(frozen=True)
class _Window:
    """Where a dask block lies in the scene [pixels]: its first row and column, and the scene's
    height and width (the square blocks are counted from the scene's first pixel)."""

    row: int
    column: int
    height: int
    width: int


def _one_hot(index: np.ndarray, n: int) -> np.ndarray:
    """(len(index), n): 1 where column ``index[g]`` of row g, else 0."""
    owner = np.zeros((index.shape[0], n))
    owner[np.arange(index.shape[0]), index] = 1.0
    return owner


def _inside(index: np.ndarray, size: int, start: int, length: int, total: int) -> np.ndarray:
    """Whether the blocks ``index`` of ``size`` pixels along an axis of ``total`` pixels (the last
    block cut at the scene's edge) lie wholly within the pixels start..start + length - 1."""
    return (index * size >= start) & (np.minimum((index + 1) * size, total) <= start + length)


def _spatial_blocks(valid: np.ndarray, k: np.ndarray, size: int,
                    window: _Window) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each valid pixel's (class, square block of ``size`` pixels of the scene) group, numbered
    0..G-1 (``member``); the groups' keys (G, 2): class index and the block's number in the scene
    (row by row); whether each group's block lies wholly within this dask block (G,)."""
    rows, columns = np.nonzero(valid)  # the order of boolean indexing
    per_row = -(-window.width // size)
    cells = per_row * -(-window.height // size)
    block = ((rows + window.row) // size) * per_row + (columns + window.column) // size
    labels, member = np.unique(k * cells + block, return_inverse=True)
    keys = np.stack(np.divmod(labels, cells), axis=1)
    block_row, block_column = np.divmod(keys[:, 1], per_row)
    inside = (_inside(block_row, size, window.row, valid.shape[0], window.height)
              & _inside(block_column, size, window.column, valid.shape[1], window.width))
    return member.reshape(-1), keys, inside


def _square_vectors(valid: np.ndarray, k: np.ndarray, s: np.ndarray, cubes, size: int,
                    window: _Window) -> tuple[_ClusterSums, np.ndarray]:
    """The sums v per (class, square block of ``size`` pixels of the scene) of one dask block
    (``valid``: (y, x) mask; ``k``, ``s``: the valid pixels' class index and signed zenith [deg];
    ``cubes``: each stage's (B, valid pixels)), and whether each block lies wholly within it."""
    member, keys, inside = _spatial_blocks(valid, k, size, window)
    return _ClusterSums(keys, _group_vectors(member, keys.shape[0], s, cubes)), inside


def _square_sums(blocks: _ClusterSums, inside: np.ndarray, n_classes: int) -> _SquareSums:
    """:class:`_SquareSums` of the square blocks' sums ``blocks`` (:func:`_square_vectors`)."""
    owner = _one_hot(blocks.keys[inside, 0], n_classes)
    return _SquareSums(owner.sum(axis=0), _moments(blocks.vectors[inside], owner),
                       _ClusterSums(blocks.keys[~inside], blocks.vectors[~inside]))


def _group_vectors(member: np.ndarray, size: int, s: np.ndarray, cubes) -> np.ndarray:
    """(G, 2, B, 5): per group of ``member`` (0..size-1 per valid pixel) the sums v = (n, Σθ, Σθ²,
    ΣR, ΣθR) of each stage's cube (B, valid pixels) and band."""
    vectors = np.empty((size, 2, cubes[0].shape[0], 5))
    for position, weights in enumerate((None, s, s * s)):
        vectors[..., position] = np.bincount(member, weights=weights, minlength=size)[:, None, None]
    for stage, cube in enumerate(cubes):
        for band, values in enumerate(cube):
            vectors[:, stage, band, 3] = np.bincount(member, weights=values, minlength=size)
            vectors[:, stage, band, 4] = np.bincount(member, weights=s * values, minlength=size)
    return vectors


def _moments(vectors: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """(2, B, K, 5, 5): per class (``owner``, (G, K) one-hot) the sum over its groups of v vᵀ."""
    return np.einsum("gk,gsbi,gsbj->sbkij", owner, vectors, vectors)


def _cluster_sums(clusters: np.ndarray | None, k: np.ndarray, s: np.ndarray, cubes) -> _ClusterSums:
    """:class:`_ClusterSums` of the valid pixels' cluster ids (empty without a layer)."""
    if clusters is None:
        return _ClusterSums(np.zeros((0, 2), np.int64), np.zeros((0, 2, cubes[0].shape[0], 5)))
    keys, member = np.unique(np.stack([k, clusters.astype(np.int64)], axis=1), axis=0, return_inverse=True)
    return _ClusterSums(keys, _group_vectors(member.reshape(-1), keys.shape[0], s, cubes))


def _block_sums(before, after, classes, vza, vaa, saa, clusters, options: _SumOptions,
                window: _Window | None = None) -> _Sums:
    """:class:`_Sums` of one block: cubes (band, y, x), layers (y, x), numpy; ``window``: where
    the block lies in the scene (default: the block is the whole scene)."""
    ids, edges, min_vza = options.ids, options.edges, options.min_vza
    n_bands, n_classes, n_bins = before.shape[0], len(ids), len(edges) - 1
    vaa = vaa + 180.0 if options.flip_view_azimuth else vaa
    with np.errstate(invalid="ignore"):
        signed = signed_view_zenith(vza.astype(np.float64), vaa, saa, by=options.by, heading=options.heading)
        valid = (vza >= 0) & (vza < 90) & np.isfinite(signed)
    valid &= np.isfinite(before).all(axis=0) & np.isfinite(after).all(axis=0)
    if clusters is not None:
        valid &= np.isfinite(clusters)
        if options.cluster_nodata is not None:
            valid &= clusters != options.cluster_nodata
    index = _class_index(classes, ids)
    valid &= index >= 0
    k, s = index[valid], signed[valid]
    cubes = (before[:, valid].astype(np.float64), after[:, valid].astype(np.float64))
    bins = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, n_bins - 1)  # the last edge closes the last bin
    groups = k * n_bins + bins
    outer = np.abs(s) >= max(min_vza, np.finfo(float).tiny)  # 0 (nadir, or perpendicular) is on neither side
    sides = k[outer] * 2 + (s[outer] > 0)
    window = window or _Window(0, 0, *valid.shape)
    # About the block's class means (the pivot) the sums per (class, square block of the scene) and
    # per cluster, whose outer products give the slope's cluster-robust error (_cluster_error): the
    # signed zenith centred per pixel, the reflectance per square block and cluster; the class
    # sums are the square blocks' added and moved back to 0.
    counts = np.bincount(k, minlength=n_classes)
    theta = np.bincount(k, weights=s, minlength=n_classes) / np.where(counts > 0, counts, 1)
    s_centred = s - theta[k]
    blocks, inside = _square_vectors(valid, k, s_centred, cubes, options.block_size, window)
    about_theta = np.einsum("gk,gsbi->sbki", _one_hot(blocks.keys[:, 0], n_classes), blocks.vectors)
    no_reflectance = np.zeros_like(about_theta[..., 3])
    pivot = (theta, about_theta[..., 3] / np.where(counts > 0, counts, 1))
    to_pivot = _shift((theta, no_reflectance), pivot)
    class_sums = np.einsum("sbkij,sbkj->sbki", _shift((theta, no_reflectance), (0 * theta, no_reflectance)),
                           about_theta)
    blocks2, inside2 = _square_vectors(valid, k, s_centred, cubes, 2 * options.block_size, window)
    sums = _Sums(
        *(class_sums[0, 0, :, position] for position in range(3)), r=class_sums[..., 3], sr=class_sums[..., 4],
        bin_n=np.bincount(groups, minlength=n_classes * n_bins).astype(np.float64).reshape(n_classes, n_bins),
        bin_s=np.bincount(groups, weights=s, minlength=n_classes * n_bins).reshape(n_classes, n_bins),
        bin_r=np.zeros((2, n_bands, n_classes, n_bins)),
        side_n=np.bincount(sides, minlength=n_classes * 2).astype(np.float64).reshape(n_classes, 2),
        side_r=np.zeros((2, n_bands, n_classes, 2)),
        squares=_square_sums(blocks.moved(to_pivot), inside, n_classes),
        squares2=_square_sums(blocks2.moved(to_pivot), inside2, n_classes),
        clusters=_cluster_sums(None if clusters is None else clusters[valid], k, s_centred, cubes).moved(to_pivot),
        pivot=pivot,
    )
    for stage, cube in enumerate(cubes):
        for band, values in enumerate(cube):
            sums.bin_r[stage, band] = np.bincount(groups, weights=values,
                                                  minlength=n_classes * n_bins).reshape(n_classes, n_bins)
            sums.side_r[stage, band] = np.bincount(sides, weights=values[outer],
                                                   minlength=n_classes * 2).reshape(n_classes, 2)
    return sums


def _tree_sum(parts: list):
    """Add delayed partial sums pairwise (a tree: few partial results alive at once)."""
    while len(parts) > 1:
        parts = [dask.delayed(operator.add)(*parts[i:i + 2]) if i + 1 < len(parts) else parts[i]
                 for i in range(0, len(parts), 2)]
    return parts[0]


def _scene_sums(arrays: list, options: _SumOptions, compute: dict) -> _Sums:
    """:class:`_Sums` of whole arrays (before, after, classes, vza, vaa, saa, clusters): directly for numpy,
    per dask block and added in a tree otherwise (one compute; every block read once)."""
    if not any(isinstance(a, da.Array) for a in arrays):
        total = _block_sums(*(None if a is None else np.asarray(a) for a in arrays), options)
    else:
        cube = next(a for a in arrays[:2] if isinstance(a, da.Array))
        spatial = cube.chunks[1:]
        starts = [np.cumsum((0, *sizes[:-1])) for sizes in spatial]
        cubes = [da.asarray(a).rechunk((-1, *spatial)).to_delayed()[0] for a in arrays[:2]]
        layers = [None if a is None else da.asarray(a).rechunk(spatial).to_delayed() for a in arrays[2:]]
        block = dask.delayed(_block_sums, pure=True)
        parts = [
            block(cubes[0][i, j], cubes[1][i, j], *(None if layer is None else layer[i, j] for layer in layers),
                  options, _Window(int(starts[0][i]), int(starts[1][j]), *cube.shape[1:]))
            for i in range(len(spatial[0])) for j in range(len(spatial[1]))
        ]
        (total,) = dask.compute(_tree_sum(parts), **compute)
    return total.centred()
