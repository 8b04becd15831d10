"""A time series fitted from a chain (issue 37): the dates of one grid are the run's scenes, the
imagery fit step fits them at once with each pixel's level free (``levels: pixel``) and the correct
step corrects date by date. The chain writes what the command line does by hand, value for value:
``brdfcorr fit-classes --levels pixel`` over the dates, then ``brdfcorr correct`` of each."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rioxarray
import yaml

from brdfcorr.chain.config import load_config
from brdfcorr.chain.run import run_chain
from brdfcorr.params import ParameterTable
from brdfcorr.testing import synthetic_angles, synthetic_scene, write_scene

DATES = ("2024-04-01", "2024-04-11", "2024-04-21", "2024-05-01")
FIT = {"levels": "pixel", "block_size": 8, "min_samples": 50, "allow_uncorrected": True}


@pytest.fixture(scope="module")
def series(tmp_path_factory) -> Path:
    """Four dates of the same ground (seed 0) under a sun 3 deg higher each date, the view zenith at
    the swath's edges 12 and 20 deg on alternate dates (a neighbouring orbit every other date)."""
    root = tmp_path_factory.mktemp("series")
    for number, date in enumerate(DATES):
        angles = synthetic_angles(24, 32, sza=(25.0 + 3 * number, 30.0 + 3 * number), vza_max=12.0 + 8 * (number % 2))
        write_scene(root / "series" / date, synthetic_scene(ny=24, nx=32, angles=angles, seed=0))
    document = {
        "inputs": {"images": ["series/*/image.tif"], "angles": {"kind": "geotiff", "path": "{dir}/angles.tif"},
                   "classes": "{dir}/classes.tif"},
        "steps": {"fit": {"source": "imagery", **FIT}, "correct": {"limits": None}},
        "outputs": {"directory": "chain_out", "naming": "{parent}_brdf.tif"},
        "engine": {"scheduler": "synchronous", "chunk": 16},
    }
    (root / "series.yaml").write_text(yaml.safe_dump(document))
    return root


def test_the_chain_fits_the_dates_at_once_and_corrects_each_as_the_command_line(series, invoke):
    report = run_chain(load_config(series / "series.yaml"))
    assert report.ok, report.scenes
    classes = [entry for entry in report.fit["classes"] if entry["status"] == "fitted"]
    assert classes and all(entry["levels"] == "pixel" for entry in classes)  # each pixel's level free

    images = [series / "series" / date / "image.tif" for date in DATES]
    by_hand = series / "by_hand"
    by_hand.mkdir()
    code, stderr = invoke(["fit-classes", *images, *(a for image in images for a in ("--angles", image.parent / "angles.tif")),
                           *(a for image in images for a in ("--classes", image.parent / "classes.tif")),
                           "--levels", "pixel", "--block-size", "8", "--min-samples", "50",
                           "-o", by_hand / "table.yaml"])
    assert code == 0, stderr
    assert ParameterTable.load(series / "chain_out" / "fitted_params.yaml") == ParameterTable.load(
        series / "by_hand" / "table.yaml")
    for date, image in zip(DATES, images):
        code, stderr = invoke(["correct", image, "--angles", image.parent / "angles.tif", "--classes",
                               image.parent / "classes.tif", "--params", by_hand / "table.yaml", "--no-limits",
                               "-o", by_hand / f"{date}_brdf.tif", "--no-progress"])
        assert code == 0, stderr
        chain = rioxarray.open_rasterio(series / "chain_out" / f"{date}_brdf.tif").values
        cli = rioxarray.open_rasterio(by_hand / f"{date}_brdf.tif").values
        np.testing.assert_array_equal(chain, cli)  # value for value
        raw = rioxarray.open_rasterio(image).values
        assert not np.allclose(chain[np.isfinite(chain)], raw[np.isfinite(chain)])  # and it did correct


def test_a_fit_of_no_class_writes_no_table_and_the_chain_runs_again(series, tmp_path):
    """Three of the four dates leave every class's geometry spread under the fit's guard rail.
    The empty fitted table was written over the good one (``exit 2: nothing is written``), and
    the unchanged chain then reused it and could not run at all."""
    import shutil

    from click.testing import CliRunner

    from brdfcorr.cli import main

    shutil.copytree(series / "series", tmp_path / "series")
    chain = tmp_path / "series.yaml"
    chain.write_text((series / "series.yaml").read_text())
    assert CliRunner().invoke(main, ["run", str(chain), "--no-progress"]).exit_code == 0
    table = tmp_path / "chain_out" / "fitted_params.yaml"
    fitted = table.read_bytes()
    few = CliRunner().invoke(main, ["run", str(chain), "--no-progress", "--set",
                                    'inputs.images=["series/2024-04-*/image.tif"]'])
    assert few.exit_code == 2, few.output
    assert "the fit step fitted no class (1 (class_1): " in few.stderr.splitlines()[-1]
    assert table.read_bytes() == fitted
    again = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert again.exit_code == 0, again.output
