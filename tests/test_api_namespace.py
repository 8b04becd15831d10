"""The top-level names of ``import brdfcorr``: loaded at first use, the same objects as in their modules."""

import subprocess
import sys

import pytest

import brdfcorr


def test_top_level_names_are_the_library_objects():
    from brdfcorr.params import ParameterTable
    from brdfcorr.workflow.api import run_chain

    assert brdfcorr.ParameterTable is ParameterTable
    assert brdfcorr.run_chain is run_chain
    assert {"ParameterTable", "run_chain", "normalize"} <= set(brdfcorr.__all__)


def test_import_brdfcorr_stays_light():
    code = ("import sys, brdfcorr; print(sorted(m for m in ('brdfcorr.params', 'brdfcorr.workflow', 'dask', 'scipy') "
            "if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "[]"


def test_run_chain_takes_a_path_or_a_loaded_config(tmp_path, make_scenes, write_chain):
    from brdfcorr.workflow.config import load_config

    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    report = brdfcorr.run_chain(chain, overrides={"outputs.existing": "overwrite"})
    assert report.ok and report.n_ok == 1 and report.path.is_file()
    again = brdfcorr.run_chain(load_config(chain, {"outputs.existing": "skip"}))
    assert again.ok and again.n_skipped == 1
    with pytest.raises(TypeError, match="overrides"):
        brdfcorr.run_chain(load_config(chain), overrides={"engine.workers": 1})
