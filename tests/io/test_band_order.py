"""Bands in the sensor's order (issue 24): a product that stacks its bands as the sensor numbers
them (MODIS: 645, 858, 469, 2130 nm) is fitted and corrected exactly as the same bands sorted by
wavelength, and the output keeps the input's band order."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from click.testing import CliRunner

from brdfcorr.chain.demo import demo_scene, write_demo_scene
from brdfcorr.cli import main

#: The demo's bands (450, 500, 560, 660, 740, 860 nm) in an order like a sensor's numbering.
ORDER = [3, 5, 0, 1, 2, 4]


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> dict[str, dict[str, Path]]:
    directory = tmp_path_factory.mktemp("band_order")
    scene = demo_scene(rows=40, pixel=12.0)
    shuffled = scene.isel(band=ORDER)
    shuffled["reflectance"].attrs["long_name"] = tuple(scene["reflectance"].attrs["long_name"][i] for i in ORDER)
    return {"sorted": write_demo_scene(directory, scene, name="sorted"),
            "sensor": write_demo_scene(directory, shuffled, name="sensor")}


def _run(*args) -> None:
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output


def test_fit_and_correct_do_not_depend_on_the_band_order(scenes, tmp_path):
    out = {}
    for name, files in scenes.items():
        inputs = ("--angles", files["angles"], "--classes", files["classes"])
        table = tmp_path / f"{name}.yaml"
        _run("fit-classes", files["image"], *inputs, "--model", "ross_thick_li_sparse", "-o", table)
        _run("correct", files["image"], *inputs, "--params", table, "-o", tmp_path / f"{name}.tif", "--no-progress")
        out[name] = yaml.safe_load(table.read_text())["classes"]
    # The fitted tables: the same numbers, wavelengths increasing, whatever the input's order.
    for sorted_entry, sensor_entry in zip(out["sorted"], out["sensor"]):
        assert sensor_entry["wavelengths"] == sorted(sensor_entry["wavelengths"]) == sorted_entry["wavelengths"]
        for name, values in sorted_entry["params"].items():
            np.testing.assert_allclose(sensor_entry["params"][name], values, rtol=1e-6)
    with rasterio.open(tmp_path / "sorted.tif") as by_wavelength, rasterio.open(tmp_path / "sensor.tif") as by_sensor:
        # The output in the input's band order, band for band the corrected sorted image.
        assert by_sensor.descriptions == tuple(by_wavelength.descriptions[i] for i in ORDER)
        np.testing.assert_allclose(by_sensor.read(), by_wavelength.read()[ORDER], rtol=1e-6)
