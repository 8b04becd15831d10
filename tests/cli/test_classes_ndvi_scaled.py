"""`classes ndvi` on scaled products (issue 24): the image is read as reflectance factors with its
scale and offset like everywhere else (`--scale`/`--offset` where untagged), and an image that does
not hold reflectance factors is refused naming `--scale`, never stratified as it is."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.chain.demo import demo_scene, write_demo_scene
from brdfcorr.cli import main

#: Landsat Collection 2 level 2: reflectance = stored * 2.75e-5 - 0.2 (uint16).
SCALE, OFFSET = 2.75e-5, -0.2


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    directory = tmp_path_factory.mktemp("ndvi_scaled")
    files = write_demo_scene(directory, demo_scene(rows=40, pixel=12.0))
    with rasterio.open(files["image"]) as source:
        profile, values, descriptions = source.profile, source.read(), source.descriptions
    counts = np.round((values - OFFSET) / SCALE).astype("uint16")
    for name, tag in (("tagged", True), ("untagged", False)):
        path = directory / f"{name}.tif"
        with rasterio.open(path, "w", **{**profile, "dtype": "uint16", "nodata": 0}) as target:
            target.write(counts)
            target.descriptions = descriptions
            if tag:
                target.scales, target.offsets = (SCALE,) * len(descriptions), (OFFSET,) * len(descriptions)
        files[name] = path
    return files


def _ndvi(image, output, *extra):
    return CliRunner().invoke(main, [str(a) for a in ("classes", "ndvi", image, "-o", output, *extra)])


def test_scaled_images_give_the_strata_of_the_reflectance_image(images, tmp_path):
    results = {}
    for name, extra in (("image", ()), ("tagged", ()), ("untagged", ("--scale", SCALE, "--offset", OFFSET))):
        result = _ndvi(images[name], tmp_path / f"{name}.tif", *extra)
        assert result.exit_code == 0, result.output
        with rasterio.open(tmp_path / f"{name}.tif") as dataset:
            results[name] = dataset.read(1)
    # Quantization (2.75e-5) may move a pixel on a bin edge: all but a handful agree.
    for name in ("tagged", "untagged"):
        assert (results[name] != results["image"]).mean() < 0.002, name


def test_an_untagged_scaled_image_is_refused(images, tmp_path):
    output = tmp_path / "strata.tif"
    result = _ndvi(images["untagged"], output)
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "untagged.tif: the values do not look like reflectance factors" in lines[0]
    assert "--scale" in lines[0] and not output.exists()
