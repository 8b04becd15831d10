"""Errors that pixels share, for simulated assessments of the slopes' 1-sigma
(:func:`brdfcorr.analysis.assess.assess_view_angles`): offsets shared by square patches (the
days of a composite, fields) and offsets shared by stripes of columns along the track (the
detectors of a push-broom line whose view zenith changes across the columns). Each returns the noise and the id
of the unit each pixel shares it with (a cluster layer)."""

from __future__ import annotations

import numpy as np

__all__ = ["patch_noise", "strip_noise"]


def patch_noise(shape: tuple[int, int], size: int, sigma: float,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """An offset drawn from N(0, ``sigma``²) per square patch of ``size`` pixels; (noise, patch id)."""
    rows, cols = np.indices(shape)
    per_row = -(-shape[1] // size)
    ids = (rows // size) * per_row + cols // size
    offsets = rng.normal(0.0, sigma, ids.max() + 1)
    return offsets[ids], ids


def strip_noise(shape: tuple[int, int], width: int, sigma: float,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """An offset drawn from N(0, ``sigma``²) per stripe of ``width`` columns along the whole track
    (every row): a detector's calibration error, seen at one view angle; (noise, stripe id)."""
    ids = np.broadcast_to(np.arange(shape[1]) // width, shape)
    offsets = rng.normal(0.0, sigma, ids.max() + 1)
    return offsets[ids], np.ascontiguousarray(ids)
