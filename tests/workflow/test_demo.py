"""The demo: scene geometry against closed forms and pvlib, the chain's output removes the
across-track gradient, the CLI writes what the README promises."""

import json
from pathlib import Path

import matplotlib.image
import numpy as np
import pandas as pd
import pvlib
import pytest
import rasterio
from click.testing import CliRunner
from pyproj import Transformer

from brdfcorr.chain.config import load_config
from brdfcorr.chain.demo import DEMO_TIME, demo_angles, demo_scene, demo_table, run_demo
from brdfcorr.chain.run import build_table, plan_run
from brdfcorr.cli import main

REPO = Path(__file__).resolve().parents[2]


def test_view_geometry_closed_form():
    angles = demo_angles(rows=4, pixel=20.0, altitude=1000.0, fov=72.0)
    columns = angles.sizes["x"]
    swath = 2 * 1000.0 * np.tan(np.radians(36.0))
    assert columns == round(swath / 20.0)
    across = 20.0 * (np.arange(columns) + 0.5) - swath / 2
    np.testing.assert_allclose(angles.vza.values[0], np.degrees(np.arctan(np.abs(across) / 1000.0)), rtol=1e-6)
    assert angles.vza.values.max() < 36.0 < angles.vza.values.max() + 0.6  # half a pixel inside the FOV
    # towards the sensor: west (270 deg) for pixels east of the track, east (90 deg) for the others
    assert set(angles.vaa.values[0, across > 0]) == {270.0} and set(angles.vaa.values[0, across < 0]) == {90.0}


def test_sun_position_matches_pvlib():

    angles = demo_angles(rows=4, pixel=50.0)
    x, y = float(angles.x[0]), float(angles.y[0])
    lon, lat = Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True).transform(x, y)
    position = pvlib.solarposition.get_solarposition(pd.DatetimeIndex([pd.Timestamp(DEMO_TIME)]), lat, lon)
    assert float(angles.sza[0, 0]) == pytest.approx(float(position["zenith"].iloc[0]), abs=0.01)
    assert float(angles.saa[0, 0]) == pytest.approx(float(position["azimuth"].iloc[0]), abs=0.01)


def test_demo_config_holds_the_demo_parameters():
    # configs/demo.yaml must correct with the parameters the scene was rendered with.
    config = load_config(REPO / "configs" / "demo.yaml")
    table, _ = build_table(plan_run(config, require_inputs=False))
    assert table.to_dict() == demo_table().to_dict()
    labels = {entry.id: entry.name for entry in table.classes}
    assert labels == {1: "roof_tile", 2: "blue_concrete", 3: "grass_illustrative", 4: "trees_illustrative",
                      5: "bare_soil_illustrative"}
    models = {entry.id: entry.model for entry in table.classes}
    assert models == {1: "torrance_sparrow", 2: "torrance_sparrow", 3: "ross_thick_li_sparse",
                      4: "ross_thick_li_sparse", 5: "ross_thick_li_sparse"}


def east_west(cube, classes, class_id, band=2):
    """Mean of a class's pixels in the eastern third of the swath over that in the western third."""
    third = classes.shape[1] // 3
    east, west = (cube[band][:, part][classes[:, part] == class_id].mean()
                  for part in (slice(-third, None), slice(None, third)))
    return east / west


def test_demo_run_removes_the_gradient(tmp_path):
    result = run_demo(tmp_path, rows=80, pixel=8.0, materials_figure=False)
    assert result.report.ok
    corrected_path = tmp_path / "corrected" / "line01_brdf.tif"
    with rasterio.open(result.inputs["image"]) as before, rasterio.open(corrected_path) as after:
        raw, corrected = before.read(), after.read()
        assert after.descriptions == before.descriptions == ("450 nm", "500 nm", "560 nm", "660 nm", "740 nm", "860 nm")
    with rasterio.open(result.inputs["classes"]) as source:
        classes = source.read(1)
    assert set(np.unique(classes)) == {0, 1, 2, 3, 4, 5}
    for class_id in (1, 2, 3, 4, 5):
        # East of the track the sensor looks into forward scattering: the specular roofs and concrete
        # (Torrance-Sparrow) are brighter there before, the vegetation and soil (RTLSR: volume
        # scattering and shadow hiding peak towards backscatter) darker. After the correction both
        # sides agree to the texture and noise level, for every class.
        before = east_west(raw, classes, class_id)
        assert before > 1.05 if class_id in (1, 2) else before < 0.95
        assert east_west(corrected, classes, class_id) == pytest.approx(1.0, abs=0.02)
    water = classes == 0
    np.testing.assert_array_equal(corrected[:, water], raw[:, water])  # no class: unchanged
    report = json.loads(result.report.path.read_text())
    assert report["scenes"][0]["qa"]["no_class"] == int(water.sum())
    assert report["scenes"][0]["qa"]["corrected"] == int((~water).sum())
    # The assess step measures the same: every class leans by 5-10 %/10 deg of view zenith before;
    # a correction with the parameters the scene was rendered with leaves only texture and 0.3 %
    # noise, so more than 95 % of the slope must go (docs/assess.md: 9.7 -> 0.07 on 300 lines).
    summary = report["scenes"][0]["assess"]
    assert [row["id"] for row in summary] == [1, 2, 3, 4, 5]
    for row in summary:
        slopes = row["median_abs_relative_slope_percent_per_10deg"]
        assert slopes["before"] > 5.0 and slopes["after"] < 0.05 * slopes["before"], row
    assessed = json.loads((tmp_path / "corrected" / "line01_assess.json").read_text())
    assert assessed["kind"] == "brdfcorr assess" and len(assessed["view_angles"]["classes"]) == 5
    figures = [tmp_path / "corrected" / name for name in ("line01_assess_profiles.png", "line01_before_after.png")]
    assert result.figures == figures and all(path.read_bytes()[:4] == b"\x89PNG" for path in figures)
    assert (tmp_path / "demo.yaml").read_text() == (REPO / "configs" / "demo.yaml").read_text()


def test_demo_scene_is_reproducible():
    a, b = demo_scene(rows=20, pixel=30.0), demo_scene(rows=20, pixel=30.0)
    np.testing.assert_array_equal(a.reflectance.values, b.reflectance.values)
    assert set(np.unique(a.classes.values)) <= {0, 1, 2, 3, 4, 5}


def test_demo_cli(tmp_path):
    # What the README promises: `brdfcorr demo` gives a corrected image and a picture.
    result = CliRunner().invoke(main, ["demo", "-o", str(tmp_path / "demo"), "--no-progress"])
    assert result.exit_code == 0, result.output
    for name in ("corrected/line01_brdf.tif", "corrected/line01_qa.tif", "corrected/line01_before_after.png",
                 "corrected/line01_assess.json", "corrected/line01_assess_profiles.png",
                 "corrected/run_report.json", "materials_brdf.png", "demo.yaml", "scene/line01_image.tif"):
        assert (tmp_path / "demo" / name).exists(), name
    assert "1 ok, 0 skipped, 0 failed" in result.output
    image = matplotlib.image.imread(tmp_path / "demo" / "materials_brdf.png")
    assert image.shape[0] > 400 and image.shape[1] > 800
    assert not [path for path in (tmp_path / "demo").rglob("*") if path.name.endswith(".partial")]  # no temp left
    # The copied chain reruns with `brdfcorr run` (and resumes: the scene is complete).
    again = CliRunner().invoke(main, ["run", str(tmp_path / "demo" / "demo.yaml"), "--no-progress"])
    assert again.exit_code == 0 and "0 ok, 1 skipped, 0 failed" in again.output


def test_demo_config_is_package_data():
    # `pip install .` (not editable) has no configs/: the demo reads its chain from the package,
    # a copy of the documented configs/demo.yaml that must not drift from it.
    from importlib.resources import files

    from brdfcorr.chain.demo import default_config

    packaged = files("brdfcorr").joinpath("data/demo.yaml")
    assert packaged.is_file()
    assert default_config() == Path(str(packaged))
    assert "configs" not in default_config().parts
    assert packaged.read_bytes() == (REPO / "configs" / "demo.yaml").read_bytes(), (
        "configs/demo.yaml and brdfcorr/data/demo.yaml differ: edit one, copy it to the other")
