"""The built-in coefficient library (Roy et al. 2016, 2017) and its use by ``correct`` and the CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import UnknownNameError
from brdfcorr.io.sensors.bands import LANDSAT_OLI_WAVELENGTHS, SENTINEL2_WAVELENGTHS
from brdfcorr.models.coefficients import coefficient_names, load_coefficients
from brdfcorr.params import ClassEntry, ParameterTable
from brdfcorr.testing import synthetic_scene, write_scene

#: Roy et al. (2016), RSE 176, Table 1: (f_iso, f_vol, f_geo) per band, as printed.
ROY2016_TABLE1 = {
    "blue": (0.0774, 0.0372, 0.0079), "green": (0.1306, 0.0580, 0.0178), "red": (0.1690, 0.0574, 0.0227),
    "nir": (0.3093, 0.1535, 0.0330), "swir1": (0.3430, 0.1154, 0.0453), "swir2": (0.2658, 0.0639, 0.0387),
}
#: An independent copy: sen2nbar 2024.6.0, sen2nbar/axioms.py (github.com/ESDS-Leipzig/sen2nbar),
#: Sentinel-2 band -> (fiso, fvol, fgeo).
SEN2NBAR_AXIOMS = {
    "B02": (0.0774, 0.0372, 0.0079), "B03": (0.1306, 0.0580, 0.0178), "B04": (0.1690, 0.0574, 0.0227),
    "B05": (0.2085, 0.0845, 0.0256), "B06": (0.2316, 0.1003, 0.0273), "B07": (0.2599, 0.1197, 0.0294),
    "B08": (0.3093, 0.1535, 0.0330), "B11": (0.3430, 0.1154, 0.0453), "B12": (0.2658, 0.0639, 0.0387),
}
KEYS = ("f_iso", "f_vol", "f_geo")


def rtlsr_brf(weights, sza, vza, raa):
    """RTLSR reflectance factor written out here from Lucht et al. (2000) eqs. 38-45 (Ross-Thick;
    Li-Sparse-Reciprocal with b/r = 1, h/b = 2), angles in degrees, raa = 0 at the hot spot."""
    ti, tv, phi = (np.radians(np.asarray(a, float)) for a in (sza, vza, raa))
    cos_xi = np.cos(ti) * np.cos(tv) + np.sin(ti) * np.sin(tv) * np.cos(phi)
    xi = np.arccos(np.clip(cos_xi, -1, 1))
    k_vol = ((np.pi / 2 - xi) * cos_xi + np.sin(xi)) / (np.cos(ti) + np.cos(tv)) - np.pi / 4
    sec = 1 / np.cos(ti) + 1 / np.cos(tv)
    d2 = np.tan(ti) ** 2 + np.tan(tv) ** 2 - 2 * np.tan(ti) * np.tan(tv) * np.cos(phi)
    cos_t = np.clip(2.0 * np.sqrt(d2 + (np.tan(ti) * np.tan(tv) * np.sin(phi)) ** 2) / sec, -1, 1)
    t = np.arccos(cos_t)
    overlap = (t - np.sin(t) * cos_t) * sec / np.pi
    k_geo = overlap - sec + 0.5 * (1 + cos_xi) / (np.cos(ti) * np.cos(tv))
    f_iso, f_vol, f_geo = weights
    return f_iso + f_vol * k_vol + f_geo * k_geo


def test_library_holds_the_published_values():
    roy2016, roy2017 = load_coefficients("roy2016"), load_coefficients("roy2017")
    assert coefficient_names() == ("roy2016", "roy2017")
    for band, values in ROY2016_TABLE1.items():
        assert tuple(roy2016.published[band][k] for k in KEYS) == values
        assert tuple(roy2017.published[band][k] for k in KEYS) == values
    for band, values in SEN2NBAR_AXIOMS.items():
        spectral = roy2017.sensor_band("sentinel2", band)
        assert tuple(roy2017.published[spectral][k] for k in KEYS) == values, band
    assert "Remote Sensing of Environment 176, 255-271" in roy2016.source
    assert "Remote Sensing of Environment 199, 25-38" in roy2017.source


def test_red_edge_weights_lie_between_red_and_nir():
    # Roy et al. (2017) interpolated the red-edge weights in wavelength between red and NIR:
    # each weight increases monotonically from red through red-edge 1-3 to NIR.
    roy = load_coefficients("roy2017")
    for key in KEYS:
        sequence = [roy.published[b][key] for b in ("red", "red_edge_1", "red_edge_2", "red_edge_3", "nir")]
        assert np.all(np.diff(sequence) > 0), key


def test_params_are_the_published_weights_divided_by_pi():
    roy = load_coefficients("Roy-2016")
    for band, values in ROY2016_TABLE1.items():
        assert [roy.params(band)[k] for k in KEYS] == pytest.approx([v / math.pi for v in values], rel=1e-15)
    with pytest.raises(UnknownNameError, match="no coefficients for spectral band 'red_edge_1'"):
        roy.params("red_edge_1")
    with pytest.raises(UnknownNameError, match="built-in coefficient sets: roy2016, roy2017"):
        load_coefficients("roy2020")


def test_c_factor_is_unchanged_by_the_division_by_pi():
    """brdfcorr's model with weights / pi (sr^-1) and the published weights in the formula written
    out here (reflectance factors) give the same c-factor f(ref) / f(obs), and the model itself is
    the written-out BRF / pi."""
    roy = load_coefficients("roy2017")
    sza, vza, raa = np.array([25.0, 40.0, 55.0]), np.array([0.5, 7.0, 12.0]), np.array([0.0, 95.0, 170.0])
    for band in roy.published:
        published = [roy.published[band][k] for k in KEYS]
        expected = rtlsr_brf(published, 45.0, 0.0, 0.0) / rtlsr_brf(published, sza, vza, raa)
        c = roy.brdf(45.0, 0.0, 0.0, band) / roy.brdf(sza, vza, raa, band)
        np.testing.assert_allclose(c, expected, rtol=1e-12)
        np.testing.assert_allclose(roy.brdf(sza, vza, raa, band), rtlsr_brf(published, sza, vza, raa) / np.pi,
                                   rtol=1e-12)


@pytest.mark.parametrize("sensor, centres, names", [
    ("sentinel2", SENTINEL2_WAVELENGTHS, ("B02", "B03", "B04", "B05", "B06", "B07", "B08", "B8A", "B11", "B12")),
    ("landsat_oli", {f"SR_B{n}": w for n, w in LANDSAT_OLI_WAVELENGTHS.items()},
     ("SR_B2", "SR_B3", "SR_B4", "SR_B5", "SR_B6", "SR_B7")),
])
def test_wavelength_table_gives_each_sensor_band_its_own_weights(sensor, centres, names):
    """Interpolated in wavelength to the sensor's band centres, the library's one-class table gives
    every band exactly the weights it takes by name (piecewise constant across each band's centres)."""
    roy = load_coefficients("roy2017")
    table = ParameterTable(classes=[ClassEntry(**roy.table_entry(1))])
    resolved = table.for_bands(wavelengths=[centres[name] for name in names])[1].params
    by_name = roy.table_entry(1, sensor=sensor, bands=names)["params"]
    for key in KEYS:
        np.testing.assert_allclose(resolved[key], by_name[key], rtol=1e-12)


def test_sensor_bands_without_coefficients_are_refused():
    roy = load_coefficients("roy2017")
    assert roy.sensor_band("sentinel2", "B8A") == roy.sensor_band("sentinel2", "B08") == "nir"
    with pytest.raises(UnknownNameError, match="no coefficients for sentinel2 band 'B01'"):
        roy.sensor_band("sentinel2", "B01")
    with pytest.raises(UnknownNameError, match="no coefficients for sentinel2 band 'B05'"):
        load_coefficients("roy2016").table_entry(1, sensor="sentinel2", bands=["B04", "B05"])


def test_cli_lists_the_sets_with_their_sources(tmp_path):
    runner = CliRunner()
    listing = runner.invoke(main, ["coefficients"])
    assert listing.exit_code == 0, listing.output
    assert "roy2016" in listing.output and "doi:10.1016/j.rse.2017.06.019" in listing.output
    shown = runner.invoke(main, ["coefficients", "roy2017"])
    assert shown.exit_code == 0 and "B8A=nir" in shown.output and "0.09845" in shown.output  # 0.3093 / pi
    table_path = tmp_path / "table.yaml"
    added = runner.invoke(main, ["coefficients", "roy2016", "-o", str(table_path), "--class-id", "3"])
    assert added.exit_code == 0, added.output
    assert ParameterTable.load(table_path)[3].model == "ross_thick_li_sparse"
    unknown = runner.invoke(main, ["coefficients", "nope"])
    assert unknown.exit_code == 2 and "unknown coefficient set 'nope'" in unknown.output


def test_correct_with_a_library_name_and_no_class_map(tmp_path):
    """``correct --params roy2016`` without ``--classes``: the whole image is class 1 and each band
    is multiplied by the c-factor of the written-out formula at its band centre's weights."""
    wavelengths = (482.0, 562.0, 655.0, 835.0)  # OLI blue, green, red; ETM+ nir (the scene needs <= 850)
    scene = synthetic_scene(ny=16, nx=16, wavelengths=wavelengths)
    paths = write_scene(tmp_path, scene)
    output = tmp_path / "nbar.tif"
    result = CliRunner().invoke(main, ["correct", str(paths["image"]), "--angles", str(paths["angles"]),
                                       "--params", "roy2016", "--ref-sza", "35", "-o", str(output)])
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as dataset, rasterio.open(paths["image"]) as image:
        corrected, observed = dataset.read(), image.read()
    angles = {name: scene[name].values for name in ("sza", "vza")}
    raa = np.abs((scene["vaa"].values - scene["saa"].values + 180.0) % 360.0 - 180.0)
    for index, band in enumerate(("blue", "green", "red", "nir")):
        weights = ROY2016_TABLE1[band]
        c = rtlsr_brf(weights, 35.0, 0.0, 0.0) / rtlsr_brf(weights, angles["sza"], angles["vza"], raa)
        np.testing.assert_allclose(corrected[index], observed[index] * c, rtol=2e-6)


def test_a_table_of_several_classes_without_a_class_map_is_refused(tmp_path):
    # Without --classes the whole image is class 1: a table of other classes would correct every
    # pixel with class 1's parameters (or none), a wrong number delivered silently.
    from click.testing import CliRunner

    from brdfcorr.cli import main
    from brdfcorr.testing import example_table, synthetic_scene, write_scene

    paths = write_scene(tmp_path, synthetic_scene(ny=16, nx=16))
    table = tmp_path / "table.yaml"
    example_table().save(table)
    result = CliRunner().invoke(main, ["correct", str(paths["image"]), "--angles", str(paths["angles"]),
                                       "--params", str(table), "-o", str(tmp_path / "out.tif")])
    assert result.exit_code == 2
    assert "no class map was given" in result.output and "--classes" in result.output
    assert not (tmp_path / "out.tif").exists()
