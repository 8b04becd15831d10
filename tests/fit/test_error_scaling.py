"""Properties of the imagery fit's errors and of the errors_reliable flag, per model family (issue 27).

Not Monte-Carlo pull SDs (those are ``benchmarks/bench_small_scene_errors.py``), but laws that must
hold for one fit:

- **3 blocks are never reliable.** The cluster score sums of a least-squares fit add up to zero
  at the optimum, so the G cluster contributions to a variance span at most G - 1 dimensions and
  the Satterthwaite degrees of freedom ``(sum lambda)^2 / sum lambda^2`` are at most that rank (Cauchy-
  Schwarz): nu <= 2 < MIN_ERROR_DOF for every parameter of every model.
- **Errors shrink like 1/sqrt(N) with independent samples, not with copies in one block.** The
  same noisy samples fitted four times over give the same estimate; as independent samples (no
  clusters) the bread and the meat of the sandwich both quadruple and every error halves (HC2's
  leverages and the t-variance factor move it by < 0.5 %: 1 % tolerance); with each copy in the
  block of its original (perfectly correlated within blocks) the meat grows 16-fold, the leverage
  of each block and its degrees of freedom stay, and every error stays the same. (With fresh noise
  the ratio is 2 only in the linear regime: red concrete's t1 and n trade off on 2000 pixels, their
  errors follow the estimate, and the ratio of two single fits ranges 1.5-2.9 over seeds.)
- **Many blocks of a well-determined model are reliable** and then every nu >= MIN_ERROR_DOF.
"""

from __future__ import annotations

import numpy as np
import pytest

from brdfcorr.fit.identifiability import MIN_ERROR_DOF
from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.testing import SMALL_SCENE_TRUTHS as TRUTHS
from brdfcorr.testing import small_scene_samples


def _scene(model, ny, nx, seed=0):
    """A push-broom scene (view zenith 0-40 deg) of ``model``'s truth (one per model family, as in
    the benchmark: brdfcorr.testing.small_scenes) with 3 % independent multiplicative noise; angles
    (N,) [deg], BRDF (N, 2)."""
    sza, vza, phi, clean = small_scene_samples(model, ny, nx)
    noise = np.random.default_rng(seed).standard_normal(clean.shape)
    return sza, vza, phi, clean * (1 + 0.03 * noise)


@pytest.mark.parametrize("model", list(TRUTHS))
def test_three_blocks_are_never_reliable(model):
    sza, vza, phi, brdf = _scene(model, 30, 40)
    result = fit_class_samples(model, sza, vza, phi, brdf, clusters=np.arange(sza.size) % 3)
    assert result["n_clusters"] == 3
    assert np.all(result["error_dof"] <= 2.0 + 1e-9)  # rank of the cluster contributions
    assert result["errors_reliable"] is False and "3 spatial blocks" in result["errors_reason"]


@pytest.mark.parametrize("model", list(TRUTHS))
def test_errors_halve_with_four_times_the_samples_and_stay_with_copies_in_one_block(model):
    sza, vza, phi, brdf = _scene(model, 40, 50, seed=1)
    blocks = np.arange(sza.size) // 100  # 20 blocks of 100 samples

    def fourfold(values):
        return np.concatenate([values] * 4)

    once = fit_class_samples(model, sza, vza, phi, brdf)
    independent = fit_class_samples(model, *map(fourfold, (sza, vza, phi, brdf)))
    blocked = fit_class_samples(model, sza, vza, phi, brdf, clusters=blocks)
    copies = fit_class_samples(model, *map(fourfold, (sza, vza, phi, brdf)), clusters=fourfold(blocks))
    for name in once["free"]:
        np.testing.assert_allclose(once["params"][name], independent["params"][name], rtol=1e-6)
        np.testing.assert_allclose(once["errors"][name] / independent["errors"][name], 2.0, rtol=0.01,
                                   err_msg=f"{model} {name}")
        np.testing.assert_allclose(blocked["errors"][name], copies["errors"][name], rtol=1e-6, err_msg=f"{model} {name}")
    np.testing.assert_allclose(blocked["error_dof"], copies["error_dof"], rtol=1e-6)


@pytest.mark.parametrize("model", ["torrance_sparrow", "empirical", "ross_thick_li_sparse", "rpv"])
def test_many_blocks_of_a_determined_fit_are_reliable(model):
    # 200 x 300 pixels in 8 x 8 blocks of 25 x 38: nu ~ 50 for every parameter.
    sza, vza, phi, brdf = _scene(model, 200, 300)
    rows, columns = np.indices((200, 300))
    blocks = (rows // 25 * 8 + columns // 38).ravel()
    result = fit_class_samples(model, sza, vza, phi, brdf, clusters=blocks)
    assert result["errors_reliable"] is True, result["errors_reason"]
    assert np.all(result["error_dof"] >= MIN_ERROR_DOF)
