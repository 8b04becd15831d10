"""Shared test helpers: the real sensor files, and a guard that lazy code computes nothing."""

from __future__ import annotations

from pathlib import Path

import dask
import pytest
from hypothesis import settings

# Property tests draw the same examples on every run (a CI run that passes here passes there); a
# random exploration is `pytest --hypothesis-profile=explore`.
settings.register_profile("default", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("default")

#: Small real sensor files (AVIRIS-NG, Sentinel-2, Landsat) beside the repository; tests that need
#: them are skipped where they are absent.
REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"
needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(), reason=f"real sensor data not found at {REALDATA}")


def _raising_scheduler(*args, **kwargs):
    raise AssertionError("a lazy function computed its dask input")


@pytest.fixture
def no_compute():
    """Within the test, any dask computation fails: lazy functions must stay lazy."""
    with dask.config.set(scheduler=_raising_scheduler):
        yield
