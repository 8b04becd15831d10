"""Small one-class scenes with a known BRDF: the samples of the imagery fit's error tests
(``tests/fit/test_error_scaling.py``) and of ``benchmarks/bench_small_scene_errors.py`` (issue 27).

Every pixel of an ny x nx push-broom scene (:func:`brdfcorr.testing.synthetic_angles`: sun zenith
30-40 deg, view zenith 0-40 deg across track, relative azimuth 60-120 deg) belongs to one class whose
BRDF is ``model`` with the parameters of :data:`SMALL_SCENE_TRUTHS`, two bands.

References
----------
.. [1] G. Meister, R. Wiemker, R. Monno, H. Spitzer, A. Strahler (1998): Investigation on the
   Torrance-Sparrow specular BRDF model. Proc. IGARSS'98, IV, 2095-2097.
.. [2] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII, section 4.
"""

from __future__ import annotations

from typing import Any

import numpy as np

import brdfcorr.testing as testing  # the package re-exports this module: its names are read at call time
from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.models import get_model

__all__ = ["RED_CONCRETE", "SMALL_SCENE_TRUTHS", "pixel_blocks", "small_scene_samples"]

#: Red concrete at 550 nm, Meister et al. (2000), Table 1: t0 [sr^-1], t1 [sr^-1], w [deg^-1], n,
#: k; band 2 has both intensities 1.6 times as large.
RED_CONCRETE: dict[str, Any] = {"t0": np.array([0.0192, 0.0307]), "t1": np.array([1.06, 1.70]), "w": 0.0804,
                                "n": 1.48, "k": 0.25}

#: The truth per model family (two bands). Both Torrance-Sparrow models: :data:`RED_CONCRETE`.
#: Empirical: a specular lobe of c = 0.05 deg^-1 with the constant-Fresnel b = 1 rad^-4 (Meister et
#: al. (1998), eq. 5). Ross-Thick/Li-Sparse: red and near-infrared weights [sr^-1] of a vegetated
#: surface of the order of MODIS BRDF products. RPV: the registry's typical k and Theta, a moderate
#: hot spot rho_c = 0.3.
SMALL_SCENE_TRUTHS: dict[str, dict[str, Any]] = {
    "torrance_sparrow": RED_CONCRETE,
    "torrance_sparrow_simplified": RED_CONCRETE,
    "empirical": {"a": np.array([0.3, 0.48]), "b": 1.0, "c": 0.05, "t0": np.array([0.02, 0.032])},
    "ross_thick_li_sparse": {"f_iso": np.array([0.05, 0.3]), "f_vol": np.array([0.02, 0.15]),
                             "f_geo": np.array([0.01, 0.03])},
    "rpv": {"rho0": np.array([0.03, 0.3]), "k": 0.75, "theta": -0.1, "rho_c": 0.3},
}


def small_scene_samples(model: str, ny: int, nx: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pixels of an ny x nx push-broom scene (view zenith 0-40 deg) as samples, in row-major
    order.

    Returns
    -------
    sza, vza, phi : (N,) float64 [deg]
        Sun zenith, view zenith and relative azimuth (DESIGN.md's convention) of each sample.
    brdf : (N, 2) float64 [sr^-1]
        The noise-free BRDF of ``model`` with its :data:`SMALL_SCENE_TRUTHS`, two bands.
    """
    angles = testing.synthetic_angles(ny, nx, vza_max=40.0, dtype=np.float64)
    sza, vza = angles["sza"].ravel(), angles["vza"].ravel()
    phi = relative_azimuth(angles["saa"], angles["vaa"]).ravel()
    geometry = ScatteringGeometry(sza[:, None], vza[:, None], phi[:, None])
    brdf = get_model(model).kernel(geometry, **SMALL_SCENE_TRUTHS[model])
    return sza, vza, phi, np.asarray(brdf, dtype=float)


def pixel_blocks(ny: int, nx: int, size: int) -> np.ndarray:
    """The index of each pixel's ``size`` x ``size`` block [pixels] of an ny x nx scene, row-major
    over the pixels and the blocks (a partial block at the right and bottom edges counts), (N,) int."""
    rows, columns = (index.ravel() for index in np.indices((ny, nx)))
    return (rows // size) * -(-nx // size) + columns // size

