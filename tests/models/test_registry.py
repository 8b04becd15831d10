"""Model registry and built-in material library."""

import inspect
import math

import numpy as np
import pytest

from brdfcorr.errors import ParameterError, UnknownNameError
from brdfcorr.models import (
    REGISTRY,
    SURFACE_MODELS,
    empirical,
    get_model,
    specular_peak,
    torrance_sparrow,
)
from brdfcorr.models.materials import load_material, material_names

PUBLIC_FUNCTIONS = {
    "torrance_sparrow": torrance_sparrow,
    "torrance_sparrow_simplified": torrance_sparrow,
    "empirical": empirical,
    "specular_peak": specular_peak,
}


@pytest.mark.parametrize("name", list(REGISTRY))
def test_every_model_is_complete_and_its_defaults_are_valid(name):
    model = get_model(name)
    assert model.description and model.reference
    for parameter in model.parameters:
        assert parameter.units and parameter.description
        assert parameter.lower <= parameter.default <= parameter.upper
    model.validate(model.defaults)  # must not raise
    assert math.isfinite(float(model(30.0, 40.0, 170.0, **model.defaults)))


@pytest.mark.parametrize("name", list(PUBLIC_FUNCTIONS))
def test_registry_names_match_the_function_signatures(name):
    signature = list(inspect.signature(PUBLIC_FUNCTIONS[name]).parameters)
    assert signature[:3] == ["theta_i", "theta_r", "phi"]
    assert tuple(signature[3 : 3 + len(get_model(name).parameters)]) == get_model(name).parameter_names


def test_physical_bounds_of_the_issue():
    # w <= 0, n <= 0, k < 0 are invalid; k = 0 is valid.
    ts = get_model("torrance_sparrow")
    assert ts.parameter("w").lower_open and ts.parameter("n").lower_open
    assert not ts.parameter("k").lower_open and ts.parameter("k").lower == 0.0
    ts.validate({**ts.defaults, "k": 0.0})


def test_validate_names_unknown_and_missing_parameters():
    ts = get_model("torrance_sparrow")
    with pytest.raises(ParameterError, match="unknown parameter 'sigma'"):
        ts.validate({**ts.defaults, "sigma": 1.0})
    with pytest.raises(ParameterError, match="missing parameter.*w"):
        ts.validate({key: value for key, value in ts.defaults.items() if key != "w"})


def test_unknown_model_lists_known_ones():
    with pytest.raises(UnknownNameError, match="unknown BRDF model 'phong'.*torrance_sparrow"):
        get_model("phong")
    assert set(SURFACE_MODELS) <= set(REGISTRY)


# Paper 003, Table 1 (550 nm, k fixed at 0.25).
TABLE_1 = {
    "spectralon_50": (0.157, 0.14, 0.032, 1.58, 1.2),
    "roof_tile": (0.0245, 0.20, 0.0362, 1.77, 4.1),
    "red_concrete": (0.0192, 1.06, 0.0804, 1.48, 5.1),
    "blue_concrete": (0.0685, 1.07, 0.0832, 1.48, 1.7),
    "red_aluminium": (0.0101, 2.99, 0.153, 1.73, 16.7),
}


@pytest.mark.parametrize("name", list(TABLE_1))
def test_material_library_holds_paper_003_table_1(name):
    material = load_material(name)
    t0, t1, w, n, chi2 = TABLE_1[name]
    assert material.params == {"t0": t0, "t1": t1, "w": w, "n": n, "k": 0.25}
    assert material.reduced_chi2 == chi2
    assert material.wavelength == 550.0
    assert material.model is get_model("torrance_sparrow")
    assert set(material.errors) == set(material.params)
    assert "Meister" in material.source and "Table 1" in material.source


def test_material_names_and_lookup():
    assert material_names() == tuple(TABLE_1)
    assert load_material("Roof tile") is load_material("roof_tile")
    assert load_material("red_aluminum") is load_material("red_aluminium")
    assert load_material("roof_tile").errors["w"] == 0.0004
    assert load_material("roof_tile").n_measurements == 145
    with pytest.raises(UnknownNameError, match="unknown material 'asphalt'.*roof_tile"):
        load_material("asphalt")


def test_material_brdf_is_its_model():
    tile = load_material("roof_tile")
    assert tile.brdf(50, 60, 180) == torrance_sparrow(50, 60, 180, **tile.params)


def test_the_light_table_of_model_names_is_the_registrys():
    # The command line's --model choices come from brdfcorr.defaults (no scipy); they must not drift.
    from brdfcorr.defaults import MODEL_NAMES, SURFACE_MODEL_NAMES

    assert MODEL_NAMES == tuple(REGISTRY)
    assert SURFACE_MODEL_NAMES == tuple(SURFACE_MODELS)
    assert set(SURFACE_MODELS) < set(REGISTRY)


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_a_single_number_gets_the_verdict_and_message_of_an_array(name):
    # Parameter.check takes a number (and a 0-d array, as table entries hold it) without numpy: the
    # same verdict and the same message as the array path, at the bounds and beyond them.
    for parameter in REGISTRY[name].parameters:
        edges = [value for value in (parameter.lower, parameter.upper) if math.isfinite(value)]
        values = [*edges, *(value + step for value in edges for step in (-1e-9, 1e-9, -1.0, 1.0)),
                  0.0, 1.0, -1.0, math.nan, math.inf, -math.inf, 2, 10**400]
        for value in values:
            outcomes = []
            for form in (value, np.asarray(value, dtype=float) if abs(value) < 1e300 else value, [value]):
                try:
                    parameter.check(form, name)
                    outcomes.append("valid")
                except (ParameterError, OverflowError) as error:
                    outcomes.append(f"{type(error).__name__}: {error}")
            assert outcomes[0] == outcomes[1] == outcomes[2], (parameter.name, value, outcomes)
