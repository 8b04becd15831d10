"""The worked examples of docs/sensors.md (AVIRIS-NG, NEON, EMIT): the products that
examples/make_sensor_products.py writes read back as the scene they were rendered from, and the
documented commands, run as written, remove the view-angle signal that the scene was rendered with.

tests/test_readme.py runs the same commands as subprocesses (they must run); their assessment reports
are checked here (the directories test_readme.py ran them in: they run once per session).
"""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest

from brdfcorr.chain.demo import demo_scene
from brdfcorr.testing import write_emit_granules, write_envi_line, write_neon_reflectance

ROOT = Path(__file__).parents[2]
SECTIONS = ("AVIRIS-NG and AVIRIS-3 (ENVI)", "NEON AOP (HDF5)", "EMIT (NetCDF)")


def example_commands() -> list[str]:
    """The shell commands of the worked examples, in page order: the generator's (in the section's
    introduction) and those of the three sensor subsections."""
    text = (ROOT / "docs" / "sensors.md").read_text()
    start = text.index("## Worked examples: AVIRIS-NG, NEON, EMIT")
    section = text[start:text.index("\n## ", start + 1)]
    assert all(f"### {title}" in section for title in SECTIONS)
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", section, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("  #")[0].strip()
            if line:
                commands.append(line)
    return commands


def _generator():
    spec = importlib.util.spec_from_file_location("make_sensor_products", ROOT / "examples" / "make_sensor_products.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def worked_examples(tmp_path_factory) -> dict[str, Path]:
    """What the documented commands wrote, by file name. tests/test_readme.py runs them as written
    (as subprocesses, each group once per test session for all workers: its groups sensors.md:products,
    :aviris, :neon and :emit, which are these commands in this order); this module checks what they wrote."""
    from test_readme import ALL_GROUPS, builder

    groups = ("sensors.md:products", "sensors.md:aviris", "sensors.md:neon", "sensors.md:emit")
    assert [command for group in groups for command in ALL_GROUPS[group].commands] == example_commands()
    build = builder(tmp_path_factory)
    return {path.name: path for group in groups[1:] for path in build(group).iterdir()}


def median_abs_slopes(report: dict, when: str) -> dict[int, float]:
    """Per class: the median over the bands of |relative slope| [%/10 deg] (the table `assess` prints)."""
    return {entry["id"]: float(np.nanmedian(np.abs(entry[when]["relative_slope"])))
            for entry in report["view_angles"]["classes"]}


@pytest.mark.parametrize("report_name", ["aviris_080000_assess.json", "neon_090000_assess.json", "emit_assess.json"])
def test_each_worked_example_removes_the_view_angle_slope(worked_examples, report_name):
    report = json.loads(worked_examples[report_name].read_text())
    before, after = median_abs_slopes(report, "before"), median_abs_slopes(report, "after")
    # The strata present: 1 (roofs and concrete, NDVI < 0.1), 2 (bare soil) and 5 (grass and trees).
    assert set(before) == {1, 2, 5}
    for class_id in before:
        # The scene was rendered with a BRDF that brightens one side of the line by several percent
        # per 10 deg (demo.py's kernel weights and paper 003's roofs): there is a signal to remove ...
        assert before[class_id] > 3.0, (class_id, before)
        # ... and a correction with parameters fitted to that signal (for EMIT, fitted on the
        # AVIRIS-NG lines of the same ground) must leave at most a quarter of it, or the figure's
        # "flat after" would be a false claim.
        assert after[class_id] < 0.25 * before[class_id], (class_id, before, after)


def test_every_pixel_with_a_stratum_is_corrected(worked_examples):
    # All three strata pass the fit's guard rails (two lines pooled), so the table has every
    # stratum and no pixel is flagged 'unknown class' (QA bit 4) in the AVIRIS-NG example's QA layer.
    import rasterio

    with rasterio.open(worked_examples["aviris_080000_qa.tif"]) as dataset:
        qa = dataset.read(1)
    assert not np.any(qa & 4)
    assert np.count_nonzero(qa == 0) > 0.9 * qa.size  # clean pixels: all but the pond (no class)


# --- the products read back as the scene they were written from ------------------------------------


@pytest.fixture(scope="module")
def small_scene():
    return demo_scene(rows=40, pixel=5.0, altitude=300.0, fov=36.0)


def test_envi_line_reads_back_as_the_scene(tmp_path, small_scene):
    from brdfcorr.io.sensors.envi import read_envi_image, read_envi_obs

    paths = write_envi_line(tmp_path, small_scene, "ang20260615t080000", altitude=300.0)
    image = read_envi_image(paths["image"])
    np.testing.assert_array_equal(image.values, small_scene["reflectance"].values)  # float32 both
    np.testing.assert_array_equal(image["wavelength"].values, small_scene["wavelength"].values)
    assert image.rio.transform() == small_scene.rio.transform() and image.rio.crs == small_scene.rio.crs
    angles = read_envi_obs(paths["obs"], like=image)
    for key in ("sza", "saa", "vza", "vaa"):
        np.testing.assert_array_equal(angles[key].values, small_scene[key].values.astype(np.float64))


def test_neon_line_reads_back_as_the_scene(tmp_path, small_scene):
    from brdfcorr.io.sensors.neon import read_neon_angles, read_neon_image

    path = write_neon_reflectance(tmp_path, small_scene, flight_line="080000")
    image = read_neon_image(path)
    # NEON stores round(reflectance x 10000) as int16: within half a stored unit.
    np.testing.assert_allclose(image.values, small_scene["reflectance"].values, atol=0.5e-4 + 1e-7)
    assert image.rio.transform() == small_scene.rio.transform()
    angles = read_neon_angles(path, like=image)
    np.testing.assert_array_equal(angles["vza"].values, small_scene["vza"].values)
    # One sun per flight line (the scene's mean), as NEON logs it.
    assert float(angles["sza"].mean()) == pytest.approx(float(small_scene["sza"].mean()), abs=1e-6)


def test_emit_granules_read_back_through_their_glt(tmp_path, small_scene):
    import xarray as xr

    from brdfcorr.io.sensors.emit import read_emit_image, read_emit_obs

    heading = 30.0
    paths = write_emit_granules(tmp_path, small_scene, heading=heading)
    image = read_emit_image(paths["reflectance"]).values
    angles = read_emit_obs(paths["obs"]).compute()
    location = xr.open_dataset(paths["reflectance"], group="location", engine="h5netcdf")
    glt_x, glt_y = location["glt_x"].values, location["glt_y"].values
    rows = small_scene.sizes["y"]
    attrs = xr.open_dataset(paths["reflectance"], engine="h5netcdf").attrs
    x0, dx, _, y0, _, dy = attrs["geotransform"]
    # EMIT's rule: cell (i, j) shows swath pixel (glt_y - 1, glt_x - 1); downtrack 0 is the scene's
    # southern (last) row, as the line is flown north; both azimuths turned by the heading.
    cells = np.argwhere(glt_x > 0)
    for i, j in cells[:: max(1, len(cells) // 50)]:
        down, cross = glt_y[i, j] - 1, glt_x[i, j] - 1
        np.testing.assert_array_equal(image[:, i, j], small_scene["reflectance"].values[:, rows - 1 - down, cross])
        # The cell's centre lies in the swath pixel it shows: within half a pixel diagonal (5 m
        # pixels) of the pixel's centre (location/lat, lon), in metres on a sphere.
        north = (y0 + (i + 0.5) * dy - location["lat"].values[down, cross]) * 111320.0
        east = (x0 + (j + 0.5) * dx - location["lon"].values[down, cross]) * 111320.0 * np.cos(np.radians(y0))
        assert np.hypot(east, north) <= 5.0 * np.sqrt(0.5) * 1.01
        assert float(angles["vaa"][i, j]) == pytest.approx(
            (float(small_scene["vaa"][rows - 1 - down, cross]) + heading) % 360.0, abs=1e-4)
    assert np.isnan(image[:, glt_x == 0]).all()


def test_the_generator_names_what_to_install_without_h5netcdf(tmp_path, monkeypatch, capsys):
    """As after `make demo` (no hdf5 extra): NEON and EMIT are refused before anything is written,
    naming the packages and the extra; the AVIRIS-NG lines alone are still written."""
    module = _generator()
    monkeypatch.setattr(module, "find_spec", lambda name: None if name == "h5netcdf" else importlib.util.find_spec(name))
    with pytest.raises(SystemExit) as stopped:
        module.main([str(tmp_path / "products"), "--rows", "8"])
    message = str(stopped.value.code)
    assert "EMIT and NEON products need h5netcdf (not installed here)" in message and "pip install 'brdfcorr[hdf5]'" in message
    assert "--sensor aviris-ng" in message and not (tmp_path / "products").exists()
    module.main([str(tmp_path / "products"), "--rows", "8", "--sensor", "aviris-ng"])
    assert sorted(path.name for path in (tmp_path / "products").iterdir()) == ["aviris-ng"]
    assert "wrote" in capsys.readouterr().out
