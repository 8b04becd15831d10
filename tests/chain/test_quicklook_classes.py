"""The chain's quicklook draws one profile per class of the class map the correction used (issue
38): with an aligned land-cover map and its lookup, the table's classes, not one "all pixels"
profile (the map's own grid differs from the image's)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from click.testing import CliRunner

import brdfcorr.chain.quicklook as chain_quicklook
from brdfcorr.chain.demo import default_config
from brdfcorr.cli import main


@pytest.fixture
def figures(monkeypatch) -> list:
    """The quicklook figures the chain draws, as it draws them."""
    drawn = []

    def spy(*args, **kwargs):
        figure = original(*args, **kwargs)
        drawn.append(figure)
        return figure

    original = chain_quicklook.quicklook_figure
    monkeypatch.setattr(chain_quicklook, "quicklook_figure", spy)
    return drawn


def _profiles(figure) -> list[str]:
    """The labels of the profile panel's lines (the axis with a legend entry per line)."""
    axis = next(axis for axis in figure.axes if axis.get_ylabel().startswith("column mean"))
    return [line.get_label() for line in axis.get_lines() if not line.get_label().startswith("_")]


def _run(root: Path, name: str, **inputs) -> Path:
    demo = yaml.safe_load(default_config().read_text())
    document = {
        "inputs": {"images": ["scenes/*_image.tif"], "scene_regex": "(?P<scene>.+)_image",
                   "angles": {"kind": "geotiff", "path": "{dir}/{scene}_angles.tif"}, **inputs},
        "parameters": demo["parameters"],
        "steps": {"correct": {"min_corrected_share": 0}, "quicklook": {}},
        "outputs": {"directory": f"out_{name}"},
        "engine": {"scheduler": "synchronous", "chunk": 64},
    }
    chain = root / f"{name}.yaml"
    chain.write_text(yaml.safe_dump(document))
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 0, result.output
    return root / f"out_{name}"


def test_an_aligned_map_gives_one_profile_per_class_of_the_table(landcover, figures):
    lookup = yaml.safe_load((landcover / "lookup.yaml").read_text())
    _run(landcover, "aligned", classes="landcover.tif", align_classes=True, class_lookup=lookup)
    # Independently: the land-cover map brought onto the image grid by `classes align`.
    aligned = landcover / "aligned.tif"
    result = CliRunner().invoke(main, ["classes", "align", str(landcover / "landcover.tif"), "--like",
                                       str(landcover / "scenes" / "line01_image.tif"), "--lookup",
                                       str(landcover / "lookup.yaml"), "-o", str(aligned)])
    assert result.exit_code == 0, result.output
    with rasterio.open(aligned) as dataset:
        ids = sorted(int(i) for i in np.unique(dataset.read(1)) if i > 0)
    assert ids == [1, 3, 4, 5]  # built-up -> roof tile, grassland, trees, bare soil (no concrete)
    names = {entry["id"]: entry["name"] for entry in yaml.safe_load(default_config().read_text())["parameters"]
             ["classes"]}
    figure, = figures
    labels = _profiles(figure)
    assert labels == [f"{names[i].replace('_', ' ')} {when}" for i in ids for when in ("before", "after")]
    assert not any(label.startswith("all pixels") for label in labels)


def test_without_a_class_map_step_the_file_map_gives_its_classes(landcover, figures):
    _run(landcover, "own", classes="{dir}/{scene}_classes.tif")
    with rasterio.open(landcover / "scenes" / "line01_classes.tif") as dataset:
        ids = sorted(int(i) for i in np.unique(dataset.read(1)) if 0 < i < 255)
    figure, = figures
    assert len(_profiles(figure)) == 2 * len(ids) == 10
