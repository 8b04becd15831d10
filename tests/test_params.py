"""Tests of brdfcorr.params: the parameter-table format, validation, band interpolation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brdfcorr.errors import BrdfcorrError, InputError, ParameterError
from brdfcorr.models.materials import load_material
from brdfcorr.params import ClassEntry, ParameterTable, ReferenceGeometry, merge_tables

# The example table of DESIGN.md, verbatim.
DESIGN_EXAMPLE = """
reference: {sza: 30.0, vza: 0.0, raa: 0.0}      # optional default reference geometry
classes:
  - id: 1
    name: roof_tile
    model: torrance_sparrow
    params: {t0: 0.0245, t1: 0.20, w: 0.0362, n: 1.77, k: 0.25}
  - id: 2
    name: grass
    model: empirical
    wavelengths: [450, 550, 650, 850]              # nm; values below then have one entry per wavelength
    params: {a: [0.01, 0.02, 0.015, 0.05], b: 1.0, c: 0.02, t0: [0.02, 0.05, 0.03, 0.30]}
"""


@pytest.fixture
def table() -> ParameterTable:
    return ParameterTable.from_yaml_text(DESIGN_EXAMPLE, "design.yaml")


def test_design_example_parses(table):
    assert table.class_ids == (1, 2)
    assert table.reference == ReferenceGeometry(sza=30.0, vza=0.0, raa=0.0)
    # Table 1 of paper 003 (roof tile), as in the material library.
    assert table[1].params == load_material("roof_tile").params
    assert table[2].model == "empirical"


def test_scalar_applies_to_every_band(table):
    values = table[1].band_values(n_bands=3)
    assert list(values) == ["t0", "t1", "w", "n", "k"]  # signature order
    np.testing.assert_array_equal(values["w"], [0.0362] * 3)


def test_per_wavelength_interpolation(table):
    # Linear interpolation by hand: 500 nm is half way 450..550, 750 nm half way 650..850.
    values = table.for_bands(wavelengths=[450, 500, 750, 850])[2].params
    np.testing.assert_allclose(values["a"], [0.01, 0.015, 0.0325, 0.05])
    np.testing.assert_allclose(values["t0"], [0.02, 0.035, 0.165, 0.30])
    np.testing.assert_allclose(values["c"], [0.02] * 4)


def test_out_of_range_wavelength_is_an_error_unless_extrapolating(table):
    with pytest.raises(ParameterError, match=r"class 2 \(grass\).*parameter a.*900 nm.*\[450, 850\]"):
        table.for_bands(wavelengths=[550, 900])
    values = table.for_bands(wavelengths=[400, 900], extrapolate=True)[2].params
    np.testing.assert_allclose(values["a"], [0.01, 0.05])  # the edge values


def test_per_wavelength_table_needs_wavelengths(table):
    with pytest.raises(ParameterError, match=r"class 2 \(grass\).*wavelengths are needed"):
        table.for_bands(n_bands=4)


def test_per_band_lists_must_match_band_count():
    entry = ClassEntry(
        id=5, name="asphalt", model="lambertian", params={"t0": [0.1, 0.2, 0.3]}
    )
    np.testing.assert_array_equal(entry.band_values(n_bands=3)["t0"], [0.1, 0.2, 0.3])
    with pytest.raises(ParameterError, match=r"class 5 \(asphalt\).*parameter t0 has 3.*4 bands"):
        entry.band_values(n_bands=4)


@pytest.mark.parametrize(
    "text, pattern",
    [
        (
            "classes: [{id: 1, name: tile, model: torrance_sparrow, "
            "params: {t0: 0.02, t1: 0.2, w: -0.03, n: 1.7, k: 0.25}}]",
            r"bad\.yaml: class 1 \(tile\): torrance_sparrow: parameter w = -0\.03 is invalid",
        ),
        (
            "classes: [{id: 1, name: tile, model: torrance_sparrow, params: {t0: 0.02, t1: 0.2}}]",
            r"class 1 \(tile\): torrance_sparrow: missing parameter\(s\) w, n, k",
        ),
        (
            "classes: [{id: 4, name: lawn, model: lambertian, params: {t0: 0.1, t2: 1}}]",
            r"class 4 \(lawn\): lambertian: unknown parameter 't2'",
        ),
        (
            "classes: [{id: 4, name: lawn, model: lamb, params: {t0: 0.1}}]",
            r"class 4 \(lawn\): unknown surface model 'lamb'",
        ),
        (
            "classes: [{id: 4, name: lawn, model: lambertian, params: {t0: [0.1, nan]}}]",
            r"class 4 \(lawn\): lambertian: parameter t0 = nan is invalid",
        ),
        (
            "classes: [{id: 4, name: lawn, model: lambertian, params: {t0: 0.1}, colour: green}]",
            r"class 4 \(lawn\): colour: unknown key; allowed keys: bad_bands, fit, id, material, model, name, params, wavelengths",
        ),
        (
            "classes: [{id: 4, name: lawn, model: lambertian, params: {t0: [1, 2]}, "
            "wavelengths: [500, 400]}]",
            r"class 4 \(lawn\): wavelengths must be strictly increasing",
        ),
        (
            "classes: [{id: 4, name: lawn, model: lambertian, params: {t0: [1, 2]}, "
            "wavelengths: [400, 500, 600]}]",
            r"class 4 \(lawn\): parameter t0 has 2 values but 3 wavelengths",
        ),
        (
            "classes: [{id: 0, name: none, model: lambertian, params: {t0: 0.1}}]",
            r"class 0 \(none\): id: Input should be greater than or equal to 1",
        ),
        (
            "classes: [{id: 3, name: a, model: lambertian, params: {t0: 0.1}}, "
            "{id: 3, name: b, model: lambertian, params: {t0: 0.2}}]",
            r"class id\(s\) 3 appear more than once",
        ),
        ("reference: {sza: 95}", r"reference\.sza: reference sza = 95 deg must be in \[0, 90\)"),
        ("reference: {sza: noon}", r"reference\.sza: 'noon' is not allowed; allowed: a number, 'mean', 'observed' or 'hls'"),
        ("reference: {vza: 10, raz: 3}", r"reference\.raz: unknown key; allowed keys: raa, sza, vza"),
        ("- 1\n- 2", r"expected a mapping"),
        ("classes: [", r"not valid YAML \(line \d+, column \d+\)"),  # where depends on the parser
    ],
)
def test_invalid_tables_name_the_class_and_parameter(text, pattern):
    with pytest.raises(ParameterError, match=pattern) as caught:
        ParameterTable.from_yaml_text(text, source="bad.yaml")
    assert isinstance(caught.value, BrdfcorrError) and isinstance(caught.value, ValueError)
    assert str(caught.value).startswith("bad.yaml: ")
    assert "\n" not in str(caught.value)


def test_direct_construction_raises_parameter_error():
    with pytest.raises(ParameterError, match=r"class 1 \(x\): lambertian: parameter t0 = -1"):
        ParameterTable(classes=[{"id": 1, "name": "x", "model": "lambertian", "params": {"t0": -1}}])


def test_save_load_round_trip(table, tmp_path: Path):
    path = table.save(tmp_path / "table.yaml")
    again = ParameterTable.load(path)
    assert again == table
    assert again.to_dict() == table.to_dict()
    assert [p.name for p in tmp_path.iterdir()] == ["table.yaml"]  # no temporary left behind


def test_load_missing_file_names_it(tmp_path: Path):
    with pytest.raises(InputError, match="cannot read parameter table .*nope.yaml"):
        ParameterTable.load(tmp_path / "nope.yaml")


def test_load_error_names_the_file(tmp_path: Path):
    path = tmp_path / "broken.yaml"
    path.write_text("classes: [{id: 1, name: x, model: lambertian, params: {t0: -1}}]")
    with pytest.raises(ParameterError, match=r"broken\.yaml: class 1 \(x\): .*t0 = -1"):
        ParameterTable.load(path)


def test_with_class_adds_and_replaces_without_mutating(table):
    grass2 = ClassEntry(id=2, name="grass_dry", model="lambertian", params={"t0": 0.05})
    concrete = {"id": 7, "name": "concrete", "model": "lambertian", "params": {"t0": 0.1}}
    updated = table.with_class(grass2).with_class(concrete)
    assert updated.class_ids == (1, 2, 7)
    assert updated[2].name == "grass_dry" and updated[7].name == "concrete"
    assert table.class_ids == (1, 2) and table[2].name == "grass"  # the original is unchanged
    with pytest.raises(ParameterError, match="class 2 is already"):
        table.with_class(grass2, replace=False)
    with pytest.raises(ParameterError, match=r"class 9 \(bad\)"):
        table.with_class({"id": 9, "name": "bad", "model": "lambertian", "params": {"t0": -2}})
    assert updated.without_class(2).class_ids == (1, 7)


def test_merge_tables(table):
    other = ParameterTable(
        reference={"sza": "mean"},
        classes=[{"id": 1, "name": "tile2", "model": "lambertian", "params": {"t0": 0.3}}],
    )
    merged = merge_tables([table, other])
    assert merged[1].name == "tile2" and merged[2].name == "grass"
    assert merged.reference.sza == "mean"


def test_xarray_view(table):
    view = table.to_xarray(wavelengths=[450.0, 550.0])
    assert view["t0"].dims == ("class", "band")
    assert view["class"].values.tolist() == [1, 2]
    assert view["name"].values.tolist() == ["roof_tile", "grass"]
    assert view["model"].values.tolist() == ["torrance_sparrow", "empirical"]
    assert view["wavelength"].values.tolist() == [450.0, 550.0]
    assert view["t0"].attrs["units"] == "sr^-1"
    np.testing.assert_allclose(view["t0"].values, [[0.0245, 0.0245], [0.02, 0.05]])
    assert np.isnan(view["w"].sel({"class": 2})).all()  # empirical has no w
    assert np.isnan(view["a"].sel({"class": 1})).all()


def test_reference_geometry_defaults_and_describe():
    reference = ReferenceGeometry()
    assert (reference.sza, reference.vza, reference.raa) == ("observed", 0.0, 0.0)
    assert ReferenceGeometry(sza=30, vza=5, raa=90).describe() == "sza=30 vza=5 raa=90"


def test_example_config_is_a_working_table():
    path = Path(__file__).parent.parent / "configs" / "params_example.yaml"
    assert path.is_file(), f"{path} is part of the repository (the README's commands use it)"
    table = ParameterTable.load(path)
    assert len(table) >= 2
    table.for_bands(wavelengths=np.linspace(450, 850, 5))
