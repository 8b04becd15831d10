"""Pooling and sampling the pixels of each class from one or many scenes (for :mod:`brdfcorr.fit.classes`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from brdfcorr.errors import InputError, ParameterError
from brdfcorr.geometry import relative_azimuth

__all__ = ["ClassSamples", "sample_classes"]


@dataclass
class ClassSamples:
    """The pooled, sampled pixels of one class: angles [deg] and BRDF [sr^-1] per band."""

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi: np.ndarray
    brdf: np.ndarray  # (N, B)
    block: np.ndarray | None = None  # spatial block id of each sample (cluster for the errors)


def _class_values(class_map: xr.DataArray) -> np.ndarray:
    """The class ids of a class map in memory, its nodata (rioxarray's) read as 0, "no class"."""
    values = np.asarray(class_map.values)
    nodata = class_map.rio.nodata if hasattr(class_map, "rio") else None
    return np.where(values == nodata, 0, values) if nodata is not None else values


def _as_list(value) -> list:
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _scene_samples(scene: int, image, angle_set, shape, flat, reflectance_scale: float, block_size: int) -> tuple:
    """The samples of one scene (number ``scene``) at the flat pixel indices ``flat`` of its class
    map (of ``shape`` (y, x)): sun zenith, view zenith and relative azimuth [deg], BRDF (N, B)
    [sr^-1], and the id of each sample's spatial block of ``block_size`` pixels (unique over the
    scenes). Stored values times ``reflectance_scale`` are reflectance factors."""
    iy, ix = np.unravel_index(flat, shape)
    where = {"y": xr.DataArray(iy, dims="sample"), "x": xr.DataArray(ix, dims="sample")}

    def pick(array):
        # Pointwise (vectorized) indexing: lazy on dask, reads only the sampled pixels.
        return np.asarray(array.isel(where).values, dtype=float)

    reflectance = pick(image.transpose("band", "y", "x")).T * reflectance_scale
    saa, vaa = pick(angle_set["saa"]), pick(angle_set["vaa"])
    blocks_x = -(-shape[1] // block_size)
    block = (scene, iy // block_size, ix // block_size)
    return (pick(angle_set["sza"]), pick(angle_set["vza"]), relative_azimuth(saa, vaa), reflectance / math.pi,
            (block[0] * 10**9 + block[1] * blocks_x + block[2]).astype(np.int64))


def _check_bands(brdf: np.ndarray, image, class_id: int) -> None:
    """Refuse samples with a band that is not finite at any of them: every sample would be dropped
    (a class of "0 samples"), and the message would not name the band."""
    empty = np.flatnonzero(~np.isfinite(brdf).any(axis=0))
    if empty.size == 0:
        return
    wavelengths = image.coords["wavelength"].values if "wavelength" in image.coords else None
    names = [f"band {index + 1}" + (f" ({float(wavelengths[index]):g} nm)" if wavelengths is not None else "")
             for index in empty[:5]]
    more = f" and {empty.size - 5} more" if empty.size > 5 else ""
    raise InputError(f"{', '.join(names)}{more}: no finite reflectance at any of the {brdf.shape[0]} sampled pixels "
                     f"of class {class_id} (all NaN, inf or nodata); leave the band out of the image")


def sample_classes(
    images,
    classes,
    angles,
    *,
    class_ids: Sequence[int] | None = None,
    max_samples: int = 50_000,
    seed: int = 0,
    reflectance_scale: float = 1.0,
    block_size: int = 32,
) -> dict[int, ClassSamples]:
    """Pool each class's valid pixels over one or many scenes and sample them reproducibly.

    Parameters
    ----------
    images : DataArray or list of DataArray, dims (band, y, x)
        Reflectance factors (numpy- or dask-backed); the band count must agree across scenes.
    classes : DataArray or list of DataArray, dims (y, x)
        Integer class maps on the images' grids; 0, negative values and the map's nodata
        (``.rio.nodata``) mean "no class".
    angles : Dataset or list of Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] on the images' grids (docs/conventions.md).
    class_ids : sequence of int, optional
        Classes to sample (default: every positive id found).
    max_samples : int, default 50000
        Cap per class, over all scenes together. Sampling without replacement, seeded.
    seed : int, default 0
        Seed of the sampler: the same inputs and seed give the same samples.
    reflectance_scale : float, default 1
        Multiplier that turns stored values into reflectance factors (e.g. 1e-4 for 0-10000).
    block_size : int, default 32
        Side [pixels] of the square spatial blocks whose ids label the samples
        (``ClassSamples.block``), so that the fit's errors allow for albedo and texture that are
        correlated between neighbouring pixels.

    Returns
    -------
    dict of int to ClassSamples
        BRDF = reflectance / pi [sr^-1]. Samples whose reflectance is not finite in some band are
        dropped after sampling, so a class may end up with fewer than ``max_samples``.

    Raises
    ------
    InputError
        A band without a finite value at any sampled pixel of a class (named by number and
        wavelength): no sample would be left.

    Notes
    -----
    Only the class maps and the angle layers needed to find valid pixels are computed whole; the
    reflectance is read at the sampled pixels only (pointwise indexing stays lazy on dask).
    """
    images, classes, angles = _as_list(images), _as_list(classes), _as_list(angles)
    if not len(images) == len(classes) == len(angles):
        raise ParameterError(
            f"{len(images)} images, {len(classes)} class maps and {len(angles)} angle sets: "
            "give one class map and one angle set per image"
        )
    maps = [_class_values(class_map) for class_map in classes]
    valid_angles = [
        np.all([np.isfinite(np.asarray(a[name].values)) for name in ("sza", "saa", "vza", "vaa")], axis=0)
        for a in angles
    ]
    if class_ids is None:
        class_ids = sorted({int(c) for m in maps for c in np.unique(m) if c > 0})
    rng = np.random.default_rng(seed)
    pooled: dict[int, ClassSamples] = {}
    for class_id in class_ids:
        candidates = [np.flatnonzero((m == class_id) & ok) for m, ok in zip(maps, valid_angles)]
        counts = np.array([c.size for c in candidates])
        offsets = np.concatenate([[0], np.cumsum(counts)])
        chosen = np.sort(rng.choice(offsets[-1], size=min(max_samples, offsets[-1]), replace=False))
        scene_of = np.searchsorted(offsets, chosen, side="right") - 1
        parts = []
        for scene, (image, angle_set) in enumerate(zip(images, angles)):
            flat = candidates[scene][chosen[scene_of == scene] - offsets[scene]]
            if flat.size:
                parts.append(_scene_samples(scene, image, angle_set, maps[scene].shape, flat, reflectance_scale,
                                            block_size))
        if not parts:
            n_bands = images[0].sizes["band"]
            pooled[class_id] = ClassSamples(
                *(np.empty(0) for _ in range(3)), np.empty((0, n_bands)), np.empty(0, np.int64)
            )
            continue
        theta_i, theta_r, phi, brdf, block = (np.concatenate(p) for p in zip(*parts))
        _check_bands(brdf, images[0], class_id)
        keep = np.all(np.isfinite(brdf), axis=1)
        pooled[class_id] = ClassSamples(theta_i[keep], theta_r[keep], phi[keep], brdf[keep], block[keep])
    return pooled
