"""The slopes' 1-sigma of ``assess`` over a cluster layer and over blocks of two sizes, and the
warning when it grows with the block (issue 40): simulated scenes whose errors are shared by
square patches (the days of a composite) or by strips along the view angle."""

from __future__ import annotations

import warnings

import dask.array as da
import numpy as np
import pytest

from brdfcorr.analysis.assess import ViewAngleOptions, assess_view_angles, signed_view_zenith, view_angle_report
from brdfcorr.analysis.view_angles import GROWTH_LIMIT, error_growth_warning
from brdfcorr.analysis.view_stripes import STRIPE_LIMIT, stripe_warning
from brdfcorr.errors import BrdfcorrWarning
from brdfcorr.testing import synthetic_angles
from brdfcorr.testing.noise import patch_noise, strip_noise

SHAPE = (128, 128)


@pytest.fixture(scope="module")
def geometry():
    """A push-broom line, vza 0-30 deg across x, sun due east: signed view zenith linear in x."""
    return synthetic_angles(*SHAPE, vza_max=30.0, saa=90.0, dtype=np.float64)


def _assess(values, geometry, *, clusters=None, block_size=8):
    cube = values[None]
    settings = {"clusters": clusters, "options": ViewAngleOptions(block_size=block_size)}
    return assess_view_angles(cube, cube, np.ones(SHAPE, np.int64), geometry["vza"], geometry["vaa"],
                              geometry["saa"], **settings)


def _cr1(theta, values, ids):
    """CR1 1-sigma of the least-squares slope over ``ids``, pixel by pixel (Cameron and Miller
    2015, eq. 11): an independent computation."""
    x = theta - theta.mean()
    slope = (x * values).sum() / (x * x).sum()
    residuals = values - values.mean() - slope * x
    scores = np.array([(x[ids == g] * residuals[ids == g]).sum() for g in np.unique(ids)])
    return np.sqrt(scores.size / (scores.size - 1) * (scores**2).sum()) / (x * x).sum()


def test_the_cluster_layer_gives_the_cr1_over_its_ids_wherever_they_lie(geometry):
    # Ids scattered over the scene in patches (a composite's days): one cluster is many patches,
    # in several dask chunks; numpy and dask equal the pixel-by-pixel CR1 over the ids.
    rng = np.random.default_rng(11)
    noise, patches = patch_noise(SHAPE, 8, 0.02, rng)
    days = rng.integers(150, 166, patches.max() + 1)[patches]
    values = 0.3 + noise + rng.normal(0, 0.01, SHAPE)
    theta = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    expected = 1000 * _cr1(theta.ravel(), values.ravel(), days.ravel()) / values.mean()
    lazy = da.from_array(values[None], chunks=(1, 48, 40))
    with_days = da.from_array(days, chunks=(48, 40))
    for result in (_assess(values, geometry, clusters=days),
                   assess_view_angles(lazy, lazy, np.ones(SHAPE, np.int64), geometry["vza"], geometry["vaa"],
                                      geometry["saa"], clusters=with_days,
                                      options=ViewAngleOptions(block_size=8))):
        np.testing.assert_allclose(result["relative_slope_error"].values[:, 0, 0], expected, rtol=1e-9)
        assert int(result["blocks"].values[0]) == np.unique(days).size
        assert "cluster layer" in result.attrs["error_clusters"]


def test_the_two_block_sizes_are_the_block_errors_of_each_size(geometry):
    values = 0.3 + np.random.default_rng(2).normal(0, 0.01, SHAPE)
    both = _assess(values, geometry, block_size=8)["relative_slope_error_blocks"].values[1, 0, 0]
    assert both[0] == _assess(values, geometry, block_size=8)["relative_slope_error"].values[1, 0, 0]
    assert both[1] == pytest.approx(_assess(values, geometry, block_size=16)["relative_slope_error"].values[1, 0, 0],
                                    rel=1e-12)


def test_patch_correlated_errors_warn_at_small_blocks_and_their_ids_follow_them(geometry):
    # Offsets shared by 32-pixel patches, blocks of 8: the 1-sigma grows with the block (warning);
    # blocks of the patches' size, or the patch ids as clusters, give the same 1-sigma (the
    # blocks coincide with the patches) and no warning.
    rng = np.random.default_rng(5)
    noise, patches = patch_noise(SHAPE, 32, 0.02, rng)
    values = 0.3 + noise + rng.normal(0, 0.01, SHAPE)
    with pytest.warns(BrdfcorrWarning, match=r"grows .*x from square blocks of 8 pixels to square blocks of 16"):
        small = _assess(values, geometry, block_size=8)
    assert small["error_growth"].values[1, 0, 0] > GROWTH_LIMIT
    matched = _assess(values, geometry, block_size=32)
    by_id = _assess(values, geometry, clusters=patches, block_size=32)
    assert error_growth_warning(by_id) is None and error_growth_warning(matched) is None
    np.testing.assert_allclose(by_id["relative_slope_error"].values, matched["relative_slope_error"].values,
                               rtol=1e-9)


def test_a_cluster_layer_too_fine_is_told_to_coarsen_not_to_be_given(geometry):
    # Offsets shared by 32-pixel patches, a cluster layer of 8-pixel squares: the 1-sigma grows from
    # the layer's units to blocks of 32 (block_size 16, doubled), and the advice is coarser units.
    rng = np.random.default_rng(5)
    noise, _ = patch_noise(SHAPE, 32, 0.02, rng)
    values = 0.3 + noise + rng.normal(0, 0.01, SHAPE)
    rows, columns = np.indices(SHAPE)
    fine = (rows // 8) * SHAPE[1] + columns // 8
    with pytest.warns(BrdfcorrWarning, match=r"from the cluster layer's ids to square blocks of 32") as caught:
        _assess(values, geometry, clusters=fine, block_size=16)
    message = str(caught[0].message)
    assert "give coarser ones" in message and "give a cluster layer" not in message


def test_stripes_along_the_track_need_their_ids_as_clusters(geometry):
    # An offset per stripe of 2 columns along the whole track (a detector, at one view angle):
    # blocks of 8 pixels cut each stripe into 16 pieces taken as independent, so their 1-sigma is
    # about sqrt(128 / 8) = 4 times too small; with the stripe ids as clusters it is that much
    # larger (this draw: 4.1x; over 20 seeds 3.3-5.8x) and does not grow with the block.
    rng = np.random.default_rng(7)
    noise, stripes = strip_noise(SHAPE, 2, 0.02, rng)
    values = 0.3 + noise + rng.normal(0, 0.01, SHAPE)
    with pytest.warns(BrdfcorrWarning, match="grows 1.6x"):  # this draw; the check misses half of such scenes
        blocks = _assess(values, geometry, block_size=8)
    by_stripe = _assess(values, geometry, clusters=stripes, block_size=8)
    ratio = by_stripe["relative_slope_error"].values[1, 0, 0] / blocks["relative_slope_error"].values[1, 0, 0]
    assert 3 < ratio < 6
    assert by_stripe["error_growth"].values[1, 0, 0] < 1
    report = view_angle_report(by_stripe)
    assert report["errors"]["warning"] is None and report["errors"]["block_sizes"] == [8, 16]
    assert report["classes"][0]["after"]["relative_slope_error_double_block"][0] == pytest.approx(
        float(by_stripe["relative_slope_error_blocks"].values[1, 0, 0, 1]))


def test_independent_errors_do_not_warn(geometry):
    # White noise: the 1-sigma does not grow with the block (256 and 64 blocks; this draw: growth
    # within 15 % of 1, far below the limit).
    values = 0.3 + np.random.default_rng(4).normal(0, 0.01, SHAPE)
    result = _assess(values, geometry, block_size=8)
    assert abs(result["error_growth"].values[1, 0, 0] - 1) < 0.15
    assert error_growth_warning(result) is None


# --------------------------------------------------------------- errors shared along the track
def _stripe_ratio_by_hand(theta, values, width):
    """The 1-sigma over bins of ``width`` deg of signed view zenith (edges at multiples of it),
    each bin's mean residual of the least-squares line less a weighted cubic over the bins, over
    the CR1 1-sigma over square blocks of 8 (:func:`_cr1`): pixel by pixel, numpy's polyfit."""
    x = theta - theta.mean()
    slope = (x * values).sum() / (x * x).sum()
    residuals = values - values.mean() - slope * x
    bins = np.floor(theta / width).astype(int)
    labels = np.unique(bins)
    n = np.array([np.sum(bins == b) for b in labels], float)
    centre = np.array([theta[bins == b].mean() for b in labels])
    mean_residual = np.array([residuals[bins == b].mean() for b in labels])
    # np.polyfit's w multiplies the residuals: sqrt(n) gives a fit weighted by the pixels.
    trend = np.polyval(np.polyfit(centre, mean_residual, 3, w=np.sqrt(n)), centre)
    scores = n * (centre - theta.mean()) * (mean_residual - trend)
    sigma = np.sqrt(labels.size / (labels.size - 4) * (scores**2).sum()) / (x * x).sum()
    rows, cols = np.indices(SHAPE)
    return sigma / _cr1(theta, values, ((rows // 8) * 16 + cols // 8).ravel())


def test_the_stripe_ratio_is_the_bins_one_over_the_blocks(geometry):
    rng = np.random.default_rng(21)
    noise, _ = strip_noise(SHAPE, 2, 0.02, rng)
    values = 0.3 + noise + rng.normal(0, 0.01, SHAPE)
    theta = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    with pytest.warns(BrdfcorrWarning):
        result = _assess(values, geometry, block_size=8)
    expected = _stripe_ratio_by_hand(theta.ravel(), values.ravel(), 2.0)
    np.testing.assert_allclose(result["stripe_ratio"].values[:, 0, 0], expected, rtol=1e-6)


def test_stripes_warn_and_their_ids_silence_the_warning(geometry):
    # Detector stripes of 2 columns: the 1-sigma over bins of view zenith is 2.79-5.59x the blocks'
    # (5th-95th percentile over 300 scenes, benchmarks/bench_assess_coverage.py), so the warning names the fix; with the stripe ids as
    # clusters the reported 1-sigma holds them and the ratio is about 1.
    rng = np.random.default_rng(7)
    noise, stripes = strip_noise(SHAPE, 2, 0.02, rng)
    values = 0.3 + noise + rng.normal(0, 0.01, SHAPE)
    with pytest.warns(BrdfcorrWarning, match=r"over bins of view zenith is .*x the one over square blocks of 8 pixels.*"
                                             r"give their ids as --clusters \(the detector ids"):
        blocks = _assess(values, geometry, block_size=8)
    assert blocks["stripe_ratio"].values[1, 0, 0] > STRIPE_LIMIT
    by_stripe = _assess(values, geometry, clusters=stripes, block_size=8)
    assert stripe_warning(by_stripe) is None and 0.5 < by_stripe["stripe_ratio"].values[1, 0, 0] < 1.5
    report = view_angle_report(blocks)
    assert report["errors"]["stripes"] == stripe_warning(blocks)
    assert report["classes"][0]["stripe_ratio"] == pytest.approx(float(blocks["stripe_ratio"].values[1, 0, 0]))


def test_a_curved_profile_and_patches_are_not_stripes(geometry):
    # White noise on a strongly curved profile (a straight line leaves a U in the residuals, 30
    # times the noise at the edges): the cubic over the bins takes it out, no stripe warning.
    # Patch-shared errors
    # (a composite's days) neither: their bins share them with each other.
    rng = np.random.default_rng(3)
    theta = signed_view_zenith(geometry["vza"], geometry["vaa"], geometry["saa"])
    curved = 0.3 + 0.3 * (theta / 30.0) ** 2 + 0.1 * (theta / 30.0) ** 3 + rng.normal(0, 0.01, SHAPE)
    with warnings.catch_warnings(record=True) as caught:  # the block growth warns here (the U is smooth in space)
        warnings.simplefilter("always", BrdfcorrWarning)
        result = _assess(curved, geometry, block_size=8)
    assert not any("bins of view zenith" in str(w.message) for w in caught)
    assert result["stripe_ratio"].values[1, 0, 0] < 1.5
    patches, _ = patch_noise(SHAPE, 16, 0.02, rng)
    with pytest.warns(BrdfcorrWarning, match="grows") as caught:
        result = _assess(0.3 + patches + rng.normal(0, 0.01, SHAPE), geometry, block_size=8)
    assert not any("bins of view zenith" in str(w.message) for w in caught)
    assert stripe_warning(result) is None
