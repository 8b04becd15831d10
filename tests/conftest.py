"""Shared test helpers: the real sensor files, a guard that lazy code computes nothing, and the
builders that several test files use, as fixtures (a test file imports nothing from another): the
example scene on disk (the one scene factory), chains of synthetic scenes, refused command lines,
overlapping flight lines, scaled integer images."""

from __future__ import annotations

import collections
import re
import shutil
import sys
from pathlib import Path

import _forked
import dask
import numpy as np
import pytest
import rasterio
import xarray as xr
import yaml
from click.testing import CliRunner
from hypothesis import settings

from brdfcorr.analysis.assess import Line
from brdfcorr.chain.demo import demo_scene, write_demo_scene
from brdfcorr.cli import main
from brdfcorr.params import ParameterTable
from brdfcorr.tasks.classmaps import NdviBins, ndvi_class_file
from brdfcorr.testing import (
    example_table,
    file_digests,
    georeference,
    render,
    synthetic_angles,
    synthetic_scene,
    write_scene,
)

# Property tests draw the same examples on every run (a CI run that passes here passes there); a
# random exploration is `pytest --hypothesis-profile=explore`. No deadline: the properties are about
# values, and a loaded machine (xdist workers beside other work) made a 13 ms example take 549 ms
# once and fail as "flaky".
settings.register_profile("default", derandomize=True, deadline=None)
settings.register_profile("explore", derandomize=False, deadline=None)
settings.load_profile("default")


@pytest.fixture(scope="session", autouse=True)
def _fork_server():
    """The fork server of forked commands (tests/_forked.py), started before any test: the
    library's worker pools fork from it too, and would otherwise start it with their modules only."""
    _forked._server()


def _raising_scheduler(*args, **kwargs):
    raise AssertionError("a lazy function computed its dask input")


@pytest.fixture
def no_compute():
    """Within the test, any dask computation fails: lazy functions must stay lazy."""
    with dask.config.set(scheduler=_raising_scheduler):
        yield


# ------------------------------------------------------------------- the example scene on disk
def _write_example_scene(directory, scene, blocksize=16) -> dict[str, Path]:
    """``scene`` (brdfcorr.testing.synthetic_scene) written to ``directory`` (write_scene) with the
    example table as params.yaml: the paths by role, and ``dir``."""
    paths = write_scene(directory, scene, blocksize=blocksize)
    paths["params"] = example_table().save(Path(directory) / "params.yaml")
    return {**paths, "dir": Path(directory)}


@pytest.fixture(scope="session")
def write_example_scene():
    """``write_example_scene(directory, scene, blocksize=16)``: a synthetic scene's image, angles and
    classes GeoTIFFs and the example table (params.yaml) in ``directory``; the paths by role
    (image, angles, classes, params) and ``dir``. The one factory of the correctable scenes on disk."""
    return _write_example_scene


@pytest.fixture(scope="session")
def template(tmp_path_factory) -> Path:
    """The example scene of 32 x 32 pixels (write_example_scene) written once; a module that needs
    another size has its own ``template``. Never modified: tests take a copy (``scene``)."""
    directory = tmp_path_factory.mktemp("template") / "scene"
    return _write_example_scene(directory, synthetic_scene(ny=32, nx=32))["dir"]


@pytest.fixture
def scene(template, tmp_path) -> dict[str, Path]:
    """A fresh copy of the ``template`` scene directory (this one or the module's), and an empty
    output directory: a test may damage its copy. Modules with their own ``scene`` fixture use
    theirs."""
    directory = tmp_path / "scene"
    shutil.copytree(template, directory)
    (tmp_path / "out").mkdir()
    return {"dir": directory, "image": directory / "image.tif", "angles": directory / "angles.tif",
            "classes": directory / "classes.tif", "params": directory / "params.yaml",
            "out": tmp_path / "out", "output": tmp_path / "out" / "corrected.tif"}


# ------------------------------------------------------------------- chains of synthetic scenes
# make_scenes, write_chain, expected, read: chain runs of tests/workflow/test_pipeline.py and
# tests/workflow/test_chain_steps.py, and the tests that run a chain of their own (band names,
# distributed, ENVI output, output guard).

REFERENCE = {"sza": 35.0, "vza": 0.0, "raa": 0.0}


def _make_scenes(root, count=3, ny=32, nx=48):
    """Scenes rendered from the example table (testing.synthetic_scene), one directory each."""
    scenes = {}
    for index in range(count):
        scene = synthetic_scene(ny, nx, seed=index)
        scenes[f"line{index}"] = (scene, write_scene(root / "scenes" / f"line{index}", scene))
    return scenes


def _write_chain(root, table=None, **changes):
    document = {
        "inputs": {"images": ["scenes/*/image.tif"], "angles": {"kind": "geotiff", "path": "{dir}/angles.tif"},
                   "classes": "{dir}/classes.tif"},
        "parameters": {"table": "params.yaml"},
        "reference": REFERENCE,
        "steps": {"correct": {"limits": None}},
        "outputs": {"directory": "out", "naming": "{parent}_brdf.tif", "qa_naming": "{parent}_qa.tif",
                    "uncertainty_naming": "{parent}_sigma.tif", "quicklook_naming": "{parent}.png"},
        "engine": {"scheduler": "threads", "workers": 2, "chunk": 16},
    }
    for key, value in changes.items():
        section, _, name = key.partition("__")
        if name:
            document.setdefault(section, {})[name] = value
        else:
            document[section] = value
    (table or example_table()).save(root / "params.yaml")
    path = root / "chain.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


def _expected(scene):
    """Closed form (brdfcorr.testing): the scene rendered at the reference geometry."""
    shape = scene["classes"].shape
    return render(
        example_table(), scene["classes"].values, np.full(shape, REFERENCE["sza"]), np.zeros(shape),
        np.zeros(shape), np.zeros(shape), wavelengths=scene["reflectance"]["wavelength"].values.tolist(),
        brightness=scene["brightness"].values,
    )


def _read(path):
    with rasterio.open(path) as dataset:
        return dataset.read(), dataset.tags()


@pytest.fixture(scope="session")
def make_scenes():
    """``make_scenes(root, count=3, ny=32, nx=48)``: synthetic scenes written under ``root/scenes``,
    {name: (scene, paths)}."""
    return _make_scenes


@pytest.fixture(scope="session")
def write_chain():
    """``write_chain(root, table=None, **changes)``: the chain file of the scenes of ``make_scenes``
    (and ``table``, by default the example table, as params.yaml) under ``root``; a change replaces
    a section, ``section__name`` one entry of it."""
    return _write_chain


@pytest.fixture(scope="session")
def chain_reference():
    """The reference geometry of ``write_chain``'s chains [deg]."""
    return dict(REFERENCE)


@pytest.fixture(scope="session")
def expected():
    """``expected(scene)``: the closed-form output of a scene of ``make_scenes`` at the reference of
    ``write_chain``."""
    return _expected


@pytest.fixture(scope="session")
def read():
    """``read(path)``: a raster's values and tags."""
    return _read


# ------------------------------------------------------------------- refused command lines
# invoke, refused, correct_args: the hostile-input tests (tests/cli/test_chunk_sizes_refused.py,
# tests/cli/test_64_bit_integer_outputs.py, tests/cli/test_angle_and_terrain_rasters_checked.py,
# tests/io/test_product_metadata_checked.py, tests/io/test_hostile_products.py, tests/io/test_hostile_files.py,
# tests/cli/test_bad_input.py).

def _invoke(args, env=None) -> tuple[int, str]:
    """``brdfcorr ARGS`` in this process (click's runner): the exit code and stderr."""
    result = CliRunner().invoke(main, [str(arg) for arg in args], env=env)
    return result.exit_code, result.stderr


def _error_line(stderr: str) -> str:
    """stderr is exactly one line, ``brdfcorr: error: ...``, and no traceback: that line."""
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr[:3000]
    assert lines[0].startswith("brdfcorr: error: ") and "Traceback" not in stderr, lines[0]
    return lines[0]


def _refused(scene, args, pattern: str, run=None, env=None) -> str:
    """Run the command line ``args`` on a ``scene`` (by ``run(args) -> (exit code, stderr)``, by
    default in this process with the environment ``env``): exit 2, one ``brdfcorr: error:`` line
    matching ``pattern``, nothing in the output directory (nor a chain's ``chain_out`` beside the
    scene) and every file beside and in the scene directory byte-identical. Returns the line."""
    before = file_digests(scene["dir"].parent)
    code, stderr = run(args) if run is not None else _invoke(args, env)
    assert code == 2, stderr[:3000]
    line = _error_line(stderr)
    assert re.search(pattern, line), line
    assert list(scene["out"].iterdir()) == [], "nothing, not even a temporary file, in the output directory"
    assert not (scene["dir"].parent / "chain_out").exists()
    assert file_digests(scene["dir"].parent) == before, "inputs must be byte-identical"
    return line


def _correct_args(scene, *extra, image=None, angles: tuple = ()) -> list:
    angles = angles or ("--angles", scene["angles"])
    return ["correct", image or scene["image"], *angles, "--classes", scene["classes"], "--params",
            scene["params"], "-o", scene["output"], "--qa", scene["out"] / "qa.tif", "--no-progress", *extra]


@pytest.fixture(scope="session")
def invoke():
    """``invoke(args, env=None) -> (exit code, stderr)``: ``brdfcorr ARGS`` in this process."""
    return _invoke


@pytest.fixture(scope="session")
def refused():
    """``refused(scene, args, pattern, run=None, env=None)``: the command line on a ``scene``
    fixture is refused (exit 2, one error line matching ``pattern``) and writes and changes nothing;
    the line."""
    return _refused


@pytest.fixture(scope="session")
def correct_args():
    """``correct_args(scene, *extra, image=None, angles=())``: ``brdfcorr correct`` on a ``scene``
    fixture (``--angles`` file, or the options ``angles``), with a QA output, no progress bar."""
    return _correct_args


# ------------------------------------------------------------------- an NDVI strata scene
# write_strata_scene: the imagery fit of fit-classes and of a chain's fit step
# (tests/cli/test_fit_classes_names.py, tests/workflow/test_imagery_fit_step.py).

#: Soil (flat spectrum, NDVI about 0.06) and grass (NDVI 0.6) [sr^-1]: strata with edge 0.3 split them.
STRATA_TRUTH = ParameterTable(classes=[
    {"id": 1, "name": "soil", "model": "ross_thick_li_sparse", "wavelengths": [480, 560, 660, 830],
     "params": {"f_iso": [0.06, 0.07, 0.08, 0.09], "f_vol": 0.01, "f_geo": 0.012}},
    {"id": 2, "name": "grass", "model": "ross_thick_li_sparse", "wavelengths": [480, 560, 660, 830],
     "params": {"f_iso": [0.02, 0.04, 0.03, 0.12], "f_vol": [0.01, 0.02, 0.01, 0.06], "f_geo": 0.004}},
])


def _write_strata_scene(directory) -> dict[str, Path]:
    paths = write_scene(directory, synthetic_scene(ny=48, nx=64, wavelengths=(480.0, 560.0, 660.0, 830.0),
                                                   table=STRATA_TRUTH))
    paths["strata"] = paths["image"].parent / "strata.tif"
    ndvi_class_file(paths["image"], paths["strata"], bins=NdviBins(edges=(0.3,)))
    return paths


@pytest.fixture(scope="session")
def write_strata_scene():
    """``write_strata_scene(directory)``: a 48 x 64 scene rendered from STRATA_TRUTH (write_scene)
    with its NDVI strata map (``classes ndvi``, edge 0.3) as ``strata.tif`` beside it; the paths by
    role and ``strata``."""
    return _write_strata_scene


# ------------------------------------------------------------------- overlapping flight lines
# make_lines, make_cube, shifted: the assessment tests (tests/analysis/test_assess.py, tests/cli/test_cli_assess_lines.py).

def _cube(*bands):
    return georeference(xr.DataArray(np.stack(bands).astype(np.float64), dims=("band", "y", "x"),
                                     coords={"band": np.arange(1, len(bands) + 1)}))


def _shifted(array: xr.DataArray, columns: int) -> xr.DataArray:
    """The array's grid moved east by ``columns`` pixels (10 m)."""
    moved = array.assign_coords(x=array["x"] + 10.0 * columns)
    return moved.rio.write_transform(moved.rio.transform(recalc=True))


KERNEL_TABLE = ParameterTable(classes=[
    {"id": 1, "name": "grass", "model": "ross_thick_li_sparse",
     "params": {"f_iso": [0.03, 0.12], "f_vol": [0.02, 0.09], "f_geo": [0.006, 0.02]}, "wavelengths": [560, 860]},
    {"id": 2, "name": "soil", "model": "ross_thick_li_sparse",
     "params": {"f_iso": [0.05, 0.07], "f_vol": [0.005, 0.007], "f_geo": [0.015, 0.02]}, "wavelengths": [560, 860]},
])



def _lines(n_lines=3, ny=48, nx=64, shift=24, szas=None):
    """Lines flown north side by side over one ground (classes, albedo texture), each with its own
    view geometry across its swath and its sun zenith ``szas[index]`` [deg] (default 35 for every
    line), rendered with KERNEL_TABLE (brdfcorr.testing.render)."""
    rng = np.random.default_rng(3)
    width = nx + shift * (n_lines - 1)
    ground_classes = np.kron(rng.choice([1, 2], size=(ny // 4, -(-width // 4))), np.ones((4, 4), int))[:ny, :width]
    ground_brightness = rng.uniform(0.8, 1.2, (ny, width))  # albedo texture
    lines = []
    for index, sza in enumerate((35.0,) * n_lines if szas is None else szas):
        angles = synthetic_angles(ny, nx, sza=(sza, sza), vza_max=30.0, saa=120.0, dtype=np.float64)
        window = slice(index * shift, index * shift + nx)
        classes, brightness = ground_classes[:, window], ground_brightness[:, window]
        cube = render(KERNEL_TABLE, classes, **angles, wavelengths=[560.0, 860.0], brightness=brightness)
        reflectance = _shifted(_cube(*(np.pi * cube)).assign_coords(wavelength=("band", [560.0, 860.0])),
                               index * shift)
        layers = {name: _shifted(georeference(xr.DataArray(value, dims=("y", "x"))), index * shift)
                  for name, value in angles.items()}
        class_map = _shifted(georeference(xr.DataArray(classes, dims=("y", "x"))), index * shift)
        lines.append(Line(f"line{index + 1}", reflectance, class_map, layers))
    return lines


@pytest.fixture(scope="session")
def make_cube():
    """``make_cube(*bands)``: the 2-d arrays as one georeferenced float64 (band, y, x) cube."""
    return _cube


@pytest.fixture(scope="session")
def shifted():
    """``shifted(array, columns)``: the array's grid moved east by ``columns`` pixels (10 m)."""
    return _shifted


@pytest.fixture(scope="session")
def make_lines():
    """``make_lines(n_lines=3, ny=48, nx=64, shift=24, szas=None)``: overlapping lines rendered
    with a known kernel model (KERNEL_TABLE), as brdfcorr.analysis.assess.Line; ``szas``: each
    line's sun zenith [deg] (default 35)."""
    return _lines


# ------------------------------------------------------------------- scaled integer images
# store, nodata_pixels: tests/io/test_scaled_inputs.py and tests/io/test_output_type.py.

NODATA_PIXELS = (slice(None), 0, slice(0, 5))  # written as nodata in every stored image


def _store(source, target, dtype, scale, offset, nodata, *, tag=True, scales=None, offsets=None):
    """Write the float image ``source`` as counts (all pixels of NODATA_PIXELS nodata); GDAL scale
    and offset tagged (``tag``), per band where ``scales``/``offsets`` are given."""
    with rasterio.open(source) as dataset:
        profile, values, descriptions = dataset.profile, dataset.read(), dataset.descriptions
    n_bands = values.shape[0]
    scales = np.full(n_bands, scale) if scales is None else np.asarray(scales, float)
    offsets = np.full(n_bands, offset) if offsets is None else np.asarray(offsets, float)
    counts = np.round((values - offsets[:, None, None]) / scales[:, None, None])
    if np.dtype(dtype).kind in "iu":
        info = np.iinfo(dtype)
        assert counts.min() > info.min and counts.max() < info.max  # the scene fits the storage
    counts[NODATA_PIXELS] = nodata
    profile.update(dtype=dtype, nodata=nodata)
    with rasterio.open(target, "w", **profile) as dataset:
        dataset.write(counts.astype(dtype))
        dataset.descriptions = descriptions  # the wavelengths
        if tag:
            dataset.scales, dataset.offsets = tuple(scales), tuple(offsets)
    return target


@pytest.fixture(scope="session")
def store():
    """``store(source, target, dtype, scale, offset, nodata, *, tag=True, scales=None, offsets=None)``:
    the float image ``source`` written as scaled integer counts to ``target``."""
    return _store


@pytest.fixture(scope="session")
def nodata_pixels():
    """The pixels (an index of the (band, y, x) values) that ``store`` writes as nodata."""
    return NODATA_PIXELS


def _tables_close(got, expected, rtol: float = 1e-9) -> None:
    """Two parameter tables with the same classes, models, names and fit sources, and parameters
    and covariances equal to ``rtol`` (the same posterior reached from a fit's arrays or from its
    table, whose covariance is symmetrized and whose numbers are rounded to float)."""
    assert [(c.id, c.name, c.model, c.wavelengths) for c in got.classes] == \
        [(c.id, c.name, c.model, c.wavelengths) for c in expected.classes]
    for mine, theirs in zip(got.classes, expected.classes):
        assert mine.params.keys() == theirs.params.keys()
        for name in mine.params:
            np.testing.assert_allclose(mine.params[name], theirs.params[name], rtol=rtol, atol=1e-15)
        assert (mine.fit is None) == (theirs.fit is None)
        if mine.fit is not None:
            assert mine.fit.source == theirs.fit.source
            np.testing.assert_allclose(mine.fit.matrices(), theirs.fit.matrices(), rtol=rtol, atol=1e-20)


@pytest.fixture(scope="session")
def tables_close():
    return _tables_close


_ROOT = Path(__file__).parents[1]


# ------------------------------------------------- a land-cover map on another grid (tests/chain)
@pytest.fixture(scope="session")
def landcover(tmp_path_factory) -> Path:
    """A directory with the demo line (60 rows) and the examples' WorldCover stand-in of it
    (EPSG:4326, about 5 m) as ``landcover.tif``."""
    root = tmp_path_factory.mktemp("share")
    paths = write_demo_scene(root / "scenes", demo_scene(rows=60, pixel=12.0))
    sys.path.insert(0, str(_ROOT / "examples"))
    try:
        import make_landcover
    finally:
        sys.path.remove(str(_ROOT / "examples"))
    make_landcover.main([str(paths["classes"]), str(root / "landcover.tif")])
    shutil.copy(_ROOT / "examples" / "worldcover_lookup.yaml", root / "lookup.yaml")
    return root


@pytest.fixture
def identified(monkeypatch) -> collections.Counter:
    """How often each SAFE folder is identified (its MTD_MSIL2A.xml read into a ProductFolder:
    :func:`brdfcorr.io.sensors.folders.find_sentinel2_l2a`, which every way of finding a SAFE takes)."""
    import brdfcorr.io.sensors.folders as folders

    counts: collections.Counter = collections.Counter()
    original = folders.find_sentinel2_l2a

    def counting(path, **options):
        counts[Path(path).name] += 1
        return original(path, **options)

    monkeypatch.setattr(folders, "find_sentinel2_l2a", counting)
    return counts
