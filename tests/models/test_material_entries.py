"""Built-in materials as parameter table classes (``material: NAME``, ``correct --material``) and the
warning for a single-wavelength material applied to far-away bands (issue 16)."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import ParameterError
from brdfcorr.models.materials import material_names
from brdfcorr.params import ParameterTable
from brdfcorr.testing import synthetic_scene, write_scene

#: paper 003, Table 1 (550 nm, k fixed at 0.25).
ROOF_TILE = {"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25}

TWO_MATERIALS = "classes:\n  - {id: 1, material: roof_tile}\n  - {id: 2, material: red_concrete}\n"


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def _warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("brdfcorr: warning:")]


def test_material_class_takes_the_library_values(tmp_path):
    path = tmp_path / "table.yaml"
    path.write_text("classes:\n  - {id: 1, name: tiles, material: roof_tile}\n  - {id: 2, material: Red concrete}\n")
    table = ParameterTable.load(path)
    tiles, concrete = table[1], table[2]
    assert (tiles.name, tiles.model, tiles.material) == ("tiles", "torrance_sparrow", "roof_tile")
    assert tiles.params == pytest.approx(ROOF_TILE)
    assert (concrete.name, concrete.material) == ("red_concrete", "red_concrete")  # name defaults
    # A saved table holds the resolved model and parameters; it reads back to the same numbers.
    saved = table.to_dict()["classes"][0]
    assert saved == {"id": 1, "name": "tiles", "model": "torrance_sparrow", "params": ROOF_TILE}
    again = ParameterTable.load(table.save(tmp_path / "saved.yaml"))
    assert again[1].params == tiles.params and again[1].material is None


def test_material_with_params_is_one_line_exit_2(tmp_path):
    path = tmp_path / "table.yaml"
    path.write_text("classes:\n  - {id: 3, name: tiles, material: roof_tile, params: {t0: 0.1}}\n")
    with pytest.raises(ParameterError, match=r"class 3 \(tiles\).*'material'.*'params'"):
        ParameterTable.load(path)
    result = _invoke("validate", path)
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "class 3 (tiles)" in lines[0]


def test_unknown_material_lists_the_known_ones(tmp_path):
    path = tmp_path / "table.yaml"
    path.write_text("classes:\n  - {id: 1, material: slate}\n")
    result = _invoke("validate", path)
    assert result.exit_code == 2
    message = result.stderr.strip()
    assert len(message.splitlines()) == 1 and "class 1" in message and "'slate'" in message
    assert all(name in message for name in material_names())


@pytest.fixture(scope="module")
def two_material_table():
    return ParameterTable.from_yaml_text(TWO_MATERIALS)


def _scene_files(directory, table, wavelengths):
    scene = synthetic_scene(ny=24, nx=24, wavelengths=wavelengths, table=table)
    return write_scene(directory, scene)


def _correct(files, output, *options):
    return _invoke("correct", files["image"], "--angles", files["angles"], "--classes", files["classes"],
                   "-o", output, "--chunk", 16, *options)


def test_correct_with_materials_equals_the_table(tmp_path, two_material_table):
    files = _scene_files(tmp_path / "scene", two_material_table, (500.0, 560.0, 620.0))
    table_path = two_material_table.save(tmp_path / "table.yaml")
    by_table = _correct(files, tmp_path / "table.tif", "--params", table_path)
    by_option = _correct(files, tmp_path / "option.tif", "--material", "1=roof_tile", "--material", "2=red_concrete")
    assert by_table.exit_code == 0, by_table.output
    assert by_option.exit_code == 0, by_option.output
    with rasterio.open(tmp_path / "table.tif") as a, rasterio.open(tmp_path / "option.tif") as b:
        np.testing.assert_array_equal(a.read(), b.read())
        assert b.tags()["brdf_parameter_table"] == "--material 1=roof_tile --material 2=red_concrete"
    assert not _warnings(by_option.stderr)  # every band within 100 nm of 550 nm


def test_material_option_wins_over_the_table(tmp_path, two_material_table):
    files = _scene_files(tmp_path / "scene", two_material_table, (500.0, 600.0))
    table_path = two_material_table.save(tmp_path / "table.yaml")
    # (an id given twice with two materials is refused: tests/cli/test_cli_settings.py)
    result = _correct(files, tmp_path / "out.tif", "--params", table_path, "--material", "2=blue_concrete")
    assert result.exit_code == 0, result.output
    with rasterio.open(tmp_path / "out.tif") as written:
        assert '"name":"blue_concrete"' in written.tags()["brdf_parameter_table_content"]


@pytest.mark.parametrize("option", [[], ["--material", "1"], ["--material", "x=roof_tile"],
                                    ["--material", "1=slate"]])
def test_material_option_usage_errors(tmp_path, two_material_table, option):
    files = _scene_files(tmp_path / "scene", two_material_table, (500.0, 600.0))
    result = _correct(files, tmp_path / "out.tif", *option)
    assert result.exit_code == 2
    assert not (tmp_path / "out.tif").exists()


def test_far_wavelength_warning_once_per_class(tmp_path, two_material_table):
    files = _scene_files(tmp_path / "scene", two_material_table, (450.0, 850.0, 1650.0, 2400.0))
    table_path = two_material_table.save(tmp_path / "table.yaml")
    result = _correct(files, tmp_path / "out.tif", "--params", table_path, "--material", "1=roof_tile",
                      "--material", "2=red_concrete")
    assert result.exit_code == 0, result.output
    shown = _warnings(result.stderr)
    assert len(shown) == 2
    assert "class 1 (roof_tile)" in shown[0] and "550 nm" in shown[0] and "2400" in shown[0]
    assert "class 2 (red_concrete)" in shown[1]
    marked = tmp_path / "marked.yaml"
    marked.write_text(TWO_MATERIALS)  # material: keys in the table file
    result = _correct(files, tmp_path / "marked.tif", "--params", marked)
    assert result.exit_code == 0 and len(_warnings(result.stderr)) == 2
    # The same table saved with resolved values carries no material marker: no warning.
    plain = _correct(files, tmp_path / "plain.tif", "--params", table_path)
    assert plain.exit_code == 0 and not _warnings(plain.stderr)
