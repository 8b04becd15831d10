"""Helpers of the model tests (tests/models/test_models.py, tests/models/test_kernels.py), as fixtures."""

from __future__ import annotations

from functools import partial

import dask.array as da
import numpy as np
import pytest
import xarray as xr


def _array_kinds_agree(function, angles: np.ndarray, rtol: float | None = None) -> None:
    """``function(theta_i, theta_r, phi)`` [deg] run with numpy, dask, xarray, dask-backed xarray
    and scalar angles (``angles``: a (3, 40, 50) stack): the array kind of the input comes back
    (lazily for dask: run under ``no_compute``), xarray keeps its coords and states ``units``, and
    every result equals the numpy one (exactly, or within ``rtol``)."""
    same = np.testing.assert_array_equal if rtol is None else partial(np.testing.assert_allclose, rtol=rtol)
    ti, tr, phi = angles
    expected = function(ti, tr, phi)
    assert isinstance(expected, np.ndarray) and expected.shape == ti.shape

    lazy = [da.from_array(a, chunks=(20, 25)) for a in (ti, tr, phi)]
    result = function(*lazy)  # no_compute: lazy in, lazy out
    assert isinstance(result, da.Array)
    same(result.compute(scheduler="sync"), expected)

    coords = {"y": np.arange(40), "x": np.arange(50) * 10.0}
    labelled = [xr.DataArray(a, dims=("y", "x"), coords=coords) for a in (ti, tr, phi)]
    result = function(*labelled)
    assert isinstance(result, xr.DataArray) and result.dims == ("y", "x")
    np.testing.assert_array_equal(result.x, coords["x"])
    same(result.values, expected)
    assert "units" in result.attrs

    lazy_labelled = [a.chunk({"y": 20}) for a in labelled]
    result = function(*lazy_labelled)  # no_compute: lazy in, lazy out
    assert isinstance(result.data, da.Array)
    same(result.compute(scheduler="sync").values, expected)

    assert np.ndim(function(ti[0, 0], tr[0, 0], phi[0, 0])) == 0


@pytest.fixture(scope="session")
def array_kinds_agree():
    """``array_kinds_agree(function, angles, rtol=None)``: the contract of every array function
    (DESIGN.md, models): scalar, numpy, dask and xarray input, numpy and dask results equal."""
    return _array_kinds_agree
