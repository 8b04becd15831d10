"""Arbitrary documents never produce a traceback: parameter tables and chain configs either parse
or raise one of the library's errors (:class:`brdfcorr.errors.BrdfcorrError`), with a one-line
message.

Property: for any YAML-ish value (None, booleans, integers, floats including NaN and inf, text,
nested lists and mappings), any mutation of a valid document (a value replaced, a key deleted or
added) and any text, the parsers raise nothing but ``BrdfcorrError``; what they accept is a valid
table or config (re-validating its own dump gives the same object).

The model properties the issue lists (finite, non-negative, reciprocal, 0 <= G <= 1) are in
``tests/models/test_models.py`` (``test_g_bounded_and_reciprocal``, ``test_ts_finite_nonnegative_reciprocal``,
``test_empirical_finite_nonnegative_reciprocal``, ``test_fresnel_is_a_reflectance``); only
``specular_peak`` (paper 000, eq. 3), checked there at fixed points, gets its property test here.
"""

from __future__ import annotations

import copy
import os
import tempfile
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from brdfcorr.chain.config import ChainConfig, apply_overrides, load_config
from brdfcorr.chain.run import plan_run
from brdfcorr.errors import BrdfcorrError
from brdfcorr.models import specular_peak
from brdfcorr.params import ParameterTable

# More examples for a long search: BRDFCORR_PROPERTY_EXAMPLES=5000 pytest tests/workflow/test_property_parsing.py
PROPERTY = settings(max_examples=int(os.environ.get("BRDFCORR_PROPERTY_EXAMPLES", 150)), deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])

scalars = (st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=True, allow_infinity=True)
           | st.text(max_size=12) | st.sampled_from(["torrance_sparrow", "lambertian", "t0", "id", "mean",
                                                     "observed", "scenes/*.tif", "{scene}", "geotiff"]))
keys = st.text(max_size=10) | st.integers(-3, 5) | st.sampled_from(
    ["id", "name", "model", "params", "wavelengths", "classes", "reference", "sza", "vza", "raa",
     "inputs", "outputs", "steps", "engine", "parameters", "directory", "images", "angles", "kind", "path"])
values = st.recursive(scalars, lambda children: st.lists(children, max_size=4)
                      | st.dictionaries(keys, children, max_size=4), max_leaves=16)

#: The parameter table of DESIGN.md.
TABLE = {
    "reference": {"sza": 30.0, "vza": 0.0, "raa": 0.0},
    "classes": [
        {"id": 1, "name": "roof_tile", "model": "torrance_sparrow",
         "params": {"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25}},
        {"id": 2, "name": "grass", "model": "empirical", "wavelengths": [450, 550, 650, 850],
         "params": {"a": [0.01, 0.02, 0.015, 0.05], "b": 1.0, "c": 0.02, "t0": [0.02, 0.05, 0.03, 0.30]}},
    ],
}

#: A chain config using most sections.
CHAIN = {
    "name": "property",
    "inputs": {"images": ["scenes/*_image.tif"], "scene_regex": "(?P<scene>.+)_image",
               "angles": {"kind": "geotiff", "path": "{dir}/{scene}_angles.tif"},
               "classes": "{dir}/{scene}_classes.tif", "wavelengths": [480, 560, 660, 830]},
    "parameters": {"materials": {1: "roof_tile"}, "classes": [TABLE["classes"][1]], "table": "params.yaml"},
    "reference": {"sza": "mean", "vza": 0.0},
    "steps": {"correct": {"limits": [0.2, 5.0], "unknown": "keep"}, "quicklook": {"bands": [3, 2, 1]}},
    "outputs": {"directory": "out", "naming": "{scene}_brdf.tif", "existing": "skip"},
    "engine": {"scheduler": "threads", "workers": 1, "chunk": 256},
}


def _paths(node, prefix=()):
    """Every (container path, key) of a nested document."""
    if isinstance(node, dict):
        for key, child in node.items():
            yield prefix, key
            yield from _paths(child, prefix + (key,))
    elif isinstance(node, list):
        for index, child in enumerate(node):
            yield prefix, index
            yield from _paths(child, prefix + (index,))


@st.composite
def mutated(draw, document):
    """``document`` with one to three random edits: a value replaced, a key deleted or added."""
    document = copy.deepcopy(document)
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(document))
        if not paths:
            break
        prefix, key = draw(st.sampled_from(paths))
        container = document
        for part in prefix:
            container = container[part]
        action = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if action == "replace":
            container[key] = draw(values)
        elif action == "delete":
            del container[key]
        elif isinstance(container, dict):
            container[draw(keys)] = draw(values)
        else:
            container.append(draw(values))
    return document


def _only_library_errors(function, *args):
    """Call ``function``; a BrdfcorrError is a fine outcome (one line), anything else fails."""
    try:
        return function(*args)
    except BrdfcorrError as error:
        assert "\n" not in str(error), str(error)
        assert str(error).strip()
        return None


# ------------------------------------------------------------------------------ parameter tables
@PROPERTY
@given(values)
def test_table_from_arbitrary_values(data):
    _only_library_errors(ParameterTable.from_dict, data, "table.yaml")


@PROPERTY
@given(mutated(TABLE), st.lists(st.floats(300, 1000), min_size=1, max_size=5))
def test_table_from_mutated_documents(document, wavelengths):
    table = _only_library_errors(ParameterTable.from_dict, document, "table.yaml")
    if table is not None:
        # What is accepted is a valid table: it round-trips, and resolving it to bands only
        # raises the library's errors (e.g. wavelengths outside a class's range).
        assert ParameterTable.from_dict(table.to_dict()) == table
        resolved = _only_library_errors(table.for_bands, sorted(wavelengths))
        for entry in (resolved or {}).values():
            for value in entry.params.values():
                assert value.shape == (len(wavelengths),) and np.all(np.isfinite(value))


@PROPERTY
@given(st.text(max_size=200))
@example("classes: [")
@example("date: 2001-02-30")  # a YAML timestamp that is no date: ValueError inside PyYAML
@example("classes: !!python/object/apply:os.system ['true']")
@example("&a [*a]")
@example("? [a, b]\n: c")
@example("\t")
def test_table_from_arbitrary_text(text):
    _only_library_errors(ParameterTable.from_yaml_text, text, "table.yaml")


@PROPERTY
@given(mutated(TABLE), st.data())
def test_table_from_dumped_and_damaged_yaml(document, data):
    """YAML text of a mutated table, then a few characters inserted or deleted."""
    text = yaml.safe_dump(document, sort_keys=False)
    for _ in range(data.draw(st.integers(0, 3))):
        position = data.draw(st.integers(0, len(text)))
        if data.draw(st.booleans()):
            text = text[:position] + data.draw(st.text(min_size=1, max_size=3)) + text[position:]
        else:
            text = text[:position] + text[position + 1:]
    _only_library_errors(ParameterTable.from_yaml_text, text, "table.yaml")


# ----------------------------------------------------------------------------------- chain configs
_SCRATCH = tempfile.TemporaryDirectory(prefix="brdfcorr_property_")  # removed at exit
BASE = Path(_SCRATCH.name)


@PROPERTY
@given(values)
def test_config_from_arbitrary_values(data):
    _only_library_errors(ChainConfig.from_dict, data, "chain.yaml", BASE)


@PROPERTY
@given(mutated(CHAIN))
def test_config_from_mutated_documents_and_plans(document):
    config = _only_library_errors(ChainConfig.from_dict, document, "chain.yaml", BASE)
    if config is not None:
        assert ChainConfig.from_dict(config.to_dict(), "chain.yaml", BASE) == config
        # Planning an accepted config (no inputs on disk) raises only the library's errors.
        _only_library_errors(lambda: plan_run(config, require_inputs=False))
        _only_library_errors(lambda: plan_run(config, require_inputs=True))


@PROPERTY
@given(st.text(max_size=200))
@example("inputs: {images: [a\n")
@example("engine: {workers: 2001-02-30}")
@example("inputs: !!python/object/apply:os.system ['true']")
@example("")
def test_config_file_with_arbitrary_text(text):
    path = BASE / "chain.yaml"
    path.write_text(text)
    _only_library_errors(load_config, path)


@PROPERTY
@given(values, st.dictionaries(st.text(max_size=20), values, max_size=3))
@example({"engine": 3}, {"engine.workers": 2})
@example({}, {"...": 1})
def test_overrides_of_arbitrary_documents(data, overrides):
    result = _only_library_errors(apply_overrides, data, overrides, "chain.yaml")
    if result is not None:
        _only_library_errors(ChainConfig.from_dict, result, "chain.yaml", BASE)


# ------------------------------------------------------------------------- specular_peak (paper 000)
zenith = st.floats(0.0, 89.9)


@PROPERTY
@given(zenith, zenith, st.floats(0.0, 180.0), st.floats(0.01, 30.0))
def test_specular_peak_finite_nonnegative_reciprocal(theta_i, theta_r, phi, sigma):
    """Paper 000 eq. 3 is a reciprocal BRDF: f(i, r) = f(r, i) >= 0, finite below grazing."""
    forward = specular_peak(theta_i, theta_r, phi, sigma)
    backward = specular_peak(theta_r, theta_i, phi, sigma)
    assert np.isfinite(forward) and forward >= 0
    np.testing.assert_allclose(forward, backward, rtol=1e-9, atol=1e-300)
