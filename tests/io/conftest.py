"""Fixtures of the io tests."""

from pathlib import Path

import pytest

from brdfcorr.testing import write_sentinel2_safe


@pytest.fixture
def safe(tmp_path) -> dict[str, Path]:
    """A SAFE folder with synthetic metadata under ``in/`` and an empty ``out/``, as a ``refused`` scene."""
    folder = write_sentinel2_safe(tmp_path / "in", size=8)
    (tmp_path / "out").mkdir()
    return {"dir": tmp_path / "in", "safe": folder, "out": tmp_path / "out", "mtd": folder / "MTD_MSIL2A.xml",
            "tl": next(folder.glob("GRANULE/*/MTD_TL.xml"))}
