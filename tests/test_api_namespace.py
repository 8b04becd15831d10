"""The top-level names of ``import brdfcorr``: loaded at first use, the same objects as in their modules."""

import subprocess
import sys

import pytest

import brdfcorr


def test_top_level_names_are_the_library_objects():
    from brdfcorr.chain.run import run_chain
    from brdfcorr.params import ParameterTable

    assert brdfcorr.ParameterTable is ParameterTable
    assert brdfcorr.run_chain is run_chain
    from brdfcorr.tasks import fit, goniometer  # the goniometer task's names where they were before

    assert fit.fit_measurement_file is goniometer.fit_measurement_file and fit.MeasurementFit is goniometer.MeasurementFit
    assert {"ParameterTable", "run_chain", "normalize"} <= set(brdfcorr.__all__)


def _last_line(code: str) -> str:
    """The last line printed by ``code`` in a fresh interpreter (this session imported everything)."""
    result = subprocess.run([sys.executable, "-W", "error", "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip().splitlines()[-1]


def test_import_brdfcorr_stays_light():
    assert _last_line("import sys, brdfcorr; print(sorted(m for m in ('brdfcorr.params', 'brdfcorr.tasks', 'brdfcorr.chain', "
                      "'dask', 'scipy', 'xarray', 'numpy') if m in sys.modules))") == "[]"


@pytest.mark.parametrize("imports", [
    "import brdfcorr; import xarray as xr",  # xarray after brdfcorr: registered when it is imported
    "import xarray as xr; import brdfcorr",  # before: registered at once
    "import brdfcorr; import rioxarray; import xarray as xr",  # by a library that imports xarray
])
def test_import_brdfcorr_registers_the_accessor_whenever_xarray_comes(imports):
    # xarray's loader is its own again after the import (its resources serve the HTML repr).
    code = (f"{imports}\nfrom brdfcorr.accessor import BrdfAccessor\n"
            "print(xr.DataArray.brdf is BrdfAccessor, 'exec_module' in vars(xr.__spec__.loader), "
            "'xarray' in xr.DataArray([1.0])._repr_html_())")
    assert _last_line(code) == "True False True"


def test_run_chain_takes_a_path_or_a_loaded_config(tmp_path, make_scenes, write_chain):
    from brdfcorr.chain.config import load_config

    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path)
    report = brdfcorr.run_chain(chain, overrides={"outputs.existing": "overwrite"})
    assert report.ok and report.n_ok == 1 and report.path.is_file()
    again = brdfcorr.run_chain(load_config(chain, {"outputs.existing": "skip"}))
    assert again.ok and again.n_skipped == 1
    with pytest.raises(TypeError, match="overrides"):
        brdfcorr.run_chain(load_config(chain), overrides={"engine.workers": 1})


def test_dir_lists_the_lazy_public_names_and_the_package_is_typed():
    from pathlib import Path

    assert {"normalize", "ParameterTable", "run_chain", "geometry", "models"} <= set(dir(brdfcorr))
    assert (Path(brdfcorr.__file__).parent / "py.typed").is_file()  # PEP 561: mypy reads the annotations


@pytest.mark.parametrize("package", ["brdfcorr.tasks", "brdfcorr.chain"])
def test_all_names_the_modules_of_the_package(package):
    import importlib
    import pkgutil

    modules = {info.name for info in pkgutil.iter_modules(importlib.import_module(package).__path__)}
    assert set(importlib.import_module(package).__all__) == modules


@pytest.mark.parametrize("package", ["brdfcorr.fit", "brdfcorr.io"])
def test_a_lazy_package_face_gives_its_modules_objects(package):
    # brdfcorr.fit and brdfcorr.io load their modules at first use (PEP 562): every name of the
    # face is the module's own object, the face keeps the public names of goniometer (which it
    # once re-exported with a star import), and dir() lists them before they are used.
    import importlib

    face = importlib.import_module(package)
    for name in face.__all__:
        module = importlib.import_module(f"{package}.{face._PUBLIC[name]}")
        assert getattr(face, name) is getattr(module, name), name
    if package == "brdfcorr.fit":
        from brdfcorr.fit import goniometer

        assert set(goniometer.__all__) <= set(face.__all__)
    assert set(face.__all__) <= set(dir(face))
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        face.nothing  # noqa: B018
