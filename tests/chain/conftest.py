"""Fixtures of the chain tests: the demo line with a land-cover map of it on another grid."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

from brdfcorr.chain.demo import demo_scene, write_demo_scene

ROOT = Path(__file__).parents[2]


@pytest.fixture(scope="session")
def landcover(tmp_path_factory) -> Path:
    """A directory with the demo line (60 rows) and the examples' WorldCover stand-in of it
    (EPSG:4326, about 5 m) as ``landcover.tif``."""
    root = tmp_path_factory.mktemp("share")
    paths = write_demo_scene(root / "scenes", demo_scene(rows=60, pixel=12.0))
    sys.path.insert(0, str(ROOT / "examples"))
    try:
        import make_landcover
    finally:
        sys.path.remove(str(ROOT / "examples"))
    make_landcover.main([str(paths["classes"]), str(root / "landcover.tif")])
    shutil.copy(ROOT / "examples" / "worldcover_lookup.yaml", root / "lookup.yaml")
    return root
