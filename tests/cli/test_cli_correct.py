"""Tests of ``brdfcorr correct``: exit codes, outputs reopened, same numbers as the library."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr import __version__, normalize
from brdfcorr.cli import main
from brdfcorr.correction import QA
from brdfcorr.errors import InputError
from brdfcorr.params import ParameterTable
from brdfcorr.testing import example_table, synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")


@pytest.fixture(scope="module")
def scene():
    scene = synthetic_scene(ny=40, nx=48)
    scene["classes"][0, :8] = 0  # no class
    scene["classes"][1, :8] = 7  # not in the table
    return scene


@pytest.fixture(scope="module")
def files(scene, tmp_path_factory, write_example_scene):
    return write_example_scene(tmp_path_factory.mktemp("cli"), scene)


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def _base(files, output):
    return ["correct", files["image"], "--angles", files["angles"], "--classes", files["classes"],
            "--params", files["params"], "-o", output, "--chunk", 16]


def test_cli_matches_library_numbers_and_writes_provenance(files, scene, tmp_path):
    output, qa_path = tmp_path / "out.tif", tmp_path / "qa.tif"
    result = _invoke(*_base(files, output), "--ref-sza", 35, "--ref-vza", 5, "--ref-raa", 60, "--qa", qa_path)
    assert result.exit_code == 0, result.output
    expected, expected_qa = normalize(
        scene["reflectance"], scene["classes"].rio.write_nodata(255), {a: scene[a] for a in ANGLES},
        example_table(), reference={"sza": 35.0, "vza": 5.0, "raa": 60.0})
    with rasterio.open(output) as written:
        np.testing.assert_array_equal(written.read(), expected.values)  # numpy path == CLI path
        tags = written.tags()
        assert tags["brdf_reference"] == "sza=35 vza=5 raa=60"
        assert tags["brdf_limits"] == "0.2,5"
        assert tags["brdf_parameter_table"] == str(files["params"])
        assert ParameterTable.from_dict(json.loads(tags["brdf_parameter_table_content"])) == example_table()
        assert tags["brdfcorr_version"] == __version__
        assert tags["wavelength"] == "480,560,660,830"
        assert written.descriptions == ("480 nm", "560 nm", "660 nm", "830 nm")
        assert written.crs == scene["reflectance"].rio.crs
        assert written.transform == scene["reflectance"].rio.transform()
        assert np.isnan(written.nodata)
    with rasterio.open(qa_path) as written:
        qa = written.read(1)
        assert written.crs == scene["reflectance"].rio.crs and written.dtypes[0] == "uint8"
    np.testing.assert_array_equal(qa, expected_qa.values)
    # One summary line, with the counts of the QA layer.
    line = result.output.strip().splitlines()[-1]
    assert f"{40 * 48 - 16} pixels corrected" in line and "8 unknown class" in line and "8 no class" in line
    assert (qa[1, :8] == QA.UNKNOWN_CLASS).all() and (qa[0, :8] == QA.NO_CLASS).all()


def test_separate_angle_files_give_the_same_output(files, scene, tmp_path):
    separate = {}
    for name in ANGLES:
        separate[name] = tmp_path / f"{name}.tif"
        scene[name].rio.to_raster(separate[name])
    one, four = tmp_path / "one.tif", tmp_path / "four.tif"
    assert _invoke(*_base(files, one), "--ref-sza", "mean").exit_code == 0
    args = ["correct", files["image"], "--classes", files["classes"], "--params", files["params"],
            "-o", four, "--chunk", 16, "--ref-sza", "mean"]
    for name in ANGLES:
        args += [f"--{name}", separate[name]]
    result = _invoke(*args)
    assert result.exit_code == 0, result.output
    with rasterio.open(one) as a, rasterio.open(four) as b:
        np.testing.assert_array_equal(a.read(), b.read())
        # The scene mean of the ramp 30..40 deg is recorded as a number.
        assert a.tags()["brdf_reference"].startswith("sza=35 ")
        assert a.tags()["brdf_reference_sza_source"] == "mean"


def test_grid_mismatch_exits_2_naming_the_file(files, scene, tmp_path):
    other = tmp_path / "classes_shifted.tif"
    other.write_bytes(files["classes"].read_bytes())
    with rasterio.open(other, "r+") as dataset:  # one pixel to the east
        dataset.transform = dataset.transform * rasterio.Affine.translation(1, 0)
    output = tmp_path / "out.tif"
    args = _base(files, output)
    args[args.index(files["classes"])] = other
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 2
    assert result.output.count("\n") == 1
    assert "classes_shifted.tif" in result.output and "transform" in result.output
    assert not output.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["classes_shifted.tif"]


@pytest.mark.parametrize("extra, message", [
    (["--ref-sza", "95"], "reference sza = 95 deg must be in [0, 90)"),
    (["--ref-vza", "91"], "reference.vza"),
    (["--limits", "2", "5"], "factor limits"),
    (["--wavelengths", "300,560,660,830"], "class 2 (grass): parameter a: band centre 300 nm is outside"),
])
def test_bad_options_exit_2_without_output(files, tmp_path, extra, message):
    output = tmp_path / "out.tif"
    result = CliRunner().invoke(main, [str(a) for a in _base(files, output) + extra])
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert not output.exists() and list(tmp_path.iterdir()) == []


def test_output_must_not_overwrite_an_input_or_go_to_a_missing_directory(files, tmp_path):
    before = files["image"].read_bytes()
    result = CliRunner().invoke(main, [str(a) for a in _base(files, files["image"])])
    assert result.exit_code == 2 and "is also an input" in result.output
    assert files["image"].read_bytes() == before
    result = CliRunner().invoke(main, [str(a) for a in _base(files, tmp_path / "nowhere" / "out.tif")])
    assert result.exit_code == 2 and "output directory" in result.output and "does not exist" in result.output


def test_no_limits_and_unknown_nan(files, tmp_path):
    output = tmp_path / "out.tif"
    result = _invoke(*_base(files, output), "--no-limits", "--unknown", "nan", "--ref-sza", 35)
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as written:
        data = written.read()
        assert written.tags()["brdf_limits"] == "none"
    assert np.isnan(data[:, :2, :8]).all() and np.isfinite(data[:, 2:]).all()


def test_cog_output(files, tmp_path):
    output = tmp_path / "out.tif"
    assert _invoke(*_base(files, output), "--cog").exit_code == 0
    with rasterio.open(output) as written:
        assert written.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"


def test_help_lists_the_contract_options():
    result = _invoke("correct", "--help")
    for option in ("--angles", "--classes", "--params", "--output", "--ref-sza", "--ref-vza", "--ref-raa",
                   "--sza", "--saa", "--vza", "--vaa"):
        assert option in result.output


def test_correct_files_reads_sensor_angle_sources(files, scene, tmp_path, monkeypatch):
    # The plumbing to brdfcorr.io.sensors.read_angles: a stand-in source kind that returns the scene's
    # angles on the image grid must give the same output as the 4-band angle file.
    import xarray as xr

    import brdfcorr.io.sensors
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles

    def stand_in(source, like, scale=1.0):
        # by absolute path, as rasters are opened: workers started in another folder read it
        assert source == Path("obs.bin").absolute() and like.sizes["x"] == 48
        return xr.Dataset({name: scene[name] * scale for name in ANGLES})

    monkeypatch.setitem(brdfcorr.io.sensors.ANGLE_KINDS, "stand_in", stand_in)
    def correct(output, angles, **sources):
        request = CorrectionRequest(SceneSources(files["image"], files["classes"], angles, **sources), example_table(),
                                    OutputFiles(tmp_path / output), reference={"sza": 35.0}, engine=Engine(chunks=16))
        return correct_files(request)

    correct("a.tif", files["angles"])
    correct("b.tif", "obs.bin", angles_kind="stand_in", angle_options={"scale": 1.0})
    with rasterio.open(tmp_path / "a.tif") as a, rasterio.open(tmp_path / "b.tif") as b:
        np.testing.assert_array_equal(a.read(), b.read())
    monkeypatch.setitem(brdfcorr.io.sensors.ANGLE_KINDS, "sun_only",
                        lambda source, like: xr.Dataset({n: scene[n] for n in ("sza", "saa")}))
    with pytest.raises(InputError, match=r"angle source t0 \(sun_only\) gives no vza, vaa"):
        correct("c.tif", "t0", angles_kind="sun_only")


def test_dask_process_pool_is_refused_up_front_and_the_local_schedulers_correct(files, tmp_path):
    """Engine(scheduler="processes") failed deep in the write with "cannot pickle '_thread.lock'"
    (the writers' GDAL handles and locks stay in this process); it is refused before anything is
    read, naming the schedulers that work, and those do."""
    import concurrent.futures

    import dask
    import dask.multiprocessing

    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles

    for scheduler in ("processes", "multiprocessing", dask.multiprocessing.get):
        with pytest.raises(InputError, match=r"dask's process pool cannot .*use 'threads' or 'synchronous', or a "
                                             r"dask.distributed Client"):
            Engine(scheduler=scheduler)
    with pytest.raises(InputError, match="dask's process pool"):  # a process executor, as dask takes one
        Engine(scheduler=concurrent.futures.ProcessPoolExecutor(1))
    with dask.config.set(scheduler="processes"), pytest.raises(InputError, match="dask's process pool"):
        Engine()  # dask's own setting (DASK_SCHEDULER=processes), which the passes would use
    for scheduler in ("synchronous", "threads"):
        request = CorrectionRequest(SceneSources(files["image"], files["classes"], files["angles"]), example_table(),
                                    OutputFiles(tmp_path / f"{scheduler}.tif"), reference={"sza": 35.0},
                                    engine=Engine(chunks=16, scheduler=scheduler))
        correct_files(request)
        assert (tmp_path / f"{scheduler}.tif").is_file()


def test_third_party_warnings_shown_with_debug_are_not_recorded_again(capsys):
    # correct shows --debug's third-party warnings while it still records them: passed to
    # warnings.showwarning there, each was appended to the list being shown, an endless loop
    # (a NetCDF image with --debug: killed for memory).
    import warnings

    from brdfcorr.cli.correct import _show_warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.warn("a third party's warning", UserWarning)
        _show_warnings(caught)
    assert len(caught) == 1
    assert "UserWarning: a third party's warning" in capsys.readouterr().err


def test_given_wavelengths_replace_the_band_descriptions_that_name_others(files, tmp_path):
    # --wavelengths 470,...: the tag said 470 and the band descriptions still "480 nm" (the input's),
    # which tools that read the descriptions take for the centres.
    output = tmp_path / "out.tif"
    result = _invoke(*_base(files, output), "--wavelengths", "470,560,650,840")
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as written:
        assert written.descriptions == ("470 nm", "560 nm", "650 nm", "840 nm")
        assert written.tags()["wavelength"] == "470,560,650,840"
