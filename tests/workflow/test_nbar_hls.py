"""``brdfcorr nbar`` on an HLS v2.0 granule: NBAR already, moved to another sun zenith on request.

The granule is built here (the HLS v2.0 file layout: one int16 GeoTIFF per band, reflectance x
10 000, no data -9999, the ``NBAR_SOLAR_ZENITH`` tag, an Fmask). The expected factor is computed
here from the RTLSR kernels in closed form at nadir view (Lucht et al. 2000, IEEE TGRS 38, 977-998,
eqs. for Ross-Thick and Li-Sparse-Reciprocal with b/r = 1, h/b = 2) and the red and NIR weights of
Roy et al. (2016), Table 1, not with brdfcorr's kernel code.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.testing import file_digests

NBAR_SZA = 38.4289484166757  # a real S30 granule's tag (T33UUP, 15 June 2023)
ROY_2016 = {"B04": (0.1690, 0.0574, 0.0227), "B8A": (0.3093, 0.1535, 0.0330)}  # red, NIR: f_iso, f_vol, f_geo


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def nadir_brf(weights, sza: float) -> float:
    """f_iso + f_vol K_vol + f_geo K_geo at view zenith 0: the phase angle is the sun zenith."""
    theta = math.radians(sza)
    k_vol = ((math.pi / 2 - theta) * math.cos(theta) + math.sin(theta)) / (math.cos(theta) + 1) - math.pi / 4
    sec = 1 / math.cos(theta)
    cos_t = min(2.0 * math.tan(theta) / (sec + 1), 1.0)  # h/b = 2, D = tan(theta)
    t = math.acos(cos_t)
    overlap = (t - math.sin(t) * cos_t) * (sec + 1) / math.pi
    k_geo = overlap - sec - 1 + 0.5 * (1 + math.cos(theta)) * sec
    f_iso, f_vol, f_geo = weights
    return f_iso + f_vol * k_vol + f_geo * k_geo


@pytest.fixture
def granule(tmp_path):
    folder = tmp_path / "HLS.S30.T33UUP.2023166T101559.v2.0"
    folder.mkdir()
    profile = dict(driver="GTiff", width=6, height=5, count=1, crs="EPSG:32633",
                   transform=Affine(30.0, 0, 300000.0, 0, -30.0, 5000040.0))
    for band, value in (("B04", 1200), ("B8A", 3100)):
        data = np.full((5, 6), value, dtype="int16")
        data[4, 5] = -9999
        with rasterio.open(folder / f"HLS.S30.T33UUP.2023166T101559.v2.0.{band}.tif", "w", dtype="int16",
                           nodata=-9999, **profile) as dataset:
            dataset.write(data, 1)
            dataset.update_tags(NBAR_SOLAR_ZENITH=str(NBAR_SZA))
    fmask = np.zeros((5, 6), dtype="uint8")
    fmask[0] = 1 << 1  # cloud
    fmask[1, 0] = 1 << 5  # water: kept
    with rasterio.open(folder / "HLS.S30.T33UUP.2023166T101559.v2.0.Fmask.tif", "w", dtype="uint8", nodata=255,
                       **profile) as dataset:
        dataset.write(fmask, 1)
    return folder


def test_the_nbar_is_moved_to_another_sun_zenith_exactly(granule, tmp_path):
    before = file_digests(granule)
    output, qa = tmp_path / "nbar45.tif", tmp_path / "qa.tif"
    result = run("nbar", granule, "--bands", "B04,B8A", "--ref-sza", "45", "-o", output, "--qa", qa)
    assert result.exit_code == 0, result.output
    assert file_digests(granule) == before
    with rasterio.open(output) as dataset:
        nbar, tags = dataset.read(), dataset.tags()
        assert dataset.descriptions == ("B04", "B8A")
    for index, (band, dn) in enumerate((("B04", 1200), ("B8A", 3100))):
        expected = dn * 1e-4 * nadir_brf(ROY_2016[band], 45.0) / nadir_brf(ROY_2016[band], NBAR_SZA)
        np.testing.assert_allclose(nbar[index, 1:4], expected, rtol=1e-6, err_msg=band)
    assert np.isnan(nbar[:, 0]).all() and np.isnan(nbar[:, 4, 5]).all()  # the cloud row, the band's no data
    assert np.isfinite(nbar[:, 1, 0]).all()  # water is not masked by default
    with rasterio.open(qa) as dataset:
        flags = dataset.read(1)
    assert (flags[0] == 1).all() and flags[4, 5] == 1 and (flags[1:4] == 0).all()
    assert tags["brdf_hls_nbar_solar_zenith"] == f"{NBAR_SZA:g}" and tags["brdf_reference"].startswith("sza=45")


def test_the_granules_own_sun_zenith_leaves_it_unchanged(granule, tmp_path):
    """f(θ, 0, 0) / f(θ, 0, 0) = 1: the output is the stored reflectance."""
    output = tmp_path / "same.tif"
    assert run("nbar", granule, "--ref-sza", str(NBAR_SZA), "-o", output).exit_code == 0
    with rasterio.open(output) as dataset:
        np.testing.assert_allclose(dataset.read()[:, 1:4], [np.full((3, 6), 0.12), np.full((3, 6), 0.31)], rtol=1e-6)


@pytest.mark.parametrize("options", [(), ("--ref-sza", "observed"), ("--ref-sza", "45", "--factor-at", "nodes"),
                                     ("--ref-sza", "45", "--bands", "B01"),
                                     ("--ref-sza", "45", "--resolution", "10")])
def test_what_an_hls_granule_cannot_do_is_one_line_and_exit_2(granule, tmp_path, options):
    result = run("nbar", granule, "-o", tmp_path / "out.tif", *options)
    assert result.exit_code == 2, result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "out.tif").exists()
    if not options:
        assert "already NBAR" in result.output and "sun zenith 38.43 deg" in result.output
        assert "--ref-sza DEG" in result.output


def test_hls_moves_the_granule_to_hls_v14s_sun_zenith_for_its_latitude(granule, tmp_path):
    """``--ref-sza hls``: the HLS v1.4 polynomial (User Guide p. 13) at the granule centre's latitude."""
    from pyproj import Transformer

    output = tmp_path / "hls14.tif"
    assert run("nbar", granule, "--bands", "B04", "--ref-sza", "hls", "-o", output).exit_code == 0
    with rasterio.open(output) as dataset:
        nbar, tags = dataset.read(1), dataset.tags()
        x, y = dataset.transform * (dataset.width / 2, dataset.height / 2)
        latitude = Transformer.from_crs(dataset.crs, "EPSG:4326", always_xy=True).transform(x, y)[1]
    coefficients = (31.0076, -0.1272, 0.01187, 2.40e-05, -9.48e-07, -1.95e-09, 6.15e-11)
    sza = sum(k * latitude**power for power, k in enumerate(coefficients))
    assert float(tags["brdf_reference"].split()[0].removeprefix("sza=")) == pytest.approx(sza, abs=1e-4)
    expected = 0.12 * nadir_brf(ROY_2016["B04"], sza) / nadir_brf(ROY_2016["B04"], NBAR_SZA)
    np.testing.assert_allclose(nbar[1:4], expected, rtol=1e-5)


def _retag(path: Path, **tags) -> None:
    with rasterio.open(path, "r+") as dataset:
        dataset.update_tags(**tags)


def test_each_band_moves_from_its_own_nbar_sun_zenith(granule, tmp_path):
    """Bands with different NBAR_SOLAR_ZENITH tags all took the first's (issue 39)."""
    _retag(next(granule.glob("*.B8A.tif")), NBAR_SOLAR_ZENITH="30")
    output = tmp_path / "nbar45.tif"
    assert run("nbar", granule, "--bands", "B04,B8A", "--ref-sza", "45", "-o", output).exit_code == 0
    with rasterio.open(output) as dataset:
        nbar, tags = dataset.read(), dataset.tags()
    for index, (band, dn, own) in enumerate((("B04", 1200, NBAR_SZA), ("B8A", 3100, 30.0))):
        expected = dn * 1e-4 * nadir_brf(ROY_2016[band], 45.0) / nadir_brf(ROY_2016[band], own)
        np.testing.assert_allclose(nbar[index, 1:4], expected, rtol=1e-6, err_msg=band)
    assert tags["brdf_hls_nbar_solar_zenith"] == f"{NBAR_SZA:g},30"


def test_a_float_reflectance_band_is_not_scaled_again(granule, tmp_path):
    """A band of float reflectance was multiplied by 1e-4 like the stored integers (issue 39)."""
    path = next(granule.glob("*.B04.tif"))
    with rasterio.open(path) as dataset:
        profile, data, tags = dataset.profile, dataset.read(), dataset.tags()
    reflectance = np.where(data == -9999, -9999.0, data * 1e-4).astype("float32")
    with rasterio.open(path, "w", **{**profile, "dtype": "float32"}) as dataset:
        dataset.write(reflectance)
        dataset.update_tags(**tags)
    output = tmp_path / "nbar45.tif"
    assert run("nbar", granule, "--bands", "B04,B8A", "--ref-sza", "45", "-o", output).exit_code == 0
    with rasterio.open(output) as dataset:
        nbar = dataset.read(1)
    expected = 0.12 * nadir_brf(ROY_2016["B04"], 45.0) / nadir_brf(ROY_2016["B04"], NBAR_SZA)
    np.testing.assert_allclose(nbar[1:4], expected, rtol=1e-6)


@pytest.mark.parametrize("sza", ["nan", "inf", "95", "-10"])
def test_a_reference_sun_zenith_outside_its_domain_is_one_line(granule, tmp_path, sza):
    """A raw pydantic ValidationError (exit 1) before (issue 39); Sentinel-2 gave exit 2 already."""
    output = tmp_path / "out.tif"
    result = run("nbar", granule, "--ref-sza", sza, "-o", output)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("brdfcorr: error: ") and "sza" in lines[0], result.stderr
    assert "ValidationError" not in result.output and not output.exists()


def _refusal_of_a_shifted_file(granule, tmp_path, pattern: str, pixels: int) -> str:
    """``nbar`` on the granule with its file ``pattern`` moved ``pixels`` east: exit 2, no output,
    and the one line it prints."""
    with rasterio.open(next(granule.glob(pattern)), "r+") as dataset:
        dataset.transform = dataset.transform * Affine.translation(pixels, 0)
    output = tmp_path / "out.tif"
    result = run("nbar", granule, "--ref-sza", "45", "-o", output)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and not output.exists(), result.stderr
    return lines[0]


def test_an_fmask_on_a_shifted_grid_is_one_line_naming_it(granule, tmp_path):
    line = _refusal_of_a_shifted_file(granule, tmp_path, "*.Fmask.tif", 2)
    assert re.search(r"Fmask\.tif: the Fmask is not on the grid of band B04 \S+B04\.tif: ", line), line


def test_a_band_on_a_shifted_grid_is_named_not_the_fmask(granule, tmp_path):
    """A band shifted against the others was blamed on the Fmask (issue 39)."""
    line = _refusal_of_a_shifted_file(granule, tmp_path, "*.B8A.tif", 1)
    assert re.search(r"B8A\.tif: band B8A is not on the grid of band B04 \S+B04\.tif: ", line), line


def _second_granule(granule: Path, granule_id: str) -> None:
    """Copies of the granule's files under another granule's id, beside them in its folder (as
    earthaccess downloads a search's granules into one folder)."""
    import shutil

    for file in sorted(granule.glob("HLS.S30.T33UUP.2023166T101559.v2.0.*.tif")):
        shutil.copy(file, granule / file.name.replace("HLS.S30.T33UUP.2023166T101559.v2.0", granule_id))


@pytest.mark.parametrize("other", ["HLS.S30.T33UUP.2023171T101601.v2.0",  # another date: its Fmask was read
                                   "HLS.L30.T33UUP.2023168T094512.v2.0"])  # L30: its B05 (NIR) is not S30's B05
def test_a_folder_of_several_granules_is_refused_naming_them(granule, tmp_path, other):
    """The bands of one granule were read with the Fmask of another, and an S30 + L30 folder read
    the S30 red-edge B05 as the L30 NIR B05 (a bug hunt): now one line naming both granules."""
    _second_granule(granule, other)
    output = tmp_path / "out.tif"
    result = run("nbar", granule, "--ref-sza", "45", "-o", output)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and not output.exists(), result.stderr
    assert "2 HLS granules in one folder" in lines[0]
    assert "HLS.S30.T33UUP.2023166T101559.v2.0" in lines[0] and other in lines[0]


def test_a_band_named_twice_is_one_line_naming_it(granule, tmp_path):
    """``--bands B04,B04`` was an internal AlignmentError, exit 1 (a bug hunt)."""
    output = tmp_path / "out.tif"
    result = run("nbar", granule, "--bands", "B04,B8A,B04", "--ref-sza", "45", "-o", output)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and not output.exists(), result.stderr
    assert lines[0] == f"brdfcorr: error: {granule}: band B04 is named more than once in --bands (B04, B8A, B04); " \
                       "name each band once"
