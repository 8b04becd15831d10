"""brdfcorr on real imagery: the MODIS MOD09A1 subset of ``benchmarks/data/modis_mod09a1_h18v04``.

A cheap version of ``benchmarks/bench_real.py`` (issue 24): NDVI strata (quartiles of the raw NDVI)
-> ``fit-classes`` -> ``correct``, and the fixed c-factor (``correct --params roy2016``), run with
the CLI's runner on the stored subset; the view-angle slope per NDVI group and band measured with
``brdfcorr assess`` (:func:`brdfcorr.analysis.assess.assess_view_angles`), as docs/real_imagery.md
runs them. Only what must hold is asserted:

- the subset is what its README says (grid, bands, angles in the product's documented ranges);
- vegetation is brighter towards backscatter (the hotspot; Ross-Li kernels, Lucht et al. 2000,
  IEEE TGRS 38, 977-998): the raw slope against the view zenith signed by the sun is negative in
  every group, red and NIR, and clearly so (the bench measures -3.5 to -7.5 %/10 deg);
- brdfcorr's correction, fitted on the scene, leaves at most half of the raw slope's magnitude in
  every group, red and NIR (the bench: at most 0.64 of 3.46-7.49 %/10 deg);
- the fixed c-factor reduces the raw slope's magnitude in every group, red and NIR. Its global
  coefficients know nothing of this scene, so this checks the relative azimuth's convention: with
  it flipped (0 deg read as forward scattering) the c-factor would steepen the slope;
- the inputs are left unchanged.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.analysis.assess import ViewAngleOptions, assess_view_angles, signed_view_zenith
from brdfcorr.cli import main
from brdfcorr.io.angles import open_angles
from brdfcorr.io.rasters import open_image
from brdfcorr.testing import file_digests

DATA = Path(__file__).resolve().parents[2] / "benchmarks" / "data" / "modis_mod09a1_h18v04"
IMAGE, ANGLES = DATA / "reflectance.tif", DATA / "angles.tif"
#: Band centres [nm], sorted (MOD09 user's guide, collection 6, table 1: bands 3, 4, 1, 2, 5, 6, 7).
CENTRES = [469.0, 555.0, 645.0, 858.5, 1240.0, 1640.0, 2130.0]
RED, NIR = CENTRES.index(645.0), CENTRES.index(858.5)
#: The NDVI groups: quartiles of the raw NDVI (0.747, 0.816, 0.859), named by ``classes ndvi``.
GROUPS = ("ndvi_-inf_0.75", "ndvi_0.75_0.82", "ndvi_0.82_0.86", "ndvi_0.86_inf")


def _run(arguments: list[str]) -> None:
    result = CliRunner().invoke(main, arguments)
    assert result.exit_code == 0, result.output


@pytest.fixture(scope="module")
def slopes(tmp_path_factory) -> dict[str, np.ndarray]:
    """Relative slopes [%/10 deg] (group, band: red, NIR) raw, after brdfcorr and after the c-factor,
    from ``brdfcorr assess`` as docs/real_imagery.md runs it (its figures too)."""
    out = tmp_path_factory.mktemp("real")
    before = file_digests(DATA)
    strata, table = out / "strata.tif", out / "table.yaml"
    _run(["classes", "ndvi", str(IMAGE), "--percentiles", "25,50,75", "-o", str(strata)])
    _run(["fit-classes", str(IMAGE), "--angles", str(ANGLES), "--classes", str(strata), "-o", str(table)])
    _run(["correct", str(IMAGE), "--angles", str(ANGLES), "--classes", str(strata), "--params", str(table),
          "-o", str(out / "brdfcorr.tif")])
    _run(["correct", str(IMAGE), "--angles", str(ANGLES), "--params", "roy2016", "--extrapolate",
          "-o", str(out / "cfactor.tif")])
    result = {}
    for name in ("brdfcorr", "cfactor"):
        _run(["assess", str(IMAGE), str(out / f"{name}.tif"), "--angles", str(ANGLES), "--classes", str(strata),
              "--block-size", "8", "-o", str(out / f"{name}.json"), "--figures", str(out / name)])
        assert (out / name / "assess_profiles.png").stat().st_size > 0
        view = json.loads((out / f"{name}.json").read_text())["view_angles"]
        groups = view["classes"]
        assert [group["name"] for group in groups] == list(GROUPS)  # the strata's names, from their tags
        within = view["summary"]["slopes_within_2_sigma"]  # every group and band has a sigma (63-81 blocks)
        assert within["of"] == len(GROUPS) * len(CENTRES) and 0 <= within["after"] <= within["of"]
        for stage, key in (("before", "raw"), ("after", name)):
            result[key] = np.array([[group[stage]["relative_slope"][band] for band in (RED, NIR)] for group in groups])
    assert file_digests(DATA) == before
    return result


def test_subset_is_what_its_readme_says():
    with rasterio.open(IMAGE) as image, rasterio.open(ANGLES) as angles:
        assert (image.count, image.height, image.width) == (7, 73, 66)
        assert [float(w) for w in image.tags()["wavelength"].split(",")] == CENTRES
        assert image.transform == angles.transform and image.crs == angles.crs
        assert abs(image.transform.a - 463.3127) < 1e-3  # the MODIS 500 m sinusoidal grid
        reflectance = image.read()
        sza, vza, raa = angles.read()
    valid = np.isfinite(reflectance)
    # the product's valid range, -100 to 16000 at scale 0.0001 (MOD09 user's guide, table 3)
    assert valid.any() and np.all((reflectance[valid] >= -0.01) & (reflectance[valid] <= 1.6))
    assert np.all(valid == valid[0])  # a masked pixel is masked in every band
    assert np.all((sza >= 0) & (sza < 90))
    assert np.all((vza >= 0) & (vza <= 66))  # MODIS scans to about 65 deg at the ground
    assert np.all((raa >= -180) & (raa <= 180))
    # a wide-swath composite: pixels from near nadir to past 50 deg, on both sides of nadir
    assert vza.min() < 10 and vza.max() > 50
    forward = np.abs(raa) > 90
    assert forward.any() and (~forward).any()


def test_raw_slope_shows_the_hotspot(slopes):
    assert slopes["raw"].shape == (4, 2)  # four NDVI groups, red and NIR
    assert np.all(slopes["raw"] < -2.0)


def test_brdfcorr_leaves_at_most_half_of_the_raw_slope(slopes):
    assert np.all(np.isfinite(slopes["brdfcorr"]))
    assert np.all(np.abs(slopes["brdfcorr"]) <= 0.5 * np.abs(slopes["raw"]))


def test_fixed_c_factor_reduces_the_raw_slope(slopes):
    assert np.all(np.abs(slopes["cfactor"]) < np.abs(slopes["raw"]))


def test_the_slopes_one_sigma_agrees_with_a_block_bootstrap():
    # The assessment's cluster-robust 1-sigma (blocks of 8 pixels) against a block bootstrap on the
    # same squares (whole squares drawn with replacement, 400 times; Kuensch 1989): two estimates
    # of one quantity, equal for many blocks; here 63-81 blocks per group, so within 30 %.
    raw, angles = open_image(IMAGE).compute(), {key: value.compute() for key, value in open_angles(ANGLES).items()}
    index = (raw.sel(band=raw["band"][NIR]) - raw.sel(band=raw["band"][RED])) / (
        raw.sel(band=raw["band"][NIR]) + raw.sel(band=raw["band"][RED]))
    edges = np.nanpercentile(index.values, [25, 50, 75])
    groups = np.where(np.isfinite(index.values), np.digitize(index.values, edges) + 1, 0)
    result = assess_view_angles(raw, raw, groups, angles["vza"], angles["vaa"], angles["saa"],
                                options=ViewAngleOptions(block_size=8))
    theta = signed_view_zenith(angles["vza"].values, angles["vaa"].values, angles["saa"].values)
    rows, columns = np.indices(theta.shape)
    squares = (rows // 8) * 100 + columns // 8
    rng = np.random.default_rng(0)
    for group in range(1, 5):
        pick = (groups == group) & np.isfinite(raw.values).all(axis=0)
        labels, member = np.unique(squares[pick], return_inverse=True)
        draws = np.stack([np.bincount(rng.integers(0, labels.size, labels.size), minlength=labels.size)
                          for _ in range(400)])[:, member].astype(float)
        for band in (RED, NIR):
            values = raw.values[band][pick]
            n = draws.sum(axis=1)
            mean_t, mean_v = draws @ theta[pick] / n, draws @ values / n
            slope = (draws @ (theta[pick] * values) / n - mean_t * mean_v) / (draws @ theta[pick] ** 2 / n - mean_t**2)
            bootstrap = np.std(1000 * slope / mean_v, ddof=1)
            analytic = float(result["relative_slope_error"].sel(stage="before").values[band, group - 1])
            assert 0.7 < analytic / bootstrap < 1.3, (group, band, analytic, bootstrap)
