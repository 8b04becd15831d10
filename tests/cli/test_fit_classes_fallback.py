"""`fit-classes --fallback roy2016`: a class whose fit fails the guard rails gets the global RTLSR
coefficients of Roy et al. (2016) (issue 25: the coefficient library as the fallback of classes
that fail), and the table it writes corrects the scene."""

import math

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from brdfcorr.chain.config_steps import ImageryFit
from brdfcorr.cli import main
from brdfcorr.params import ParameterTable


@pytest.fixture(scope="module")
def files(tmp_path_factory, write_strata_scene):
    root = tmp_path_factory.mktemp("fallback")
    return {**write_strata_scene(root), "root": root}


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_classes_failing_the_guard_rails_get_the_global_coefficients(files):
    # A view-zenith spread of 90 deg cannot be met: every stratum fails and falls back.
    table_path = files["root"] / "fallback.yaml"
    result = _run("fit-classes", files["image"], "--angles", files["angles"], "--classes", files["strata"],
                  "--min-vza-spread", "90", "--fallback", "roy2016", "-o", table_path)
    assert result.exit_code == 0, result.output
    assert "using built-in coefficient set 'roy2016'" in result.output
    table = ParameterTable.load(table_path)
    assert [entry.id for entry in table.classes] == [1, 2]
    for entry in table.classes:
        assert entry.model == "ross_thick_li_sparse" and entry.fit is None
        red = entry.wavelengths.index(654.6)  # Roy et al. (2016) Table 1, red: 0.1690, 0.0574, 0.0227 (BRF)
        assert [entry.params[name][red] * math.pi for name in ("f_iso", "f_vol", "f_geo")] == pytest.approx(
            [0.1690, 0.0574, 0.0227], rel=1e-12)
    assert "fit" not in yaml.safe_load(table_path.read_text())["classes"][0]
    corrected = files["root"] / "corrected.tif"
    result = _run("correct", files["image"], "--angles", files["angles"], "--classes", files["strata"],
                  "--params", table_path, "-o", corrected, "--ref-sza", "35")
    assert result.exit_code == 0, result.output
    assert corrected.is_file()


def test_an_unknown_fallback_names_both_kinds_and_fails_before_the_fit(files):
    result = _run("fit-classes", files["image"], "--angles", files["angles"], "--classes", files["strata"],
                  "--fallback", "roy2015", "-o", files["root"] / "never.yaml")
    assert result.exit_code == 2
    line = result.output.strip()
    assert len(line.splitlines()) == 1 and "roof_tile" in line and "roy2016" in line
    assert not (files["root"] / "never.yaml").exists()


def test_a_chain_fit_step_takes_a_coefficient_set_as_fallback():
    assert ImageryFit(source="imagery", fallback="roy2017").fallback == "roy2017"
    with pytest.raises(ValueError, match="neither a built-in material"):
        ImageryFit(source="imagery", fallback="roy2015")
    np.testing.assert_equal(ImageryFit(source="imagery").fallback, None)
