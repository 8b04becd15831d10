"""A band named twice in ``--bands`` (``bands=``) is one line naming it, from every product reader.

The readers keep their band files by name, while the band centres (and HLS's NBAR sun zeniths)
were counted per name asked: Landsat and Sentinel-2 failed on an internal scratch VRT ("2
wavelengths ... for 1 bands"), HLS with an internal AlignmentError (exit 1), and Sentinel-2 with
``--view-band each`` wrote one band where two were asked (a bug hunt). The HLS granule's case is
in test_nbar_hls.py.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors.folders import find_product
from brdfcorr.tasks.series import open_products
from brdfcorr.testing import write_landsat_c2, write_sentinel2_safe, write_stac_item

MTD = Path(__file__).resolve().parents[1] / "data" / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"


@pytest.fixture(scope="module")
def products(tmp_path_factory):
    directory = tmp_path_factory.mktemp("products")
    safe = write_sentinel2_safe(directory, MTD, size=8)
    return {"safe": (safe, "B04"), "item": (write_stac_item(safe), "B04"),
            "landsat": (write_landsat_c2(directory, size=8, angle_bands=True), "SR_B4")}


@pytest.mark.parametrize("kind, options", [("safe", ()), ("safe", ("--view-band", "each")), ("item", ()),
                                           ("landsat", ())])
def test_the_command_line_names_the_band(products, tmp_path, kind, options):
    product, band = products[kind]
    output = tmp_path / "out.tif"
    result = CliRunner().invoke(main, ["nbar", str(product), "--bands", f"{band},{band}", *options, "-o", str(output)])
    assert result.exit_code == 2, result.output
    assert result.stderr.splitlines() == [f"brdfcorr: error: {product}: band {band} is named more than once in "
                                          f"--bands ({band}, {band}); name each band once"]
    assert not output.exists() and not list(tmp_path.iterdir())  # no scratch folder left either


@pytest.mark.parametrize("kind", ["safe", "item", "landsat"])
def test_python_entry_points_name_the_band(products, kind):
    product, band = products[kind]
    message = rf"band {band} is named more than once in bands= \({band}, {band}\); name each band once"
    with pytest.raises(SensorInputError, match=message):
        open_products([product], bands=[band, band])
    if kind != "item":
        with pytest.raises(SensorInputError, match=message):
            find_product(product, bands=(band, band))
