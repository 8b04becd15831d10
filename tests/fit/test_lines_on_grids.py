"""Free levels over overlapping flight lines on different grids (issue 37): the lines are brought
onto one common grid (brdfcorr.fit.grids) and each pixel's level is fitted from its own views."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import brdfcorr.fit.sampling as sampling
from brdfcorr.errors import ParameterError
from brdfcorr.fit import ClassModels, Sampling, fit_classes
from brdfcorr.fit.grids import common_grid
from brdfcorr.fit.sampling import sample_classes
from brdfcorr.geometry import relative_azimuth
from brdfcorr.models import get_model
from brdfcorr.testing import CRS, ORIGIN, PIXEL

RTLSR = get_model("ross_thick_li_sparse")
TRUTH = {"f_iso": 0.1, "f_vol": 0.06, "f_geo": 0.015}
WIDTH = 100 * PIXEL  # [m] over which the cover rises by COVER_RISE eastwards
COVER_RISE = 0.6


def _cover(x, y):
    """Land cover (a brightness factor): rising eastwards, smooth, so that half a pixel of
    misregistration by the nearest-neighbour resampling changes it by < 0.3 %."""
    return 1 + COVER_RISE * (x - ORIGIN[0]) / WIDTH + 0.05 * np.sin(y / 300.0)


def _on_grid(array: xr.DataArray, x, y, crs=CRS) -> xr.DataArray:
    array = array.assign_coords(x=("x", x), y=("y", y)).rio.write_crs(crs)
    return array.rio.write_transform(array.rio.transform(recalc=True))


def _line(columns: float, rows: float, vaa: float, pixel: float = PIXEL, shape=(48, 64), seed=0, noise=0.003):
    """One line whose grid starts ``columns``, ``rows`` pixels east and south of ORIGIN, with the
    view zenith rising eastwards across its swath (2-40 deg) from azimuth ``vaa``: within the
    line the cover rises with the view zenith (the confounding of issues 24 and 37)."""
    ny, nx = shape
    x = ORIGIN[0] + pixel * (columns + np.arange(nx) + 0.5)
    y = ORIGIN[1] - pixel * (rows + np.arange(ny) + 0.5)
    vza = np.broadcast_to(np.linspace(2.0, 40.0, nx)[None, :], shape).copy()
    sza = np.broadcast_to(np.linspace(30.0, 40.0, ny)[:, None], shape).copy()
    saa, vaa = np.full(shape, 150.0), np.full(shape, vaa)
    cover = _cover(*np.meshgrid(x, y))
    noisy = 1 + noise * np.random.default_rng(seed).standard_normal(shape)
    reflectance = np.pi * RTLSR(sza, vza, relative_azimuth(saa, vaa), **TRUTH) * cover * noisy
    image = _on_grid(xr.DataArray(reflectance[None], dims=("band", "y", "x"), coords={"band": [1]}), x, y)
    classes = _on_grid(xr.DataArray(np.ones(shape, np.uint8), dims=("y", "x")), x, y)
    angles = xr.Dataset({name: _on_grid(xr.DataArray(value, dims=("y", "x")), x, y)
                         for name, value in {"sza": sza, "saa": saa, "vza": vza, "vaa": vaa}.items()})
    return image, classes, angles


def _fit(lines, levels: str):
    images, classes, angles = (list(layer) for layer in zip(*lines))
    return fit_classes(images, classes, angles, ClassModels("ross_thick_li_sparse"), wavelengths=[650.0],
                       sampling=Sampling(levels=levels, block_size=8)).fits[0]


def _ratios(fit) -> np.ndarray:
    params = fit.params
    return np.array([params["f_vol"][0], params["f_geo"][0]]) / params["f_iso"][0]


TRUE_RATIOS = np.array([TRUTH["f_vol"], TRUTH["f_geo"]]) / TRUTH["f_iso"]  # 0.6 and 0.15


@pytest.mark.parametrize("second", [
    {"columns": 30.25, "rows": 0.3},  # shifted by a non-integer number of pixels
    {"columns": 20.0, "rows": 0.0, "pixel": 15.0, "shape": (32, 42)},  # another resolution
], ids=["shifted", "coarser"])
def test_pixel_levels_on_a_common_grid_recover_the_shape_pooled_reads_from_the_cover(second):
    """Two lines over one ground (one truth), on different grids, seen from opposite sides: the
    pooled fit takes the cover's eastward rise for volume scattering; with each common-grid
    pixel's level free the kernel weights' ratios are the truth's, f_vol/f_iso = 0.6 and
    f_geo/f_iso = 0.15 (TRUTH). Nearest neighbour pairs views up to half a coarse pixel apart
    (7.5 m) on a cover rising 0.06 %/m: the within ratios keep a bias of up to 0.06 (measured
    without noise on the coarser line), a third of the pooled fit's or less; hence 0.1."""
    lines = [_line(0.0, 0.0, 90.0), _line(vaa=270.0, seed=1, **second)]
    pooled, within = _fit(lines, "pooled"), _fit(lines, "pixel")
    assert within.levels == "pixel" and within.status == "fitted"
    within_error = np.abs(_ratios(within) - TRUE_RATIOS)
    pooled_error = np.abs(_ratios(pooled) - TRUE_RATIOS)
    assert np.all(within_error < 0.1), _ratios(within)
    assert np.all(pooled_error > 0.14), _ratios(pooled)  # the confounding this fit removes: f_geo goes to 0
    assert np.max(within_error) < 0.5 * np.max(pooled_error)
    assert any("seen by two or more scenes" in note for note in within.notes)


def test_auto_frees_pixels_where_lines_overlap_and_pools_where_they_do_not():
    """auto frees a class's pixel levels where the lines see enough of its ground twice:
    min_repeated views of pixels seen twice or more (fit_classes: its guard rail's min_samples)."""
    overlapping = [_line(0.0, 0.0, 90.0), _line(30.25, 0.3, 270.0, seed=1)]
    apart = [_line(0.0, 0.0, 90.0), _line(80.0, 0.0, 270.0, seed=1)]  # no common ground
    layers = [list(layer) for layer in zip(*overlapping)]
    # Common pixels whose centres lie in both lines: columns 30-63 (centres 30.5-63.5 >= 30.25),
    # rows 0-47 (centres 0.5-47.5 >= 0.3): 34 x 48, two views each.
    views = 2 * 34 * 48
    assert sample_classes(*layers, min_repeated=views, sampling=Sampling(levels="auto"))[1].levels == "pixel"
    assert sample_classes(*layers, min_repeated=views + 1, sampling=Sampling(levels="auto"))[1].levels == "pooled"
    assert sample_classes(*(list(layer) for layer in zip(*apart)), min_repeated=1, sampling=Sampling(levels="auto"))[1].levels \
        == "pooled"
    with pytest.warns(UserWarning):  # pixel levels where no pixel is seen twice: nothing to fit within
        assert _fit(apart, "pixel").status != "fitted"


def test_the_common_grid_is_the_first_lines_grid_over_the_union():
    first, second = _line(0.0, 0.0, 90.0), _line(30.25, 0.3, 270.0)
    grid = common_grid([first[0], second[0]])
    # Union: columns 0 to 30.25 + 64 = 94.25 -> 95 pixels of 10 m; rows 0 to 48.3 -> 49.
    assert grid.shape == (49, 95)
    # The first line's pixels are common-grid pixels unchanged (row r, column c -> r * 64 + c).
    source = grid.sources[0].reshape(grid.shape)
    np.testing.assert_array_equal(source[:48, :64], np.arange(48 * 64).reshape(48, 64))
    assert np.all(source[48:] == -1) and np.all(source[:, 64:] == -1)
    # Nearest neighbour: each common pixel takes the second line's pixel that holds its centre.
    ys, xs = np.meshgrid(np.arange(49) + 0.5, np.arange(95) + 0.5, indexing="ij")  # common centres [pixels]
    column, row = np.floor(xs - 30.25), np.floor(ys - 0.3)  # the second line's pixel holding each centre
    inside = (column >= 0) & (column < 64) & (row >= 0) & (row < 48)
    expected = np.where(inside, row * 64 + column, -1)
    np.testing.assert_array_equal(grid.sources[1].reshape(grid.shape), expected)


def test_integer_shifts_sample_exactly_as_lines_placed_on_one_grid_by_hand():
    """Lines shifted by whole pixels: the common-grid path gives the samples of the same lines
    padded onto their union grid by hand (numpy; NaN and class 0 outside each line)."""
    lines = [_line(0.0, 0.0, 90.0), _line(24.0, 3.0, 270.0, seed=1)]
    resampled = sample_classes(*(list(layer) for layer in zip(*lines)), sampling=Sampling(levels="pixel", max_samples=3000, block_size=8))[1]
    padded = []
    for (image, classes, angles), (row, column) in zip(lines, [(0, 0), (3, 24)]):
        def place(values, fill, row=row, column=column):
            canvas = np.full((*values.shape[:-2], 51, 88), fill, dtype=float)
            canvas[..., row:row + 48, column:column + 64] = values
            return canvas
        dims = ("y", "x")
        padded.append((xr.DataArray(place(image.values, np.nan), dims=("band", *dims)),
                       xr.DataArray(place(classes.values, 0).astype(int), dims=dims),
                       xr.Dataset({name: (dims, place(angles[name].values, np.nan)) for name in angles})))
    by_hand = sample_classes(*(list(layer) for layer in zip(*padded)), sampling=Sampling(levels="pixel", max_samples=3000, block_size=8))[1]
    for name in ("theta_i", "theta_r", "phi", "brdf", "block", "group", "scene"):
        np.testing.assert_array_equal(getattr(resampled, name), getattr(by_hand, name), err_msg=name)


def test_scenes_on_one_grid_take_no_resampling_path(monkeypatch):
    """Scenes on one grid are sampled as before: the common grid is never built, no note."""
    lines = [_line(0.0, 0.0, 90.0), _line(0.0, 0.0, 270.0, seed=1)]

    def refuse(images):
        raise AssertionError("resampled scenes on one grid")

    monkeypatch.setattr(sampling, "common_grid", refuse)
    fit = _fit(lines, "pixel")
    assert fit.levels == "pixel" and not any("resampled" in note for note in fit.notes)
    samples = sample_classes(*(list(layer) for layer in zip(*lines)), sampling=Sampling(levels="auto"))[1]
    assert samples.note is None and samples.levels == "pixel"


def test_pixel_levels_need_georeferenced_scenes_on_different_grids():
    image, classes, angles = _line(0.0, 0.0, 90.0)
    small = _line(0.0, 0.0, 270.0, shape=(40, 64))
    bare = [(layer.drop_vars("spatial_ref") if "spatial_ref" in layer.coords else layer)
            for layer in (image, small[0])]
    with pytest.raises(ParameterError, match="has no CRS"):
        sample_classes(bare, [classes, small[1]], [angles, small[2]], sampling=Sampling(levels="pixel"))
    pooled = sample_classes(bare, [classes, small[1]], [angles, small[2]], sampling=Sampling(levels="auto"))[1]
    assert pooled.levels == "pooled" and pooled.note is None
