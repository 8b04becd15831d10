"""Hostile input files and values: answered within seconds by one line and exit 2, never a hang,
a gigabyte, a traceback or a silently wrong number.

Each command-line case builds one hostile file beside a good synthetic scene
(:mod:`brdfcorr.testing`) and checks: exit code 2; stderr exactly one line ``brdfcorr: error: ...``
matching the expected message (naming the file and the key or line at fault); no output written;
every input byte-identical. Files that could block (a FIFO, ``/dev/urandom``) are given to the
command line in a subprocess killed after :data:`HANG_GUARD` seconds, so a regression fails instead
of hanging the test run. How fast bad documents are refused is measured by
``benchmarks/bench_documents.py``, not here: a test never reads the clock.

The parameter bounds of the registry are checked against the models on a dense angle grid, and the
correction's rule for invalid factors (``nodata``, never counted as corrected) on small scenes.
"""

from __future__ import annotations

import itertools
import math
import os
import tracemalloc
from functools import partial
from pathlib import Path

import _forked
import numpy as np
import pytest

from brdfcorr.correction import QA, normalize, qa_counts
from brdfcorr.errors import InputError, ParameterError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.io.files import MAX_ALIAS_NODES, MAX_DOCUMENT_BYTES, parse_yaml
from brdfcorr.models import SURFACE_MODELS, get_model
from brdfcorr.params import ParameterTable, merge_tables
from brdfcorr.testing import example_table, synthetic_scene, write_scene_chain

NY, NX = 16, 20
#: A command that could block is killed after this many seconds [s]: a guard against a hang, far
#: above any real answer (about 1 s), never a measurement of speed.
HANG_GUARD = 300.0

TABLE = ("classes: [{id: 1, name: tile, model: torrance_sparrow, "
         "params: {t0: 0.02, t1: %s, w: 0.036, n: %s, k: 0.25}}]\n")


def _bomb(leaf: str = "0.1") -> str:
    """Half a kilobyte whose aliases expand to 9^10 = 3.5 billion values (``*l9``)."""
    lines = [f"l0: &l0 [{', '.join([leaf] * 9)}]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, 10)]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def template(tmp_path_factory, write_example_scene) -> Path:
    return write_example_scene(tmp_path_factory.mktemp("template") / "scene", synthetic_scene(ny=NY, nx=NX))["dir"]


# ------------------------------------------------------------------------------------- helpers
# refused(scene, args, pattern, run=None): tests/conftest.py.
def _correct_args(scene, params: Path | str) -> list[str]:
    return ["correct", str(scene["image"]), "--angles", str(scene["angles"]), "--classes",
            str(scene["classes"]), "--params", str(params), "-o", str(scene["output"]), "--chunk", "16"]


def _chain(scene, text: str | None = None, **sections) -> Path:
    """The chain config over the one scene of ``scene`` (brdfcorr.testing.write_scene_chain)."""
    return write_scene_chain(scene["dir"], text, **sections)


def _subprocess(args: list, cwd: Path | None = None) -> tuple[int, str]:
    """The command line in its own process, killed after :data:`HANG_GUARD` (a FIFO cannot hang
    the test run): the exit code and stderr."""
    finished = _forked.run(["brdfcorr", *args], cwd=cwd, timeout=HANG_GUARD)
    return finished.returncode, finished.stderr


# ------------------------------------------------------------------------ parameter tables (correct)
LATIN_1 = "classes: [{id: 4, name: b\u00e9ton, model: lambertian, params: {t0: 0.1}}]\n"

TABLE_CASES = {
    "alias bomb": (
        lambda s: _write(s, "bomb.yaml", _bomb() + "classes: [{id: 4, name: flat, model: lambertian, "
                                                   "params: {t0: *l9}}]\n"),
        r"bomb\.yaml: not valid YAML \(line \d+, column \d+\): its aliases expand to more than 1,000,000 "
        r"values \(an alias bomb\?\)"),
    "duplicate key: the first classes vanish": (
        lambda s: _write(s, "dup.yaml", "classes: [{id: 1, name: tile, model: lambertian, params: {t0: 0.1}}]\n"
                                        "reference: {sza: 30}\n"
                                        "classes: [{id: 4, name: flat, model: lambertian, params: {t0: 0.1}}]\n"),
        r"dup\.yaml: not valid YAML \(line 3, column 1\): duplicate key 'classes' \(first on line 1\)"),
    "duplicate key inside a class": (
        lambda s: _write(s, "dup.yaml", "classes:\n- id: 1\n  name: tile\n  model: lambertian\n"
                                        "  params: {t0: 0.1}\n  id: 4\n"),
        r"dup\.yaml: not valid YAML \(line 6, column 3\): duplicate key 'id' \(first on line 2\)"),
    "yes as a parameter": (
        lambda s: _write(s, "yes.yaml", TABLE % ("yes", "1.77")),
        r"yes\.yaml: class 1 \(tile\): params\.t1: expected a number, got the boolean true \(YAML reads "
        r"unquoted yes, no, on, off"),
    "off in a per-band list": (
        lambda s: _write(s, "off.yaml", "classes: [{id: 4, name: flat, model: lambertian, "
                                        "params: {t0: [0.1, 0.1, off, 0.1]}}]\n"),
        r"off\.yaml: .*class 4 \(flat\): params\.t0\[2\]: expected a number, got the boolean false"),
    "on as the reference view zenith": (
        lambda s: _write(s, "on.yaml", "reference: {vza: on}\n" + TABLE % ("0.2", "1.77")),
        r"on\.yaml: reference\.vza: expected a number, got the boolean true"),
    "yes as a class id": (
        lambda s: _write(s, "id.yaml", "classes: [{id: yes, name: flat, model: lambertian, params: {t0: 0.1}}]\n"),
        r"id\.yaml: class True \(flat\): id: expected a number, got the boolean true"),
    "t1 = 1e308": (
        lambda s: _write(s, "t1.yaml", TABLE % ("1e308", "1.77")),
        r"t1\.yaml: class 1 \(tile\): torrance_sparrow: parameter t1 = 1e\+308 is invalid; it must be "
        r"finite and >= 0 and <= 1000 \[sr\^-1\]"),
    "n = 1e308": (
        lambda s: _write(s, "n.yaml", TABLE % ("0.2", "1.0e+308")),
        r"n\.yaml: class 1 \(tile\): torrance_sparrow: parameter n = 1e\+308 is invalid; it must be "
        r"finite and > 0 and <= 1e\+10 \[1\]"),
    "binary file": (
        lambda s: _write_bytes(s, "image_copy.yaml", s["image"].read_bytes()),
        r"cannot read parameter table \S*image_copy\.yaml: a binary file, not UTF-8 text \(NUL byte at offset \d+\)"),
    "Latin-1 file": (
        lambda s: _write_bytes(s, "latin1.yaml", LATIN_1.encode("latin-1")),
        r"cannot read parameter table \S*latin1\.yaml: not UTF-8 text \(byte 0xe9 on line 1\); save it as UTF-8"),
    "UTF-16 file": (
        lambda s: _write_bytes(s, "utf16.yaml", LATIN_1.encode("utf-16")),
        r"cannot read parameter table \S*utf16\.yaml: UTF-16 or UTF-32 text; save it as UTF-8"),
    "file over 10 MB": (
        lambda s: _write_bytes(s, "huge.yaml", b"# padding\n" * (MAX_DOCUMENT_BYTES // 10 + 1)),
        r"cannot read parameter table \S*huge\.yaml: larger than 10 MB; is it the right file\?"),
    "a huge string value": (
        lambda s: _write(s, "long.yaml", "classes: [{id: 4, name: flat, model: lambertian, params: {t0: '"
                                         + "x" * 1_000_000 + "'}}]\n"),
        r"long\.yaml: class 4 \(flat\): params\.t0: invalid value 'xxx+\.\.\.x+'$"),
}


def _write(scene, name: str, text: str) -> Path:
    path = scene["dir"] / name
    path.write_text(text, encoding="utf-8")
    return path


def _write_bytes(scene, name: str, data: bytes) -> Path:
    path = scene["dir"] / name
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("case", list(TABLE_CASES))
def test_hostile_parameter_table(scene, case, refused):
    build, pattern = TABLE_CASES[case]
    table = build(scene)
    line = refused(scene, _correct_args(scene, table), pattern)
    assert len(line) < 1000, "a message never repeats a huge input"


def test_the_alias_bomb_is_small_and_refused_before_it_grows():
    text = _bomb() + "t0: *l9\n"
    assert len(text) < 600 and 9**10 > 1000 * MAX_ALIAS_NODES
    tracemalloc.start()
    try:
        with pytest.raises(ParameterError, match=r"its aliases expand to more than 1,000,000 values"):
            parse_yaml(text, "bomb.yaml", ParameterError)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1e6, f"{peak} bytes: the bomb grew before it was refused"


@pytest.mark.parametrize("text, pattern", [
    ("a: &r [1, *r]\n", r"^x\.yaml: not valid YAML \(line 1, column 11\): alias \*r is inside the node it names "
                       r"\(a recursive document\)$"),
    # Deeper than MAX_DEPTH: refused by our composer (at level 101) or, deeper still, by libyaml's
    # own nesting bound first, in its words; either way one error naming the file and the place.
    ("[" * 150 + "]" * 150, r"^x\.yaml: not valid YAML \(line 1, column 101\): nested more than 100 levels deep$"),
    ("[" * 100_000 + "]" * 100_000, r"^x\.yaml: not valid YAML \(line 1, column \d+\): "),
    ("- " * 1_000_000 + "1\n", r"^x\.yaml: not valid YAML \(line 1, column \d+\): "),
    ("a: " + "1" * 5000 + "\n", r"^x\.yaml: not valid YAML: "),  # Python's bound on int() digits
])
def test_recursive_deep_and_oversized_documents_are_one_error(text, pattern):
    with pytest.raises(InputError, match=pattern) as raised:
        parse_yaml(text, "x.yaml", InputError)
    assert "\n" not in str(raised.value) and len(str(raised.value)) < 300


def test_legitimate_aliases_and_merge_keys_still_work():
    data = parse_yaml("base: &b {t0: 0.1, t1: 0.2}\nlist: &l [1, 2]\n"
                      "top: {<<: *b, t1: 0.3}\nmid: {<<: &m {<<: *b, t0: 0.5}}\nagain: *m\nmore: *l\n",
                      "x.yaml", InputError)
    assert data["top"] == {"t0": 0.1, "t1": 0.3}
    assert data["again"] == {"t0": 0.5, "t1": 0.2} and data["more"] == [1, 2]


def test_a_long_list_of_problems_is_one_short_line():
    classes = [{"id": i, "name": "x" * 10_000, "model": "lambertian", "params": {"t0": -1.0}} for i in range(1, 2001)]
    with pytest.raises(ParameterError) as raised:
        ParameterTable.from_dict({"classes": classes}, source="many.yaml")
    message = str(raised.value)
    assert len(message) < 3000 and "\n" not in message
    assert message.endswith("and 1990 more problems")


# --------------------------------------------------------- files that block: FIFO, /dev/urandom
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_as_a_table(scene, refused):
    fifo = scene["dir"] / "fifo.yaml"
    os.mkfifo(fifo)
    refused(scene, _correct_args(scene, fifo),
            r"cannot read parameter table \S*fifo\.yaml: not a regular file \(a FIFO \(named pipe\)\)", run=_subprocess)


@pytest.mark.skipif(not os.path.exists("/dev/urandom"), reason="needs /dev/urandom")
def test_dev_urandom_as_a_table(scene, refused):
    refused(scene, _correct_args(scene, "/dev/urandom"),
            r"cannot read parameter table /dev/urandom: not a regular file \(a character device\)", run=_subprocess)


def test_directory_as_a_table(scene):
    sub = scene["dir"] / "tables"
    sub.mkdir()
    with pytest.raises(InputError, match=r"cannot read parameter table \S*tables: Is a directory"):
        ParameterTable.load(sub)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_as_a_chain_config(scene, refused):
    fifo = scene["dir"].parent / "fifo_chain.yaml"
    os.mkfifo(fifo)
    refused(scene, ["run", fifo], r"cannot read chain config \S*fifo_chain\.yaml: not a regular file \(a FIFO",
            run=partial(_subprocess, cwd=scene["dir"].parent))


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_as_the_table_of_a_chain(scene, refused):
    os.mkfifo(scene["dir"] / "fifo.yaml")
    chain = _chain(scene, parameters={"table": "scene/fifo.yaml"})
    refused(scene, ["run", chain], r"cannot read parameter table \S*fifo\.yaml: not a regular file \(a FIFO",
            run=partial(_subprocess, cwd=scene["dir"].parent))


# ------------------------------------------------------------------------- chain configs (run)
CHAIN_CASES = {
    "binary file": (lambda s: _chain(s).write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR"),
                    r"cannot read chain config \S*chain\.yaml: a binary file, not UTF-8 text"),
    "Latin-1 file": (lambda s: _chain(s).write_bytes("name: r\u00e9sum\u00e9\n".encode("latin-1")),
                     r"cannot read chain config \S*chain\.yaml: not UTF-8 text \(byte 0xe9 on line 1\)"),
    "UTF-16 file": (lambda s: _chain(s).write_bytes(_chain(s).read_text().encode("utf-16")),
                    r"cannot read chain config \S*chain\.yaml: UTF-16 or UTF-32 text; save it as UTF-8"),
    "alias bomb": (lambda s: _chain(s, text=_bomb("x") + "name: *l9\n"),
                   r"chain\.yaml: not valid YAML \(line \d+, column \d+\): its aliases expand to more than"),
    "duplicate section: the first outputs vanish": (
        lambda s: _chain(s, text=_chain(s).read_text() + "outputs: {directory: elsewhere}\n"),
        r"chain\.yaml: not valid YAML \(line \d+, column 1\): duplicate key 'outputs' \(first on line \d+\)"),
    "yes as a worker count": (lambda s: _chain(s, engine={"scheduler": "synchronous", "workers": True}),
                              r"chain\.yaml: engine\.workers: expected a number, got the boolean true"),
    "on as a class-lookup id": (
        lambda s: _chain(s, inputs={"images": ["scene/image.tif"], "angles": {"path": "{dir}/angles.tif"},
                                    "classes": "{dir}/classes.tif", "class_lookup": {10: True}}),
        r"chain\.yaml: inputs\.class_lookup\[10\]: expected a number, got the boolean true"),
    "off as a factor limit": (
        lambda s: _chain(s, steps={"correct": {"limits": [False, 5]}}),
        r"chain\.yaml: steps\.correct\.limits\[0\]: expected a number, got the boolean false"),
    "file over 10 MB": (
        lambda s: _chain(s).write_bytes(_chain(s).read_bytes() + b"#" * MAX_DOCUMENT_BYTES),
        r"cannot read chain config \S*chain\.yaml: larger than 10 MB"),
    "Latin-1 parameter table": (
        lambda s: (_write_bytes(s, "latin1.yaml", LATIN_1.encode("latin-1")),
                   _chain(s, parameters={"table": "scene/latin1.yaml"})),
        r"cannot read parameter table \S*latin1\.yaml: not UTF-8 text"),
}


@pytest.mark.parametrize("case", list(CHAIN_CASES))
def test_hostile_chain_config(scene, case, monkeypatch, refused):
    build, pattern = CHAIN_CASES[case]
    monkeypatch.chdir(scene["dir"].parent)
    build(scene)
    refused(scene, ["run", scene["dir"].parent / "chain.yaml"], pattern)


def test_yes_as_an_override_value(scene, monkeypatch, refused):
    monkeypatch.chdir(scene["dir"].parent)
    chain = _chain(scene)
    refused(scene, ["run", chain, "--set", "engine.chunk=yes"],
            r"engine\.chunk: expected a number, got the boolean true")


# ------------------------------------------------------------------------- big valid tables
def _big_table_text(n_classes: int) -> str:
    lines = ["classes:"]
    lines += [f"  - {{id: {i}, name: c{i}, model: torrance_sparrow, "
              "params: {t0: 0.02, t1: 0.2, w: 0.036, n: 1.77, k: 0.25}}" for i in range(1, n_classes + 1)]
    return "\n".join(lines) + "\n"


def test_a_big_valid_table_loads_and_merges(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_text(_big_table_text(20_000))
    assert 2e6 < path.stat().st_size < MAX_DOCUMENT_BYTES
    table = ParameterTable.load(path)  # its speed: benchmarks/bench_documents.py
    assert len(table) == 20_000 and table.class_ids[-1] == 20_000
    merged = merge_tables([table, example_table()])
    assert len(merged) == 20_000 and merged[2].model == "empirical"


def test_one_shared_anchor_for_20000_classes_is_no_bomb(tmp_path):
    lines = ["shared: &p {t0: 0.02, t1: 0.2, w: 0.036, n: 1.77, k: 0.25}", "classes:"]
    lines += [f"  - {{id: {i}, name: c{i}, model: torrance_sparrow, params: *p}}" for i in range(1, 20_001)]
    data = parse_yaml("\n".join(lines), "shared.yaml", ParameterError)
    del data["shared"]
    assert len(ParameterTable.from_dict(data).classes) == 20_000


def test_duplicate_ids_of_a_big_table_are_found():
    classes = [{"id": i % 19_999 + 1, "name": "c", "model": "lambertian", "params": {"t0": 0.1}}
               for i in range(20_000)]
    with pytest.raises(ParameterError, match=r"class id\(s\) 1 appear more than once"):
        ParameterTable(classes=classes)


# ------------------------------------------------------------- parameter bounds keep models finite
#: The angle domain [0, 90) deg densely, with the largest float below 90 (cos = 2.5e-16).
ZENITHS = np.unique(np.concatenate([np.linspace(0.0, 89.9, 46), [89.99, 89.9999, 89.999999, 89.99999999,
                                                                   np.nextafter(90.0, 0.0)]]))
AZIMUTHS = np.unique(np.concatenate([np.linspace(0.0, 180.0, 37), [1e-9, 180.0 - 1e-9]]))


def _dense_geometry() -> ScatteringGeometry:
    ti, tr, phi = np.meshgrid(ZENITHS, ZENITHS, AZIMUTHS, indexing="ij")
    return ScatteringGeometry(ti.ravel(), tr.ravel(), phi.ravel())


def _corner_values(parameter) -> list[float]:
    """The ends of a parameter's range (the smallest positive float for an open 0, +-1e308 where
    unbounded) and its default."""
    low = parameter.lower if math.isfinite(parameter.lower) else -1e308
    if parameter.lower_open:
        low = np.nextafter(low, np.inf)
    high = parameter.upper if math.isfinite(parameter.upper) else 1e308
    return sorted({float(low), float(high), parameter.default})


def _corner_blocks(model):
    """Every corner of a model's parameter bounds (:func:`_corner_values`), in blocks of rows: one
    block per corner of the shape parameters, holding every corner of the intensity parameters
    (``model.linear``) as columns of one row per corner. One evaluation of a block gives one row of
    values per corner (numpy broadcasts the columns against the angles; each value is the same
    float64 arithmetic as a call with scalars). Yields (params, number of rows)."""
    intensities = [p for p in model.parameters if p.name in model.linear]
    shapes = [p for p in model.parameters if p.name not in model.linear]
    rows = np.array(list(itertools.product(*(_corner_values(p) for p in intensities))), dtype=float)
    for values in itertools.product(*(_corner_values(p) for p in shapes)):
        block = {p.name: rows[:, [index]] for index, p in enumerate(intensities)}
        yield {**block, **{p.name: value for p, value in zip(shapes, values)}}, len(rows)


@pytest.mark.parametrize("name", SURFACE_MODELS)
def test_every_model_is_finite_at_every_corner_of_its_bounds(name):
    model = get_model(name)
    geometry = _dense_geometry()
    corners = 0
    for params, rows in _corner_blocks(model):
        # A huge w or c overflows (w alpha)^2 on the way to exp(-inf) = 0: the value is still finite.
        with np.errstate(over="ignore"):
            brdf = np.asarray(model.evaluate(geometry, **params), dtype=float)
        finite = np.isfinite(np.broadcast_to(brdf, (rows, geometry.theta_i.size))).all(axis=1)
        row = int(np.argmin(finite))  # the first corner with a value that is not finite
        assert finite.all(), {key: np.ravel(value)[row if np.ndim(value) else 0] for key, value in params.items()}
        corners += rows
    assert corners == math.prod(len(_corner_values(p)) for p in model.parameters)  # every corner once


@pytest.mark.parametrize("name, params", [
    ("torrance_sparrow", {"t0": 1e3, "t1": 1e3, "w": 1e-6, "n": 1e10, "k": 1e10}),
    ("torrance_sparrow_simplified", {"t0": 1e3, "t1": 1e3, "w": 5.0, "n": 1e-6, "k": 0.0}),
    ("empirical", {"a": 1e3, "b": 10.0, "c": 1e-6, "t0": 1e3}),
    ("lambertian", {"t0": 1e3}),
    ("ross_thin_li_sparse", {"f_iso": 1e3, "f_vol": 1e3, "f_geo": 0.0}),
    ("ross_thick_li_dense", {"f_iso": 1e3, "f_vol": 1e3, "f_geo": 0.0}),
    ("rpv", {"rho0": 1e3, "k": 2.0, "theta": -0.5, "rho_c": 0.0}),
])
def test_factors_at_the_upper_bounds_are_finite_on_a_dense_angle_grid(name, params):
    """f(ref) / f(obs) at the intensity bounds: finite and positive for every pair of geometries of
    the grid (closed form: the model itself, evaluated in float64)."""
    model = get_model(name)
    brdf = np.asarray(model.evaluate(_dense_geometry(), **params), dtype=float)
    assert np.isfinite(brdf).all() and (brdf > 0).all()
    factors = brdf.max() / brdf.min()  # the largest factor between any two geometries
    assert np.isfinite(factors) and factors > 0


def test_a_table_at_the_bounds_corrects_every_pixel_with_a_finite_factor():
    table = ParameterTable(classes=[
        {"id": 1, "name": "ts", "model": "torrance_sparrow",
         "params": {"t0": 1e3, "t1": 1e3, "w": 1e-6, "n": 1e10, "k": 1e10}},
        {"id": 2, "name": "emp", "model": "empirical", "params": {"a": 1e3, "b": 10.0, "c": 1e-6, "t0": 1e3}},
        # f_geo K_geo is negative; a large f_geo makes f <= 0 (no valid factor, the next tests).
        {"id": 3, "name": "kernels", "model": "ross_thin_li_sparse",
         "params": {"f_iso": 1e3, "f_vol": 1e3, "f_geo": 0.0}},
        {"id": 4, "name": "rpv", "model": "rpv", "params": {"rho0": 1e3, "k": 2.0, "theta": -0.5, "rho_c": 0.0}},
    ])
    scene = synthetic_scene(ny=NY, nx=NX, table=table)
    for dtype in (np.float32, np.float64):
        cube = scene["reflectance"].astype(dtype)
        result = normalize(cube, scene["classes"], {a: scene[a] for a in ("sza", "saa", "vza", "vaa")},
                           table, reference={"sza": 35.0, "vza": 0.0, "raa": 0.0}, limits=None)
        assert np.isfinite(result.reflectance.values).all() and (result.reflectance.values > 0).all()
        counts = {key: int(value) for key, value in qa_counts(result.qa).items()}
        assert counts["corrected"] == NY * NX and counts["nodata"] == 0


# --------------------------------------------------- invalid factors: nodata, never "corrected"


def test_negative_model_values_are_nodata_not_limited_nor_corrected():
    # f = f_geo K_geo < 0 away from the hot spot (and 0 at nadir): no valid factor anywhere.
    table = ParameterTable(classes=[{"id": 1, "name": "shadow", "model": "ross_thick_li_sparse",
                                     "params": {"f_iso": 0.0, "f_vol": 0.0, "f_geo": 1.0}}])
    cube = np.full((2, 1, 3), 0.3)
    angles = np.array([[20.0, 40.0, 60.0]])
    result = normalize(cube, np.ones((1, 3), np.uint8),
                       {"sza": angles, "saa": np.zeros((1, 3)), "vza": angles, "vaa": np.full((1, 3), 90.0)}, table)
    assert np.isnan(result.reflectance.values).all()
    assert (result.qa.values & QA.NODATA).all() and not (result.qa.values & QA.LIMITED).any()
    counts = {key: int(value) for key, value in qa_counts(result.qa).items()}
    assert counts == {"corrected": 0, "limited": 0, "unknown_class": 0, "no_class": 0, "nodata": 3}


def test_a_peak_vanishing_at_the_reference_is_nodata_not_clipped():
    # A narrow pure peak (t0 = 0) underflows to 0 at the nadir reference: the factor is 0, not a
    # number to clip to the lower limit. Beside a class that has a signal there (class 2); a
    # reference at which no class has one is refused as a whole (issue 39: not an all-NaN output).
    mirror = {"id": 1, "name": "mirror", "model": "empirical", "params": {"a": 1.0, "b": 1.0, "c": 5.0, "t0": 0.0}}
    table = ParameterTable(classes=[mirror, {"id": 2, "name": "flat", "model": "lambertian", "params": {"t0": 0.1}}])
    sza = vza = np.full((1, 3), 30.0)
    saa, vaa = np.zeros((1, 3)), np.full((1, 3), 180.0)  # the specular direction: the observed peak
    angles = {"sza": sza, "saa": saa, "vza": vza, "vaa": vaa}
    classes = np.array([[1, 1, 2]], np.uint8)
    result = normalize(np.full((2, 1, 3), 0.3), classes, angles, table, reference={"sza": 30.0, "vza": 0.0})
    assert np.isnan(result.reflectance.values[:, :, :2]).all()
    np.testing.assert_allclose(result.reflectance.values[:, :, 2], 0.3)
    qa = result.qa.values[:, :2]
    assert ((qa & QA.NODATA) > 0).all() and not (qa & QA.LIMITED).any()
    assert int(qa_counts(result.qa)["corrected"]) == 1
    with pytest.raises(InputError, match=r"reference geometry sza=30 vza=0 raa=0: no class's model predicts a "
                                         r"positive reflectance there"):
        normalize(np.full((2, 1, 3), 0.3), np.ones((1, 3), np.uint8), angles, ParameterTable(classes=[mirror]),
                  reference={"sza": 30.0, "vza": 0.0})


def test_a_model_beyond_float32_is_nodata_in_float32_and_finite_in_float64():
    # RPV within its bounds at the hot spot near grazing: up to ~1e56 sr^-1, finite in float64 but
    # beyond float32's 3.4e38.
    table = ParameterTable(classes=[{"id": 1, "name": "rpv", "model": "rpv",
                                     "params": {"rho0": 1e3, "k": 1e-300, "theta": -0.999, "rho_c": 0.0}}])
    zenith = np.array([[30.0, 89.9999999999, np.nextafter(90.0, 0.0)]])
    zeros = np.zeros((1, 3))
    for dtype in (np.float64, np.float32):
        cube = np.full((2, 1, 3), 0.3, dtype=dtype)
        result = normalize(cube, np.ones((1, 3), np.uint8),
                           {"sza": zenith, "saa": zeros, "vza": zenith, "vaa": zeros}, table, limits=None)
        values, qa = result.reflectance.values, result.qa.values[0]
        invalid = (qa & QA.NODATA) > 0
        assert np.isnan(values[:, 0, invalid]).all() and np.isfinite(values[:, 0, ~invalid]).all()
        assert (values[:, 0, ~invalid] > 0).all()
        if dtype == np.float64:
            assert not invalid.any()
        else:
            assert invalid[1:].all() and not invalid[0]
        assert int(qa_counts(result.qa)["corrected"]) == int((~invalid).sum())


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
@pytest.mark.parametrize("command, pattern", [
    (lambda s, fifo: ["fit", str(fifo)], r"fifo: not a regular file"),
    (lambda s, fifo: ["validate", str(fifo)], r"cannot read chain config \S*fifo: not a regular file"),
    (lambda s, fifo: ["correct", str(s["image"]), "--angles", str(s["angles"]), "--classes", str(s["classes"]),
                      "--params", str(s["params"]), "--class-lookup", str(fifo), "-o", str(s["out"] / "x.tif")],
     r"cannot read lookup table \S*fifo: not a regular file"),
], ids=["measurements", "validate", "lookup table"])
def test_fifo_as_another_input(scene, command, pattern, refused):
    fifo = scene["dir"] / "fifo"
    os.mkfifo(fifo)
    try:
        refused(scene, command(scene, fifo), pattern, run=_subprocess)
    finally:
        fifo.unlink()


def test_escape_beyond_unicode_is_a_yaml_error():
    # Found by hypothesis in tests/workflow/test_property_parsing.py: libyaml refuses "\U00110000" and the
    # re-scan for PyYAML's message raised ValueError from chr() (an internal error).
    from brdfcorr.errors import ParameterError
    from brdfcorr.io.files import parse_yaml

    with pytest.raises(ParameterError, match=r"^t\.yaml: not valid YAML \(line 1, column 7\)"):
        parse_yaml('a: "\\U00110000"', "t.yaml", ParameterError)


# ----------------------------------------------------------------------- ENVI files cut short
def test_an_envi_image_cut_short_is_refused_not_read_as_zeros(scene, refused, correct_args):
    # GDAL's ENVI driver reads the missing part of a data file as zeros (it refuses a file only
    # under about half its size): the rows cut off were corrected as reflectance 0, exit 0.
    import rasterio.shutil

    image = scene["dir"] / "cut.img"
    rasterio.shutil.copy(scene["image"], image, driver="ENVI")
    size = image.stat().st_size
    with open(image, "r+b") as data:
        data.truncate(int(size * 0.6))
    refused(scene, correct_args(scene, image=image),
            rf"cannot read image file \S*cut\.img: its data file holds {int(size * 0.6)} of {size} bytes "
            r"\(a truncated or damaged file\?\)")


def test_an_envi_obs_file_cut_short_is_refused(tmp_path):
    # A sun and view at the zenith in the rows cut off (zeros): 18 % off in them, exit 0.
    import shutil

    from brdfcorr.errors import SensorInputError
    from brdfcorr.io.sensors.envi import read_envi_obs

    real = Path(__file__).resolve().parents[1] / "data" / "isofit_avirisng_profiling_cube"
    obs = tmp_path / "ang20170323t202244_obs_7000-7010"
    shutil.copy(real / obs.name, obs)
    shutil.copy(real / f"{obs.name}.hdr", tmp_path / f"{obs.name}.hdr")
    read_envi_obs(obs)  # whole: read
    with open(obs, "r+b") as data:
        data.truncate(obs.stat().st_size - 400)
    with pytest.raises(SensorInputError, match=r"its data file holds \d+ of \d+ bytes \(a truncated or damaged"):
        read_envi_obs(obs)
