"""Each scene's own level is freed beside each pixel's only where it leaves the shape identified.

Two flight lines that see their overlap from opposite sides of nadir (the second shifted east by
half a swath) differ at every common pixel by the same step in view (line 1 forward, line 2
backward scattering): a level per line absorbs the mean forward/backward contrast, the very
signal of the within fit. ``fit_classes`` then frees the pixels' levels only and says so; on
noise-free lines rendered with the model itself the shape is then the truth (closed form).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr

from brdfcorr.fit import ClassModels, Sampling, fit_classes
from brdfcorr.geometry import relative_azimuth
from brdfcorr.models import get_model

RTLSR = get_model("ross_thick_li_sparse")
TRUTH = {"f_iso": np.array([0.05, 0.12]), "f_vol": np.array([0.03, 0.096]), "f_geo": np.array([0.01, 0.0144])}
ROWS, COLUMNS = 24, 40


def _georeferenced(array: xr.DataArray, offset: int) -> xr.DataArray:
    x = 500_000.0 + 10.0 * (offset + np.arange(array.sizes["x"]) + 0.5)
    y = 5_000_000.0 - 10.0 * (np.arange(array.sizes["y"]) + 0.5)
    array = array.assign_coords(x=("x", x), y=("y", y)).rio.write_crs("EPSG:32632")
    return array.rio.write_transform(array.rio.transform(recalc=True))


def _line(offset: int, cover: np.ndarray, vza: np.ndarray, vaa: np.ndarray, sza: float = 35.0):
    """A line over ground columns ``offset ..``: RTLSR truth times the ground's cover, no noise."""
    shape = (ROWS, COLUMNS)
    angles = {"sza": np.full(shape, sza), "saa": np.full(shape, 100.0), "vza": vza, "vaa": vaa}
    phi = relative_azimuth(angles["saa"], angles["vaa"])
    brdf = RTLSR(angles["sza"][None], vza[None], phi[None], **{k: v[:, None, None] for k, v in TRUTH.items()})
    image = xr.DataArray((math.pi * brdf * cover[:, :, offset:offset + COLUMNS]).astype(np.float64),
                         dims=("band", "y", "x"))
    angle_set = xr.Dataset({k: _georeferenced(xr.DataArray(v, dims=("y", "x")), offset) for k, v in angles.items()})
    classes = _georeferenced(xr.DataArray(np.ones(shape, np.int32), dims=("y", "x")), offset)
    return _georeferenced(image, offset), classes, angle_set


def _swath(flip: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """View zenith [deg] rising from 0 to 20 on either side of the centre column, and the azimuth
    of the sensor as seen from the ground (west half 90 deg, east half 270 deg)."""
    across = np.linspace(-1.0, 1.0, COLUMNS) * math.tan(math.radians(20.0))
    vza = np.broadcast_to(np.degrees(np.arctan(np.abs(across))), (ROWS, COLUMNS)).copy()
    vaa = np.broadcast_to(np.where(across > 0, 270.0, 90.0), (ROWS, COLUMNS)).copy()
    return vza, vaa


def _ratios(fit) -> np.ndarray:
    return np.array([fit.params["f_vol"] / fit.params["f_iso"], fit.params["f_geo"] / fit.params["f_iso"]])


def test_lines_seen_from_opposite_sides_free_the_pixels_levels_only():
    rng = np.random.default_rng(3)
    cover = 1.0 + 0.3 * rng.uniform(size=(1, ROWS, COLUMNS + COLUMNS // 2))
    lines = [_line(offset, cover, *_swath()) for offset in (0, COLUMNS // 2)]
    result = fit_classes(*(list(parts) for parts in zip(*lines)), ClassModels("ross_thick_li_sparse"),
                         sampling=Sampling(levels="pixel", block_size=8, max_samples=10_000))
    fit = result.fits[0]
    assert fit.status == "fitted" and fit.levels == "pixel"
    assert any("no level of its own per scene" in note for note in fit.notes)
    truth = np.array([TRUTH["f_vol"] / TRUTH["f_iso"], TRUTH["f_geo"] / TRUTH["f_iso"]])
    # noise-free, the model's own form: exact but for the within fit's level iterations (< 1e-4 after 3)
    np.testing.assert_allclose(_ratios(fit), truth, rtol=1e-3)


@pytest.mark.parametrize("seed", [0, 1])
def test_scenes_keep_their_levels_where_the_views_vary_within_each(seed):
    """Three dates on one grid, each seeing every pixel from its own random view: the spread left
    beside the dates' levels is large, so they stay free (no note), and the fit is exact."""
    rng = np.random.default_rng(seed)
    cover = 1.0 + 0.3 * rng.uniform(size=(1, ROWS, COLUMNS))
    lines = [_line(0, cover, rng.uniform(0.0, 30.0, (ROWS, COLUMNS)), rng.choice([90.0, 270.0], (ROWS, COLUMNS)),
                   sza=sza) for sza in (30.0, 35.0, 40.0)]
    result = fit_classes(*(list(parts) for parts in zip(*lines)), ClassModels("ross_thick_li_sparse"),
                         sampling=Sampling(levels="pixel", block_size=8, max_samples=10_000))
    fit = result.fits[0]
    assert fit.status == "fitted" and not any("per scene" in note for note in fit.notes)
    truth = np.array([TRUTH["f_vol"] / TRUTH["f_iso"], TRUTH["f_geo"] / TRUTH["f_iso"]])
    np.testing.assert_allclose(_ratios(fit), truth, rtol=1e-3)
