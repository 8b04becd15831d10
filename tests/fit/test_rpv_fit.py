"""Goniometer fits of RPV: its own surfaces are recovered from the geometries of a laboratory
goniometer; on a specular lobe its best fit is a limit of the model, reported as such."""

import warnings

import numpy as np
import pytest

from brdfcorr.fit.goniometer import FitWarning, NonIdentifiableWarning, fit_brdf
from brdfcorr.models import get_model, load_material

RPV_SURFACES = [  # within the model's bounds; backward and forward, bowl and bell, weak and strong hot spot
    {"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 0.5},
    {"rho0": 0.05, "k": 1.3, "theta": 0.3, "rho_c": 0.1},
    {"rho0": 0.02, "k": 0.5, "theta": -0.4, "rho_c": 0.9},
    {"rho0": 0.1, "k": 1.8, "theta": 0.6, "rho_c": 0.05},
    {"rho0": 0.04, "k": 0.3, "theta": -0.7, "rho_c": 0.3},
]


def _goniometer(seed: int, count: int = 73):
    """73 geometries drawn from a grid with sun and view zenith <= 60 deg over both halves of the
    azimuth circle (benchmarks/bench_model_choice.py)."""
    grid = np.meshgrid([0, 15, 30, 45, 60], [0, 10, 20, 30, 40, 50, 60], np.arange(0, 181, 30), indexing="ij")
    ti, tr, phi = (np.asarray(a, dtype=float).ravel() for a in grid)
    rows = np.random.default_rng(seed).choice(ti.size, count, replace=False)
    return ti[rows], tr[rows], phi[rows]


@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize("truth", RPV_SURFACES)
def test_a_noise_free_rpv_surface_is_recovered_from_goniometer_geometries(truth, seed):
    angles = _goniometer(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)  # no limit, no bound ...
        warnings.simplefilter("ignore", NonIdentifiableWarning)  # (rho_c trades with rho0 near the hot spot)
        # (... but the errors of a fit without sigma whose hot-spot sample alone fixes rho_c are scaled)
        warnings.filterwarnings("ignore", "rpv: a measurement alone determines", FitWarning)
        result = fit_brdf("rpv", *angles, get_model("rpv")(*angles, **truth))
    assert result.n_converged >= 1
    for name, value in truth.items():
        assert result.params[name] == pytest.approx(value, rel=1e-4, abs=1e-6), name


def test_rpv_on_a_specular_lobe_ends_at_its_limit_and_says_so():
    # The roof tile of paper 003 (Table 1): a Torrance-Sparrow lobe. RPV comes closest as theta -> 1
    # with rho0 -> inf (rho0 (1 - theta^2) finite): every start runs out of evaluations along that
    # valley, which used to be "no start converged". The limit's chi^2 is the lowest: below the
    # converged fit with theta kept <= 0.99.
    angles = _goniometer(0)
    brdf = get_model("torrance_sparrow")(*angles, **load_material("roof_tile").params)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NonIdentifiableWarning)  # (the limit's errors are not determined)
        with pytest.warns(FitWarning, match="limit of the model"):
            result = fit_brdf("rpv", *angles, brdf)
    assert result.params["theta"] > 0.99 and result.n_converged >= 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bounded = fit_brdf("rpv", *angles, brdf, bounds={"theta": (-1.0, 0.99)})
    assert result.chi2 <= bounded.chi2
