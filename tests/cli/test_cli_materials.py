"""`brdfcorr materials NAME -o TABLE`: the material library as classes of a parameter table."""

from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.models import load_material
from brdfcorr.params import ParameterTable


def test_materials_are_added_to_a_table(tmp_path):
    table_path = tmp_path / "table.yaml"
    for name, overwrite in (("roof_tile", []), ("red_concrete", ["--overwrite"])):  # an existing table: --overwrite
        result = CliRunner().invoke(main, ["materials", name, "-o", str(table_path), *overwrite])
        assert result.exit_code == 0, result.output
    result = CliRunner().invoke(main, ["materials", "blue_concrete", "-o", str(table_path), "--class-id", "7",
                                       "--overwrite"])
    assert result.exit_code == 0, result.output
    table = ParameterTable.load(table_path)
    assert table.class_ids == (1, 2, 7)
    assert table[2].name == "red_concrete" and table[2].model == "torrance_sparrow"
    assert table[2].params == load_material("red_concrete").params  # paper 003, Table 1


def test_output_needs_a_name(tmp_path):
    result = CliRunner().invoke(main, ["materials", "-o", str(tmp_path / "t.yaml")])
    assert result.exit_code == 2 and "-o needs a material NAME" in result.stderr
    assert not (tmp_path / "t.yaml").exists()
