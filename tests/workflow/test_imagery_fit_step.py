"""A chain's imagery fit step is `brdfcorr fit-classes` (issues 26 and 29): the same options under
the same names, the same defaults (the model chosen from an NDVI strata map, the class names of its
tags, the water-vapour bad bands, the condition-number guard rail), documented in
configs/full_reference.yaml with every key at its default."""

from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml

from brdfcorr.chain.config import ChainConfig, ConfigError, load_config
from brdfcorr.chain.config_steps import ImageryFit
from brdfcorr.chain.plan import plan_run
from brdfcorr.chain.run import run_chain
from brdfcorr.cli.fitting import fit_classes_command
from brdfcorr.errors import InputError
from brdfcorr.fit.settings import WATER_VAPOUR_BANDS, GuardRails, Sampling
from brdfcorr.params import ParameterTable

REPO = Path(__file__).resolve().parents[2]

@pytest.fixture(scope="module")
def strata_scene(tmp_path_factory, write_strata_scene) -> Path:
    """One scene rendered from STRATA_TRUTH with its NDVI strata map (``classes ndvi``, edge 0.3) as
    ``strata.tif`` (tests/conftest.py); returns the folder."""
    root = tmp_path_factory.mktemp("strata_chain")
    write_strata_scene(root / "scenes" / "line0")
    return root


def _chain(root: Path, name: str, fit: dict) -> Path:
    document = {
        "inputs": {"images": ["scenes/*/image.tif"], "angles": {"kind": "geotiff", "path": "{dir}/angles.tif"},
                   "classes": "{dir}/strata.tif"},
        "steps": {"fit": {"source": "imagery", "min_samples": 50, **fit}, "correct": {"limits": None}},
        "outputs": {"directory": f"out_{name}", "naming": "{parent}_brdf.tif", "qa_naming": "{parent}_qa.tif"},
        "engine": {"scheduler": "synchronous", "chunk": 16},
    }
    path = root / f"{name}.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


def _cli_defaults() -> dict:
    """The values `fit-classes` gives its options when none is given, as click resolves them."""
    arguments = ["image.tif", "--angles", "angles.tif", "--classes", "classes.tif", "-o", "table.yaml"]
    with fit_classes_command.make_context("fit-classes", arguments) as context:
        return dict(context.params)


def test_the_step_defaults_are_those_of_fit_classes():
    settings = ImageryFit(source="imagery").fit_settings()
    cli = _cli_defaults()
    # fit-classes: no --model (chosen from the class maps), the guard rails and sampling of its options.
    assert settings["models"].model is None and cli["model_name"] is None
    assert settings["guard"] == GuardRails(min_samples=cli["min_samples"], min_vza_spread=cli["min_vza_spread"],
                                           max_condition=cli["max_condition"])
    assert settings["sampling"] == Sampling(max_samples=cli["max_samples"], seed=cli["seed"])
    assert settings["sampling"].bad_bands == WATER_VAPOUR_BANDS and cli["bad_bands"] == ()  # no --bad-bands: the default
    assert settings["guard"].max_condition == 1000.0


def test_given_settings_reach_the_fit_and_names_of_the_step_win():
    step = ImageryFit(source="imagery", model="lambertian", names={2: "grass"}, max_condition=50,
                      bad_bands=[[650, 670]], min_samples=20)
    settings = step.fit_settings({1: "roof_tile", 2: "tile"})
    assert settings["models"].model == "lambertian"
    models = settings["models"]  # the table's names are defaults: not checked against the classes found
    assert dict(models.names) == {2: "grass"} and dict(models.default_names) == {1: "roof_tile", 2: "tile"}
    assert [models.name_of(class_id) for class_id in (1, 2, 3)] == ["roof_tile", "grass", "class_3"]
    assert settings["guard"] == GuardRails(min_samples=20, max_condition=50.0)
    assert settings["sampling"].bad_bands == ((650.0, 670.0),)
    assert ImageryFit(source="imagery", bad_bands=[]).fit_settings()["sampling"].bad_bands == ()  # --bad-bands none


@pytest.mark.parametrize("key, value, expected", [
    ("bad_bands", [[1450, 1340]], "steps.fit.bad_bands: range [1450, 1340] nm must be finite with 0 < low <= high"),
    ("bad_bands", [[0, 10]], "steps.fit.bad_bands: range [0, 10] nm"),
    ("bad_bands", [[1340]], "steps.fit.bad_bands[0]"),
    ("max_condition", 0.5, "steps.fit.max_condition: Input should be greater than or equal to 1"),
    ("max_condition", ".inf", "steps.fit.max_condition: Input should be a finite number"),
    ("prior", "roy2015", "steps.fit.prior: "),
    ("prior_spread", 0, "steps.fit.prior_spread: Input should be greater than 0"),
])
def test_bad_values_are_one_line_naming_the_key(key, value, expected):
    document = {"inputs": {"images": ["a.tif"], "angles": {"path": "a_angles.tif"}, "classes": "c.tif"},
                "steps": {"fit": {"source": "imagery", key: yaml.safe_load(str(value)) if value == ".inf" else value}},
                "outputs": {"directory": "out"}}
    with pytest.raises(ConfigError) as caught:
        ChainConfig.from_dict(document, "chain.yaml")
    message = str(caught.value)
    assert "\n" not in message and expected in message, message


def test_full_reference_documents_every_key_of_the_imagery_fit_at_its_default():
    path = REPO / "configs" / "full_reference.yaml"
    step = load_config(path).steps.fit
    assert isinstance(step, ImageryFit)
    assert step == ImageryFit(source="imagery")  # every value written there is the default
    written = yaml.safe_load(path.read_text())["steps"]["fit"]
    assert set(written) == set(ImageryFit.model_fields)  # and every key is written


def test_a_chain_on_strata_maps_gets_the_kernel_model_and_the_tag_names(strata_scene):
    config = load_config(_chain(strata_scene, "defaults", {}))
    plan = plan_run(config)
    assert any("model ross_thick_li_sparse on NDVI strata class maps" in text for text in plan.table_sources)
    report = run_chain(config)
    assert report.ok, report.scenes
    table = ParameterTable.load(strata_scene / "out_defaults" / "fitted_params.yaml")
    # As fit-classes on the same map (tests/cli/test_fit_classes_names.py): the kernel model and
    # the names `classes ndvi` wrote in the map's class_names tag, not torrance_sparrow, class_1.
    assert {entry.model for entry in table.classes} == {"ross_thick_li_sparse"}
    assert [entry.name for entry in table.classes] == ["ndvi_-inf_0.30", "ndvi_0.30_inf"]
    notes = report.fit["notes"]
    assert any(note.startswith("model ross_thick_li_sparse for every class: the class map is NDVI strata")
               for note in notes)
    assert "class names from the class map's tags: 1=ndvi_-inf_0.30, 2=ndvi_0.30_inf" in notes


def test_a_chain_leaves_out_its_bad_bands_and_applies_its_condition_limit(strata_scene):
    report = run_chain(load_config(_chain(strata_scene, "bands", {"bad_bands": [[650, 670]],
                                                                    "names": {2: "grass"}})))
    assert report.ok, report.scenes
    table = ParameterTable.load(strata_scene / "out_bands" / "fitted_params.yaml")
    assert [entry.bad_bands for entry in table.classes] == [[[650.0, 670.0]]] * 2  # the 660 nm band only
    assert report.fit["bands_left_out"] == [660.0]
    assert table[2].name == "grass" and table[1].name == "ndvi_-inf_0.30"  # a given name wins over the tag
    # A condition number is >= 1 and the kernels' columns are not orthogonal: every class fails
    # the limit 1, as `fit-classes --max-condition 1` does, and a run with no class is refused,
    # naming each class and why, before it writes anything (the fitted table included).
    strict = load_config(_chain(strata_scene, "strict", {"max_condition": 1}))
    with pytest.raises(InputError, match=r"the fit step fitted no class \(1 \(ndvi_-inf_0\.30\): .*condition"):
        run_chain(strict)
    assert not (strata_scene / "out_strict" / "line0_brdf.tif").exists()
    assert not (strata_scene / "out_strict" / "fitted_params.yaml").exists()


def test_a_prior_of_the_step_is_that_of_fit_classes(strata_scene, tables_close):
    # steps.fit.prior/prior_spread as fit-classes --prior/--prior-spread: the fitted table under
    # the coefficient set's kernel shape (brdfcorr.fit.prior.with_shape_prior).
    from brdfcorr.fit.prior import ShapePrior, with_shape_prior

    assert run_chain(load_config(_chain(strata_scene, "plain", {}))).ok
    config = load_config(_chain(strata_scene, "prior", {"prior": "roy2016", "prior_spread": 0.1}))
    assert run_chain(config).ok
    plain = ParameterTable.load(strata_scene / "out_plain" / "fitted_params.yaml")
    tables_close(ParameterTable.load(strata_scene / "out_prior" / "fitted_params.yaml"),
                 with_shape_prior(plain, ShapePrior("roy2016", 0.1)))
    with pytest.raises(ValueError, match="prior_spread needs prior"):
        ImageryFit(source="imagery", prior_spread=0.1)


# ------------------------------------------------------------------ the view azimuth convention
def _minimal(inputs: dict | None = None, steps: dict | None = None) -> dict:
    document = {"inputs": {"images": ["a.tif"], "angles": {"path": "a_angles.tif"}, "classes": "c.tif",
                           **(inputs or {})},
                "parameters": {"materials": {1: "roof_tile"}}, "outputs": {"directory": "out"}}
    if steps is not None:
        document["steps"] = steps
    return document


def test_a_fit_only_chain_reads_view_azimuths_from_the_sensor_as_its_inputs_say(tmp_path, write_strata_scene,
                                                                                 tables_close):
    # The same scene written twice, the second with each view azimuth as seen from the sensor
    # (vaa + 180), each fitted by a chain with a fit step and no correct step. With
    # inputs.flip_view_azimuth the second table is the first one's (as fit-classes
    # --flip-view-azimuth gives it, tests/fit/test_classfit.py); without it, it is not.
    tables = {}
    for name, turn, inputs in (("plain", 0.0, {}), ("from_sensor", 180.0, {"flip_view_azimuth": True}),
                               ("unflipped", 180.0, {})):
        root = tmp_path / name
        paths = write_strata_scene(root / "scenes" / "line0")
        with rasterio.open(paths["angles"], "r+") as dataset:
            dataset.write((dataset.read(4).astype(np.float64) + turn) % 360.0, 4)
        path = _chain(root, name, {})
        document = yaml.safe_load(path.read_text())
        document["inputs"].update(inputs)
        document["steps"]["correct"] = None  # fit only
        path.write_text(yaml.safe_dump(document))
        config = load_config(path)
        assert config.flips_view_azimuth is bool(inputs)
        report = run_chain(config)
        assert report.ok, report.scenes
        tables[name] = ParameterTable.load(root / f"out_{name}" / "fitted_params.yaml")
    tables_close(tables["from_sensor"], tables["plain"], rtol=1e-5)
    with pytest.raises(AssertionError):  # the flip matters here: unflipped, the fit is another
        tables_close(tables["unflipped"], tables["plain"], rtol=1e-2)


def test_the_view_azimuth_convention_is_one_setting():
    fit = {"fit": {"source": "imagery"}}
    # At inputs it is the correct step's too (the config written back says so and reads back).
    config = ChainConfig.from_dict(_minimal({"flip_view_azimuth": True}, {**fit}), "chain.yaml")
    assert config.flips_view_azimuth and config.steps.correct.flip_view_azimuth
    assert ChainConfig.from_dict(config.to_dict(), "chain.yaml") == config
    assert ChainConfig.from_dict(_minimal({"flip_view_azimuth": True}, {**fit, "correct": {
        "flip_view_azimuth": True}}), "chain.yaml").flips_view_azimuth  # the same twice: accepted
    # The correct step's key alone still works (and a fit-only chain without either reads them as they are).
    assert ChainConfig.from_dict(_minimal(steps={"correct": {"flip_view_azimuth": True}}),
                                 "chain.yaml").flips_view_azimuth
    assert not ChainConfig.from_dict(_minimal(steps={**fit, "correct": None}), "chain.yaml").flips_view_azimuth
    # Two different values: one line naming both keys.
    for given, step in ((True, False), (False, True)):
        with pytest.raises(ConfigError) as caught:
            ChainConfig.from_dict(_minimal({"flip_view_azimuth": given}, {"correct": {"flip_view_azimuth": step}}),
                                  "chain.yaml")
        message = str(caught.value)
        assert "\n" not in message and message.startswith("chain.yaml: ")
        assert "inputs.flip_view_azimuth" in message and "steps.correct.flip_view_azimuth" in message
    with pytest.raises(ConfigError, match="inputs.flip_view_azimuth: Input should be a valid boolean"):
        ChainConfig.from_dict(_minimal({"flip_view_azimuth": "maybe"}), "chain.yaml")


def test_the_fit_fingerprint_holds_the_flip_wherever_it_is_set():
    from brdfcorr.chain.resume import fit_fingerprint

    def fingerprint(inputs=None, correct=None):
        steps = {"fit": {"source": "imagery"}, "correct": correct}
        return fit_fingerprint(ChainConfig.from_dict(_minimal(inputs, steps), "chain.yaml"), [])

    unset = fingerprint()
    flipped = fingerprint({"flip_view_azimuth": True})
    assert flipped != unset  # a resumed fit-only run refits when the flip is set
    assert flipped == fingerprint(correct={"flip_view_azimuth": True})  # the same fit, however it is set
    assert fingerprint({"flip_view_azimuth": False}) == unset == fingerprint(correct={})  # false: the default
