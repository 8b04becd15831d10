"""Chain configs: validation messages (key path, allowed values), overrides, example configs."""

import shutil
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from brdfcorr.chain.config import ChainConfig, ConfigError, apply_overrides, format_pattern, load_config
from brdfcorr.cli import main

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((REPO / "configs").glob("*.yaml"))
CHAINS = [path for path in EXAMPLES if "inputs" in (yaml.safe_load(path.read_text()) or {})]


def minimal(**sections) -> dict:
    document = {
        "inputs": {"images": ["scenes/*_image.tif"], "scene_regex": r"(?P<scene>.+)_image",
                   "angles": {"kind": "geotiff", "path": "{dir}/{scene}_angles.tif"},
                   "classes": "{dir}/{scene}_classes.tif"},
        "parameters": {"materials": {1: "roof_tile"}},
        "outputs": {"directory": "out"},
    }
    for key, value in sections.items():
        document[key] = value
    return document


def error_of(document) -> str:
    with pytest.raises(ConfigError) as caught:
        ChainConfig.from_dict(document, "chain.yaml")
    return str(caught.value)


def test_defaults_and_base_dir(tmp_path):
    path = tmp_path / "chain.yaml"
    path.write_text(yaml.safe_dump(minimal()))
    config = load_config(path)
    assert config.engine.scheduler == "threads"
    assert config.outputs.existing == "skip"
    assert config.steps.correct.limits == (0.2, 5.0)  # DESIGN.md default factor range
    assert config.steps.fit is None and config.steps.quicklook is None
    assert config.resolve("out") == tmp_path.resolve() / "out"  # relative to the config file
    assert config.resolve("/abs/x.tif") == Path("/abs/x.tif")


@pytest.mark.parametrize("section, value, expected", [
    ("engine", {"scheduler": "thread"},
     "chain.yaml: engine.scheduler: 'thread' is not allowed; allowed: 'threads', 'processes', "
     "'synchronous' or 'distributed'"),
    ("outputs", {"directory": "out", "compres": "lzw"},
     "chain.yaml: outputs.compres: unknown key; allowed keys: cog, compress, directory, existing, "
     "format, interleave, naming, qa_naming, quicklook_naming, report, strata_naming, uncertainty, "
     "uncertainty_naming"),
    ("reference", {"sza": "meen"},
     "chain.yaml: reference.sza: 'meen' is not allowed; allowed: a number, 'mean', 'observed' or 'hls'"),
    ("steps", {"fit": {"source": "imag"}},
     "chain.yaml: steps.fit: source 'imag' is not allowed; allowed: 'imagery', 'goniometer'"),
    ("engine", {"chunk": 100}, "chain.yaml: engine.chunk: chunk 100 must be a multiple of 16"),
])
def test_error_names_key_path_and_allowed_values(section, value, expected):
    assert error_of(minimal(**{section: value})).startswith(expected)


def test_errors_inside_lists_and_unions():
    document = minimal(steps={"fit": {"source": "goniometer", "measurements": [
        {"file": "a.csv", "class_id": 1, "name": "tile", "fixd": {"k": 0.25}}]}})
    message = error_of(document)
    assert message.startswith("chain.yaml: steps.fit.measurements[0].fixd: unknown key; allowed keys: class_id, file, fixed")
    message = error_of(minimal(parameters={"materials": {1: "roof"}}))
    assert "parameters.materials: 'roof' is not a built-in material; allowed: 'spectralon_50', 'roof_tile'" in message
    message = error_of(minimal(parameters={"classes": [{"id": 3, "name": "g", "model": "lambertian", "params": {"t0": -1}}]}))
    assert message.startswith("chain.yaml: parameters.classes[0]: class 3 (g):")
    assert "t0" in message


def test_unknown_top_level_key_and_missing_section():
    assert error_of({**minimal(), "enigne": {}}).startswith(
        "chain.yaml: enigne: unknown key; allowed keys: engine, inputs, name, outputs, parameters, reference, steps")
    document = minimal()
    del document["inputs"]["classes"]
    assert error_of(document).startswith("chain.yaml: inputs.classes is missing")
    # inputs.angles may be left out (product folders bring their own): image files without it are
    # refused by the plan (tests/chain/test_product_chain.py)


def test_patterns_and_semantic_checks():
    document = minimal()
    document["inputs"]["classes"] = "{scen}_classes.tif"
    assert "pattern '{scen}_classes.tif' uses {scen}; allowed placeholders: {dir}, {parent}, {stem}, {scene}" in error_of(document)
    assert "must contain {scene}" in error_of(minimal(outputs={"directory": "o", "naming": "fixed.tif"}))
    assert "needs a parameter table" in error_of(minimal(parameters={}))
    assert "only used with scheduler 'distributed'" in error_of(minimal(engine={"address": "tcp://x:1"}))
    assert "lower <= 1 <= upper" in error_of(minimal(steps={"correct": {"limits": [1.5, 5]}}))
    document = minimal()
    document["inputs"]["scene_regex"] = "(?P<name>.+)"
    assert "no named group (?P<scene>...)" in error_of(document)


def with_inputs(**keys) -> dict:
    return {**minimal()["inputs"], **keys}


@pytest.mark.parametrize("sections, expected", [
    ({"steps": {"correct": {"terrain": {}}}},
     "chain.yaml: steps.correct.terrain needs slope and aspect: set inputs.slope_aspect or inputs.dem"),
    ({"inputs": with_inputs(dem="{dir}/{scene}_dem.tif")},
     "chain.yaml: inputs.slope_aspect and inputs.dem are read by steps.correct.terrain"),
    ({"inputs": with_inputs(dem="{dir}/{scene}_dem.tif", slope_aspect="{dir}/{scene}_sa.tif"),
      "steps": {"correct": {"terrain": {}}}},
     "chain.yaml: inputs: give slope_aspect or dem, not both"),
    ({"inputs": with_inputs(dem="{dir}/{sceen}_dem.tif"), "steps": {"correct": {"terrain": {}}}},
     "chain.yaml: inputs.dem: pattern '{dir}/{sceen}_dem.tif' uses {sceen}"),
    ({"inputs": with_inputs(dem="{dir}/{scene}_dem.tif"), "steps": {"correct": {"terrain": {"topographic": "c"}}}},
     "chain.yaml: steps.correct.terrain: topographic 'c' fits an empirical C"),
    ({"steps": {"correct": {"terrain": {"topographic": "minnaert"}}}},
     "chain.yaml: steps.correct.terrain.topographic: 'minnaert' is not allowed; allowed: 'cosine', 'c', 'scs', "
     "'scs+c' or 'none'"),
    ({"steps": {"correct": None, "assess": {}}},
     "chain.yaml: steps: assess compares input and corrected images: it needs the correct step"),
    ({"steps": {"assess": {"sign_by": "track"}}},
     "chain.yaml: steps.assess: sign_by 'track' needs the flight direction: set heading [deg]"),
    ({"steps": {"assess": {"heading": 10}}}, "chain.yaml: steps.assess: heading is only used with sign_by 'track'"),
    ({"steps": {"assess": {"bin_width": 0}}},
     "chain.yaml: steps.assess.bin_width: Input should be greater than or equal to 0.01"),
    ({"outputs": {"directory": "o", "interleave": "bil"}},
     "chain.yaml: outputs: interleave applies to format ENVI, not 'GTiff'"),
    ({"outputs": {"directory": "o", "format": "ENVI", "interleave": "bip"}},
     "chain.yaml: outputs.interleave: 'bip' is not allowed; allowed: 'bsq' or 'bil'"),
    ({"outputs": {"directory": "o", "uncertainty": True}, "steps": {"correct": None}},
     "chain.yaml: outputs.uncertainty is written by the correct step: it needs steps.correct"),
    ({"outputs": {"directory": "o", "uncertainty_naming": "{scene}_u.img"}},
     "chain.yaml: outputs: outputs.uncertainty_naming {scene}_u.img: extension .img does not fit format GTiff"),
])
def test_terrain_assess_uncertainty_and_interleave_settings_are_checked(sections, expected):
    assert error_of(minimal(**sections)).startswith(expected)


def test_terrain_assess_uncertainty_and_interleave_defaults():
    config = ChainConfig.from_dict(minimal(
        inputs=with_inputs(slope_aspect="{dir}/{scene}_slope_aspect.tif"),
        steps={"correct": {"terrain": {}}, "assess": {}},
        outputs={"directory": "o", "format": "ENVI", "interleave": "bil", "uncertainty": True}))
    terrain, assess = config.steps.correct.terrain, config.steps.assess
    # the defaults of brdfcorr.tasks.correct.Terrain and brdfcorr.analysis.view_angles.ViewAngleOptions
    assert (terrain.topographic, terrain.brdf_frame) == ("cosine", "surface")
    assert (assess.sign_by, assess.heading, assess.bin_width, assess.min_vza) == ("sun", None, 2.0, 0.0)
    assert config.outputs.uncertainty_naming == "{scene}_uncertainty.tif"
    assert ChainConfig.from_dict(minimal()).outputs.interleave is None  # ENVI's bsq unless asked


def test_format_pattern():
    image = Path("/data/line07/x_image.tif")
    assert format_pattern("{dir}/{scene}_angles.tif", image, "x") == "/data/line07/x_angles.tif"
    assert format_pattern("{parent}_{stem}.tif", image, "x") == "line07_x_image.tif"



def test_format_spec_in_pattern_accepted_and_formatted_as_str_format():
    """``{scene:>8}`` is a valid str.format pattern (the old regex refused it): the config takes it and
    the name is what ``str.format`` makes of it (source: the str.format spec, right-aligned in 8)."""
    document = minimal()
    document["inputs"]["classes"] = "{dir}/{scene:>8}_classes.tif"
    config = ChainConfig.from_dict(document)
    assert config.inputs.classes == "{dir}/{scene:>8}_classes.tif"
    image = Path("/data/line07/x_image.tif")
    assert format_pattern(config.inputs.classes, image, "x") == "/data/line07/       x_classes.tif"
    assert format_pattern("{scene:>8}", image, "x") == "{:>8}".format("x")
    assert format_pattern("{scene!r:_<5}{{lit}}", image, "ab") == "{!r:_<5}{{lit}}".format("ab")


@pytest.mark.parametrize(("pattern", "message"), [
    ("{scen:>8}_classes.tif", "pattern '{scen:>8}_classes.tif' uses {scen}; allowed placeholders: "
                              "{dir}, {parent}, {stem}, {scene}"),
    ("{scene.upper}.tif", "pattern '{scene.upper}.tif' uses {scene.upper}; allowed placeholders"),
    ("{scene:>{width}}.tif", "uses {width}; allowed placeholders"),
    ("{scene:d}.tif", "pattern '{scene:d}.tif': Unknown format code 'd'"),
    ("{scene.tif", "pattern '{scene.tif': "),
])
def test_unknown_field_or_bad_spec_refused_in_one_line(pattern, message):
    document = minimal()
    document["inputs"]["classes"] = pattern
    error = error_of(document)
    assert message in error
    assert "\n" not in error

def test_overrides(tmp_path):
    data = minimal()
    changed = apply_overrides(data, {"engine.workers": 3, "outputs.existing": "overwrite"})
    assert changed["engine"] == {"workers": 3} and changed["outputs"]["existing"] == "overwrite"
    assert "engine" not in data  # the input is not modified
    with pytest.raises(ConfigError, match="inputs.images is not a section"):
        apply_overrides(data, {"inputs.images.x": 1})
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(data))
    assert load_config(path, {"engine.workers": 5}).engine.workers == 5


def test_yaml_errors_name_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("inputs: [\n  outputs: {")
    with pytest.raises(ConfigError, match=r"bad.yaml: not valid YAML \(line \d+, column \d+\)"):
        load_config(path)
    with pytest.raises(ConfigError, match="cannot read chain config"):
        load_config(tmp_path / "missing.yaml")


def test_every_example_config_validates(tmp_path):
    """The example chains are templates: their keys and values are valid, and each one's line says
    it is not ready to run, naming the input that is missing, instead of "valid; 0 scenes found".
    Validated as copies in an empty folder: after ``make demo`` the repository's ``demo_output/``
    holds the scenes that ``configs/cluster.yaml`` names (``../demo_output``)."""
    assert len(CHAINS) >= 3, "configs/ should hold several example chains"
    assert REPO / "configs" / "demo.yaml" in CHAINS
    copies = shutil.copytree(REPO / "configs", tmp_path / "configs")
    result = CliRunner().invoke(main, ["validate", *(str(copies / path.name) for path in EXAMPLES)])
    assert result.exit_code == 0, result.output
    lines = {line.split(": ", 1)[0]: line for line in result.stdout.splitlines()}
    assert len(lines) == len(EXAMPLES)
    for chain in CHAINS:
        images = yaml.safe_load(chain.read_text())["inputs"]["images"]
        line = lines[str(copies / chain.name)]
        assert ": not ready to run, an input is missing: inputs.images" in line and images[0] in line, line
        assert "its keys and values are valid" in line and ": valid;" not in line
    assert result.output.count(": valid parameter table;") == len(EXAMPLES) - len(CHAINS)


def test_validate_strict_refuses_the_templates_naming_what_is_missing():
    chain = REPO / "configs" / "goniometer_fit.yaml"
    result = CliRunner().invoke(main, ["validate", "--strict", str(chain)])
    assert result.exit_code == 2, result.output
    errors = [line for line in result.stderr.splitlines() if line.startswith("brdfcorr: error: ")]
    assert any("inputs.images matches no file (../data/lines/*.tif)" in line for line in errors), errors
    assert any("roof_tile.csv does not exist" in line for line in errors), errors
    assert "(and 2 more, above)" in result.stdout


def test_validate_names_each_missing_input_of_a_chain(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path)
    for strict in ([], ["--strict"]):
        result = CliRunner().invoke(main, ["validate", *strict, str(chain)])
        assert result.exit_code == 0 and "valid; 2 scenes found" in result.stdout, result.output
    classes = tmp_path / "scenes" / "line1" / "classes.tif"
    classes.unlink()
    (tmp_path / "params.yaml").unlink()
    result = CliRunner().invoke(main, ["validate", str(chain)])
    assert result.exit_code == 0, result.output
    assert "not ready to run, an input is missing: parameters.table: " in result.stdout
    assert "(and 1 more, above)" in result.stdout and "2 scenes found" in result.stdout
    assert f"warning: {chain}: scene line1_image: missing input: class map {classes}" in result.stderr
    strict = CliRunner().invoke(main, ["validate", "--strict", str(chain)])
    assert strict.exit_code == 2
    assert f"error: {chain}: parameters.table: {tmp_path / 'params.yaml'} does not exist" in strict.stderr
    assert f"error: {chain}: scene line1_image: missing input: class map {classes}" in strict.stderr


def test_validate_cli_rejects_bad_config(tmp_path):
    path = tmp_path / "chain.yaml"
    path.write_text(yaml.safe_dump(minimal(engine={"scheduler": "mpi"})))
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2
    assert "engine.scheduler: 'mpi' is not allowed" in result.output
    result = CliRunner().invoke(main, ["validate", str(path), "--set", "engine.scheduler=threads"])
    assert result.exit_code == 0, result.output


def test_engine_address_must_be_a_scheduler_address():
    document = minimal(engine={"scheduler": "distributed", "address": "localhost"})
    assert "engine: address 'localhost' is not a dask scheduler address like 'tcp://host:8786'" in error_of(document)
    config = ChainConfig.from_dict(minimal(engine={"scheduler": "distributed", "address": "tcp://10.0.0.5:8786"}))
    assert config.engine.address == "tcp://10.0.0.5:8786"
