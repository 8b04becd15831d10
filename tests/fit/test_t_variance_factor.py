"""The t-variance factor of the imagery fit's errors (docs/uncertainty.md, "How far the fit's
errors can be trusted", item 3): what the inflation of each error by sqrt(nu / (nu - 2)) does."""

import numpy as np
import pytest
from scipy import stats

from brdfcorr.fit.identifiability import t_variance_factor


@pytest.mark.parametrize("dof", [4, 5, 6, 8, 12, 20, 30, 100, 1000])
def test_two_inflated_errors_hold_95_percent_of_a_t_distribution(dof):
    # Student's t with nu degrees of freedom (scipy): +-2 sqrt(nu / (nu - 2)) holds 95.0-95.4 %.
    coverage = 2 * stats.t.cdf(2 * np.sqrt(t_variance_factor(dof)), dof) - 1
    assert 0.950 <= coverage <= 0.9545


def test_the_factor_is_the_t_variance_and_held_below_four():
    assert t_variance_factor(10) == pytest.approx(stats.t.var(10))
    assert t_variance_factor(np.inf) == 1.0
    held = 2 * stats.t.cdf(2 * np.sqrt(t_variance_factor(3)), 3) - 1
    assert t_variance_factor(3) == 2.0 and held == pytest.approx(0.934, abs=5e-4)
