"""A correction that draws nothing imports neither scipy.stats nor matplotlib, nor dask.distributed (issue 42).

Every ``brdfcorr`` process paid ~1.7 s for scipy.stats (one chi^2 survival function in
``fit/results.py``, now ``scipy.special.chdtrc``), ~1.1 s for matplotlib (``plot/*`` imported
``matplotlib.figure`` at module level, and ``chain/scenes.py`` reaches ``plot/assess.py``) and
~0.6 s for scipy.integrate/optimize (``analysis/papers.py``, reached through ``analysis``) before
it corrected a pixel. The figures and those analyses import them when they run. Likewise pvlib
(with requests and h5py, 0.3 s; the sun positions of the ``solar`` angle source) and
scipy.interpolate (0.2 s; the spline of a Landsat ANG.txt), which the sensor readers reached at
import. And the commands that compute on this machine no longer import dask.distributed (0.3-0.5 s
a process), which dask imported to look for a Client. A property, not a timing: each check runs in
a fresh interpreter, since this test session has long imported them.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

from brdfcorr.testing import write_sentinel2_safe

#: Imported only by what needs them: the figures, the papers' analyses, the statistics tests, the
#: sun positions and the Landsat angle reader.
DEFERRED = ("matplotlib", "scipy.stats", "scipy.integrate", "pvlib", "scipy.interpolate")


def _deferred_after(code: str, cwd=None, libraries: tuple[str, ...] = DEFERRED) -> list[str]:
    """The ``libraries`` in sys.modules of a fresh interpreter after running ``code`` (printed as
    the last line of its output)."""
    report = f"import sys; print(sorted(m for m in {libraries!r} if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", f"{code}\n{report}"], capture_output=True, text=True,
                            timeout=300, cwd=cwd)
    assert result.returncode == 0, result.stderr
    return ast.literal_eval(result.stdout.strip().splitlines()[-1])


def _command(arguments: list[str]) -> str:
    """Code that runs ``brdfcorr ARGUMENTS`` as the console script does and asserts its success."""
    return f"from brdfcorr.cli import main\ntry:\n    main({arguments!r})\nexcept SystemExit as stop:\n    assert not stop.code"


def test_the_correction_path_and_the_chain_runner_import_no_figures_nor_statistics():
    assert _deferred_after("import brdfcorr.tasks.correct, brdfcorr.chain.run, brdfcorr.cli.correct") == []


def test_a_chain_that_draws_nothing_imports_no_figures_nor_statistics(tmp_path, make_scenes, write_chain):
    # The run as `brdfcorr run` makes it (its lazy imports included): one scene, the correct step only.
    make_scenes(tmp_path, count=1, ny=8, nx=8)
    args = ["run", str(write_chain(tmp_path)), "--no-progress"]
    assert _deferred_after(_command(args), cwd=tmp_path, libraries=(*DEFERRED, "distributed")) == []
    assert (tmp_path / "out" / "line0_brdf.tif").exists()


def test_the_commands_on_this_machine_do_not_import_dask_distributed(tmp_path, make_scenes):
    # fit-classes, correct, assess and nbar, one after the other in one fresh interpreter. dask looks
    # for a dask.distributed Client (importing it: 0.5 s of a fresh 2.6 s correction of the demo's
    # line) on each pass given a scheduler's name or none, and for the graphs of dask.array.unique
    # and of a dask array given to dask.delayed whole; a local pass names the local scheduler's
    # function instead (brdfcorr.io.writer.local_scheduler). No Client can exist without the module.
    (_, paths), = make_scenes(tmp_path, count=1, ny=16, nx=16).values()
    inputs = ["--angles", str(paths["angles"]), "--classes", str(paths["classes"])]
    fit = ["fit-classes", str(paths["image"]), *inputs, "--model", "lambertian", "--min-samples", "10",
           "--min-vza-spread", "0", "-o", str(tmp_path / "lambertian.yaml")]
    params = Path(__file__).parents[2] / "configs" / "params_example.yaml"
    correct = ["correct", str(paths["image"]), *inputs, "--params", str(params), "--ref-sza", "mean",
               "-o", str(tmp_path / "out.tif"), "--qa", str(tmp_path / "qa.tif")]
    assess = ["assess", str(paths["image"]), str(tmp_path / "out.tif"), *inputs, "-o", str(tmp_path / "assess.json")]
    safe = write_sentinel2_safe(tmp_path / "s2", Path(__file__).parents[1] / "data" / "s2_MTD_TL_sensor_harmonization"
                                / "MTD_TL.xml", size=16)
    nbar = ["nbar", str(safe), "-o", str(tmp_path / "nbar.tif")]
    # A chain's assessment finds the class ids itself (the command line's names them), chunk by
    # chunk; NDVI strata interpolated in NDVI take each class's mean NDVI.
    ids = ("import dask.array, numpy\nfrom brdfcorr.analysis.view_angles import _present_ids\n"
           "from brdfcorr.correction.continuous import _class_means\n"
           "classes = dask.array.from_array(numpy.array([[0, 3], [1, 255]]), chunks=1)\n"
           "assert _present_ids(classes, 255).tolist() == [1, 3]\n"
           "index = dask.array.from_array(numpy.array([[0.2, 0.4], [0.6, numpy.nan]]), chunks=1)\n"
           "assert _class_means(index, classes, numpy.array([1, 3])).tolist() == [0.6, 0.4]")
    code = "\n".join([*(_command(command) for command in (fit, correct, assess, nbar)), ids])
    assert _deferred_after(code, libraries=("distributed",)) == []
    assert all((tmp_path / name).exists() for name in ("lambertian.yaml", "assess.json", "nbar.tif"))


def test_a_figure_still_imports_matplotlib_when_it_is_drawn():
    # The other side of the property: the deferred import is there, and it is matplotlib's Figure.
    code = ("import numpy as np\nfrom brdfcorr.plot.quicklook import quicklook_figure\n"
            "cube = np.ones((3, 4, 5))\nfigure = quicklook_figure(cube, cube)\n"
            "assert type(figure).__module__ == 'matplotlib.figure', type(figure)")
    assert "matplotlib" in _deferred_after(code)


def test_the_library_listings_and_a_tables_validation_import_neither_xarray_nor_scipy():
    # `brdfcorr models`, `materials` and `coefficients` (the README's first commands) print
    # registries and published tables: they took 1.7 s for xarray, pandas, dask and scipy.special
    # (brdfcorr._arrays imported them for the kernels' xarray wrapping and degree sines).
    # `validate TABLE` reads YAML into pydantic models: 2.8 s before (params imported brdfcorr.strata
    # for the NDVI's band ranges, and xarray for the one function that makes a Dataset).
    table = Path(__file__).parents[2] / "configs" / "params_example.yaml"
    for command in (["models"], ["materials", "roof_tile"], ["coefficients", "roy2016"], ["validate", str(table)]):
        assert _deferred_after(_command(command), libraries=("xarray", "pandas", "dask", "scipy")) == [], command


def test_a_chains_validation_imports_neither_xarray_nor_scipy(tmp_path, make_scenes, write_chain):
    # `brdfcorr validate CHAIN.yaml` checks keys, values and the plan (which reads image headers with
    # rasterio): 3.5 s before, 2.6 s of it importing the correction, the fits and the writer, which
    # the config's settings reached through their packages' faces (fit/__init__, io.writer).
    make_scenes(tmp_path, count=1, ny=8, nx=8)
    examples = Path(__file__).parents[2] / "configs"
    for chain in (write_chain(tmp_path), examples / "demo.yaml", examples / "imagery_fit.yaml"):
        assert _deferred_after(_command(["validate", str(chain)]), cwd=tmp_path, libraries=("xarray", "pandas", "dask", "scipy")) == [], chain


def test_a_goniometer_fit_imports_no_raster_stack(tmp_path):
    # `brdfcorr fit CSV -o TABLE` (paper 003's procedure, the README's goniometer step) needs scipy's
    # optimizers, not xarray, dask or rasterio: 3.7 s before, when its task lived beside the imagery
    # fit (brdfcorr.tasks.fit), now brdfcorr.tasks.goniometer.
    csv = tmp_path / "tile.csv"
    csv.write_text("theta_i,theta_r,phi,brdf\n" + "".join(f"{ti},{tr},180,{0.02 + 0.001 * tr}\n"
                                                        for ti in (30, 50) for tr in range(0, 70, 5)))
    command = ["fit", str(csv), "--model", "lambertian", "-o", str(tmp_path / "table.yaml")]
    assert _deferred_after(_command(command), libraries=("xarray", "pandas", "dask", "rasterio", "matplotlib")) == []
    assert (tmp_path / "table.yaml").is_file()
