"""`brdfcorr correct` on a real AVIRIS-NG line with its ENVI obs file as the angle source (issue 9).

The expected output is computed independently: the obs bands are read with rasterio by their
header names and the Torrance-Sparrow factor is evaluated with the public model function.
"""

from pathlib import Path

import numpy as np
import rasterio
import rioxarray
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.geometry import relative_azimuth
from brdfcorr.models import torrance_sparrow
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable

REALDATA = Path(__file__).resolve().parents[1] / "data"  # real files and their licences (README.md there)
LINE = REALDATA / "isofit_avirisng_topoflux"
IMAGE = LINE / "ang20160910t185702_2rdn_img"
OBS = LINE / "ang20160910t185702_obs_ortdem_mod"


def _obs_band(name: str) -> np.ndarray:
    with rasterio.open(OBS) as source:
        names = [d.split(" (")[0].strip() for d in source.descriptions]
        return source.read(names.index(name) + 1).astype(float)


def test_correct_aviris_ng_line_with_obs_angles(tmp_path):
    image = rioxarray.open_rasterio(IMAGE)
    classes = (image.isel(band=0, drop=True) * 0 + 1).astype("uint8").rio.write_nodata(255)
    classes.attrs = {}
    classes.rio.to_raster(tmp_path / "classes.tif")
    tile = load_material("roof_tile")
    table = ParameterTable(classes=[{"id": 1, "name": "roof_tile", "model": "torrance_sparrow",
                                     "params": tile.params}])
    table.save(tmp_path / "params.yaml")
    before = IMAGE.read_bytes()

    arguments = ["correct", str(IMAGE), "--angles", str(OBS), "--angles-kind", "envi_obs",
                 "--classes", str(tmp_path / "classes.tif"), "--params", str(tmp_path / "params.yaml"),
                 "-o", str(tmp_path / "out.tif"), "--no-limits", "--ref-vza", "0", "--no-progress"]
    # Radiance (uW cm-2 sr-1 nm-1, up to ~15) is no reflectance factor: used as it is only on the
    # user's word (--scale 1), never silently.
    refused = CliRunner().invoke(main, arguments)
    assert refused.exit_code == 2 and "do not look like reflectance factors" in refused.stderr
    assert "--scale/--offset" in refused.stderr and "scale 1: use them as they are" in refused.stderr and not (tmp_path / "out.tif").exists()
    result = CliRunner().invoke(main, [*arguments, "--scale", "1"])
    assert result.exit_code == 0, result.output
    assert IMAGE.read_bytes() == before

    sza, saa = _obs_band("To-sun zenith"), _obs_band("To-sun azimuth")
    vza, vaa = _obs_band("To-sensor zenith"), _obs_band("To-sensor azimuth")
    phi = relative_azimuth(saa, vaa)
    # Reference: the observed sun, nadir view (the CLI default without a table reference).
    factor = torrance_sparrow(sza, 0.0, 0.0, **tile.params) / torrance_sparrow(sza, vza, phi, **tile.params)
    with rasterio.open(IMAGE) as source:
        radiance = source.read().astype(float)
    with rasterio.open(tmp_path / "out.tif") as output:
        corrected = output.read().astype(float)
        assert output.crs == rasterio.open(IMAGE).crs
        assert output.count == radiance.shape[0] == 425
    valid = np.isfinite(corrected) & (radiance != -9999)
    assert valid.mean() > 0.9
    expected = radiance * factor[None]
    np.testing.assert_allclose(corrected[valid], expected[valid], rtol=2e-6)
    assert np.ptp(factor) > 0.01  # the line's view geometry varies enough to matter


def test_unknown_angle_option_is_one_clear_error(tmp_path):
    result = CliRunner().invoke(main, [
        "correct", str(IMAGE), "--angles", str(OBS), "--angles-kind", "envi_obs",
        "--angle-option", "novalue", "--classes", str(IMAGE), "--params", "missing.yaml",
        "-o", str(tmp_path / "out.tif"),
    ])
    assert result.exit_code == 2
    assert "Traceback" not in result.output and not (tmp_path / "out.tif").exists()
