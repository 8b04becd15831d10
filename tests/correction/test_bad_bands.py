"""Bad bands (issue 24): water-vapour bands and those an ENVI header's ``bbl`` marks bad are left
out of imagery fits, get no parameters in the table (``bad_bands``) and are passed through
uncorrected by the correction, flagged ``band_uncorrected``.

Closed forms: a passed-through band is the input bit for bit (factor 1); every other band equals,
bit for bit, the result of the same step on the image without the bad bands.
"""

import json
import warnings

import numpy as np
import pytest
import rasterio
import xarray as xr
import yaml
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.correction import QA, normalize, qa_counts
from brdfcorr.errors import BrdfcorrWarning, ParameterError
from brdfcorr.fit import fit_classes
from brdfcorr.fit.classes import WATER_VAPOUR_BANDS, Sampling
from brdfcorr.params import ParameterTable
from brdfcorr.testing import synthetic_scene, write_envi_line

#: Band centres [nm]: 1400 and 1900 lie in the water-vapour ranges (1340-1450, 1800-1960 nm).
WAVELENGTHS = (480.0, 560.0, 660.0, 830.0, 1400.0, 1650.0, 1900.0, 2200.0)
BAD = np.array([w in (1400.0, 1900.0) for w in WAVELENGTHS])
GOOD = np.flatnonzero(~BAD)

#: Two kernel-driven classes with band-independent weights [sr^-1]: the scene renders at any band.
TRUTH = ParameterTable(classes=[
    {"id": 1, "name": "grass", "model": "ross_thick_li_sparse",
     "params": {"f_iso": 0.08, "f_vol": 0.04, "f_geo": 0.01}},
    {"id": 2, "name": "soil", "model": "ross_thick_li_sparse",
     "params": {"f_iso": 0.06, "f_vol": 0.01, "f_geo": 0.012}},
])
#: A fitted-looking class: parameters at the good wavelengths, none in the water-vapour ranges.
SPECTRAL = {"id": 1, "name": "grass", "model": "ross_thick_li_sparse",
            "wavelengths": [480.0, 560.0, 660.0, 830.0, 1650.0, 2200.0],
            "params": {"f_iso": [0.02, 0.04, 0.03, 0.12, 0.09, 0.05], "f_vol": [0.01, 0.02, 0.01, 0.06, 0.04, 0.02],
                       "f_geo": 0.004}}


def _angles(scene):
    return {name: scene[name] for name in ("sza", "saa", "vza", "vaa")}


@pytest.fixture(scope="module")
def scene():
    return synthetic_scene(ny=48, nx=64, wavelengths=WAVELENGTHS, table=TRUTH, seed=3)


# ------------------------------------------------------------------------------ the table


def test_bad_bands_round_trip_and_name_the_class_when_wrong(tmp_path):
    table = ParameterTable(classes=[{**SPECTRAL, "bad_bands": [[1340, 1450], [1800, 1960]]}])
    path = table.save(tmp_path / "table.yaml")
    assert yaml.safe_load(path.read_text())["classes"][0]["bad_bands"] == [[1340.0, 1450.0], [1800.0, 1960.0]]
    assert ParameterTable.load(path) == table
    with pytest.raises(ParameterError, match=r"class 1 \(grass\): wavelength 1650 nm lies in bad_bands"):
        ParameterTable(classes=[{**SPECTRAL, "bad_bands": [[1600, 1700]]}])
    with pytest.raises(ParameterError, match=r"class 1 \(grass\): bad_bands range \[1450, 1340\] nm"):
        ParameterTable(classes=[{**SPECTRAL, "bad_bands": [[1450, 1340]]}])


def test_bands_in_bad_ranges_resolve_to_no_parameters_the_others_as_without_them():
    table = ParameterTable(classes=[{**SPECTRAL, "bad_bands": [[1340, 1450], [1800, 1960]]}])
    resolved = table.for_bands(WAVELENGTHS)[1]
    assert resolved.no_parameters.tolist() == BAD.tolist()
    assert all(np.isnan(values[BAD]).all() for values in resolved.params.values())
    # The good bands: linear interpolation in the class's wavelengths (np.interp), untouched by
    # the gaps; 1650 and 2200 nm are table wavelengths, so exact.
    expected = np.interp(np.asarray(WAVELENGTHS)[GOOD], SPECTRAL["wavelengths"], SPECTRAL["params"]["f_iso"])
    assert np.array_equal(resolved.params["f_iso"][GOOD], expected)
    # A band centre outside the class's wavelengths needs extrapolation, unless it is a bad band.
    short = {**SPECTRAL, "wavelengths": SPECTRAL["wavelengths"][:5],
             "params": {"f_iso": SPECTRAL["params"]["f_iso"][:5], "f_vol": SPECTRAL["params"]["f_vol"][:5],
                        "f_geo": 0.004}}
    edge = ParameterTable(classes=[{**short, "bad_bands": [[2100, 2500]]}])
    assert edge.for_bands([480.0, 2200.0])[1].no_parameters.tolist() == [False, True]
    with pytest.raises(ParameterError, match="bad_bands are wavelength ranges"):
        table.for_bands(n_bands=len(WAVELENGTHS))
    assert ParameterTable(classes=[SPECTRAL]).for_bands(WAVELENGTHS[:4])[1].no_parameters is None


# ------------------------------------------------------------------------------ the correction


@pytest.mark.parametrize("chunked", [False, True])
def test_a_bad_band_is_the_input_bit_for_bit_and_the_others_as_without_it(scene, chunked):
    table = ParameterTable(classes=[{**SPECTRAL, "bad_bands": [[1340, 1450], [1800, 1960]]},
                                    {**SPECTRAL, "id": 2, "name": "soil"}])
    plain = ParameterTable(classes=[SPECTRAL, {**SPECTRAL, "id": 2, "name": "soil"}])
    reflectance = scene["reflectance"].chunk({"band": 3, "y": 16, "x": 32}) if chunked else scene["reflectance"]
    classes = scene["classes"].copy()
    classes[:4] = 0  # no class: not corrected, no band flag
    result = normalize(reflectance, classes, _angles(scene), table)
    out, qa, observed = result.reflectance.values, result.qa.values, scene["reflectance"].values
    # Class 2 has parameters in every band (interpolated): only class 1's bad bands pass through.
    ones, twos = classes.values == 1, classes.values == 2
    assert np.array_equal(out[BAD][:, ones], observed[BAD][:, ones])
    assert not np.isclose(out[BAD][:, twos], observed[BAD][:, twos]).all()
    without = normalize(scene["reflectance"].isel(band=GOOD), classes, _angles(scene), plain)
    assert np.array_equal(out[GOOD], without.reflectance.values)
    assert np.array_equal((qa & QA.BAND_UNCORRECTED) > 0, ones)
    assert np.array_equal(qa & ~np.uint8(QA.BAND_UNCORRECTED), without.qa.values)
    assert int(qa_counts(result.qa)["corrected"]) == int(qa_counts(without.qa)["corrected"])
    assert "band_uncorrected" in result.qa.attrs["flag_meanings"].split() and QA.BAND_UNCORRECTED == 128


# ------------------------------------------------------------------------------ the fit


def test_fit_leaves_bad_bands_out_and_fits_the_others_as_without_them(scene):
    args = ([scene["reflectance"]], [scene["classes"]], [xr.Dataset(_angles(scene))])
    with_bad = fit_classes(*args, "ross_thick_li_sparse", guard=_loose())
    without = fit_classes([scene["reflectance"].isel(band=GOOD)], *args[1:], "ross_thick_li_sparse", guard=_loose())
    assert with_bad.bad_bands == [list(WATER_VAPOUR_BANDS[0]), list(WATER_VAPOUR_BANDS[1])]
    assert with_bad.bands_left_out == [1400.0, 1900.0]
    for entry in with_bad.table.classes:
        other = without.table[entry.id]
        assert entry.bad_bands == with_bad.bad_bands and other.bad_bands is None
        assert entry.params == other.params and entry.wavelengths == other.wavelengths
    everything = fit_classes(*args, "ross_thick_li_sparse", guard=_loose(), sampling=Sampling(bad_bands=()))
    assert everything.bad_bands == [] and everything.table[1].bad_bands is None


def test_uncertainty_is_zero_and_ndvi_interpolation_passes_bad_bands_through(scene):
    from brdfcorr.correction.uncertainty import correction_uncertainty

    args = ([scene["reflectance"]], [scene["classes"]], [xr.Dataset(_angles(scene))])
    table = fit_classes(*args, "ross_thick_li_sparse", guard=_loose()).table
    plain = fit_classes([scene["reflectance"].isel(band=GOOD)], *args[1:], "ross_thick_li_sparse",
                        guard=_loose()).table
    sigma = correction_uncertainty(scene["reflectance"], scene["classes"], _angles(scene), table).values
    expected = correction_uncertainty(scene["reflectance"].isel(band=GOOD), scene["classes"], _angles(scene),
                                      plain).values
    assert (sigma[BAD] == 0).all()  # the output is the input there: the correction adds nothing
    assert np.array_equal(sigma[GOOD], expected, equal_nan=True) and np.isfinite(expected).any()
    group = {"classes": [1, 2], "centres": [0.1, 0.5]}
    result = normalize(scene["reflectance"], scene["classes"], _angles(scene), table.with_ndvi_interpolation(group))
    without = normalize(scene["reflectance"].isel(band=GOOD), scene["classes"], _angles(scene),
                        plain.with_ndvi_interpolation(group))
    assert np.array_equal(result.reflectance.values[BAD], scene["reflectance"].values[BAD])
    assert np.array_equal(result.reflectance.values[GOOD], without.reflectance.values)
    assert ((result.qa.values & QA.BAND_UNCORRECTED) > 0).all()


def _loose():
    from brdfcorr.fit import GuardRails

    return GuardRails(min_samples=50, min_r2=-np.inf)


def test_cli_leaves_out_water_vapour_and_bbl_bands_says_so_and_correct_passes_them_through(scene, tmp_path):
    line = write_envi_line(tmp_path / "line", xr.Dataset(dict(scene)))
    with rasterio.open(line["image"], "r+") as dataset:  # bbl: 1 good, 0 bad (band 2, 560 nm)
        dataset.update_tags(ns="ENVI", bbl="{1, 0, 1, 1, 1, 1, 1, 1}")
    scene["classes"].rio.to_raster(tmp_path / "classes.tif")
    out = tmp_path / "out"
    common = [str(line["image"]), "--angles", str(line["obs"]), "--angles-kind", "envi_obs",
              "--classes", str(tmp_path / "classes.tif")]
    fitted = CliRunner().invoke(main, ["fit-classes", *common, "--model", "ross_thick_li_sparse", "--min-samples",
                                       "50", "-o", str(out / "table.yaml"), "--report", str(out / "report.json"),
                                       "--plot-dir", str(out / "plots")])
    assert fitted.exit_code == 0, fitted.output
    report = json.loads((out / "report.json").read_text())
    assert report["bands_left_out"] == [560.0, 1400.0, 1900.0]
    assert ("3 bad bands left out of the fit (560, 1340-1450, 1800-1960 nm; 1 marked bad by the ENVI header's bbl)"
            in fitted.output)
    table = ParameterTable.load(out / "table.yaml")
    assert table[1].bad_bands == [[560.0, 560.0], [1340.0, 1450.0], [1800.0, 1960.0]]
    corrected = CliRunner().invoke(main, ["correct", *common, "--params", str(out / "table.yaml"),
                                          "--qa", str(out / "qa.tif"), "-o", str(out / "corrected.tif")])
    assert corrected.exit_code == 0, corrected.output
    with rasterio.open(line["image"]) as source, rasterio.open(out / "corrected.tif") as result:
        before, after = source.read(masked=True).filled(np.nan), result.read()
    bad = np.array([False, True, False, False, True, False, True, False])
    assert np.array_equal(after[bad], before[bad], equal_nan=True)
    assert not np.allclose(after[~bad], before[~bad], equal_nan=True)
    with rasterio.open(out / "qa.tif") as qa:
        flags = qa.read(1)
    assert ((flags & QA.BAND_UNCORRECTED) > 0).all()

    # An ENVI output keeps the input's bad band list: downstream tools still skip band 2.
    envi = CliRunner().invoke(main, ["correct", *common, "--params", str(out / "table.yaml"), "--format", "ENVI",
                                     "-o", str(out / "corrected.img")])
    assert envi.exit_code == 0, envi.output
    with rasterio.open(out / "corrected.img") as result:
        assert result.tags(ns="ENVI")["bbl"].replace(" ", "") == "{1,0,1,1,1,1,1,1}"
        assert np.array_equal(result.read(), after, equal_nan=True)

    none = CliRunner().invoke(main, ["fit-classes", *common, "--model", "ross_thick_li_sparse", "--min-samples",
                                     "50", "--bad-bands", "none", "-o", str(out / "bbl_only.yaml")])
    assert none.exit_code == 0, none.output
    assert ParameterTable.load(out / "bbl_only.yaml")[1].bad_bands == [[560.0, 560.0]]


def test_help_names_the_default_ranges():
    text = " ".join(CliRunner().invoke(main, ["fit-classes", "--help"]).output.split())
    assert all(f"{low:g}:{high:g}" in text for low, high in WATER_VAPOUR_BANDS)
    refused = CliRunner().invoke(main, ["fit-classes", "x.tif", "--angles", "a", "--classes", "c", "-o", "t.yaml",
                                        "--bad-bands", "1450:1340"])
    assert refused.exit_code == 2 and "0 < LOW <= HIGH" in refused.output


def test_bad_bands_of_every_class_over_every_band_warn(scene):
    """A table whose bad_bands cover every band corrects nothing: the output was the input with
    "57550 pixels corrected" and no word (issue 39)."""
    everything = {**SPECTRAL, "wavelengths": [350.0, 2450.0], "bad_bands": [[400, 2400]],
                  "params": {"f_iso": [0.02, 0.05], "f_vol": [0.01, 0.02], "f_geo": 0.004}}  # no image band left
    table = ParameterTable(classes=[everything, {**everything, "id": 2, "name": "soil"}])
    with pytest.warns(BrdfcorrWarning, match=r"the bad_bands of every class \(1, 2\) cover every band of the image"):
        result = normalize(scene["reflectance"], scene["classes"], _angles(scene), table)
    assert np.array_equal(result.reflectance.values, scene["reflectance"].values)
    partly = ParameterTable(classes=[everything, {**SPECTRAL, "id": 2, "name": "soil"}])
    with warnings.catch_warnings():
        warnings.simplefilter("error", BrdfcorrWarning)
        normalize(scene["reflectance"], scene["classes"], _angles(scene), partly)
