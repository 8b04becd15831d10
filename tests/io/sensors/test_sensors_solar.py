"""Solar angles from time and coordinates (pvlib SPA) against the sun angles real products store."""

from __future__ import annotations

from pathlib import Path

import dask.array as da
import numpy as np
import pyproj
import pytest
import rasterio
import xarray as xr
from affine import Affine

from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors import grid_template, read_angles
from brdfcorr.io.sensors.envi import acquisition_time, read_envi_image, read_envi_obs
from brdfcorr.io.sensors.sentinel2 import parse_mtd_tl
from brdfcorr.io.sensors.solar import solar_angles, solar_position

REALDATA = Path(__file__).resolve().parents[2] / "data"  # real files and their licences (README.md there)

TOPOFLUX = REALDATA / "isofit_avirisng_topoflux"
CUBE = REALDATA / "isofit_avirisng_profiling_cube"


def test_avirisng_orthorectified_line_sun_angles_at_line_start_time():
    """The obs to-sun bands of ang20160910t185702 are the sun position at the line time in its
    name: pvlib at each pixel centre (UTM 11N -> WGS 84) agrees to 0.005 deg."""
    image = read_envi_image(TOPOFLUX / "ang20160910t185702_2rdn_img")
    obs = read_envi_obs(TOPOFLUX / "ang20160910t185702_obs_ortdem_mod", like=image).compute()
    sun = solar_angles(acquisition_time(image.attrs["source"]), image, chunks=(10, 12))
    assert isinstance(sun.sza.data, da.Array) and sun.sza.data.npartitions == 9
    np.testing.assert_allclose(sun.sza.values, obs.sza.values, atol=5e-3)
    np.testing.assert_allclose(sun.saa.values, obs.saa.values, atol=5e-3)
    assert sun.rio.crs.to_epsg() == 32611


def test_avirisng_raw_line_sun_angles_from_loc_file():
    """The profiling cube has no map grid; its loc file gives each pixel's longitude, latitude and
    elevation. pvlib at those positions and the line-name time matches the obs to-sun bands."""
    with rasterio.open(CUBE / "ang20170323t202244_loc_7000-7010") as loc:
        longitude, latitude, elevation = loc.read()
    with rasterio.open(CUBE / "ang20170323t202244_obs_7000-7010") as obs:
        sun_azimuth, sun_zenith = obs.read(4), obs.read(5)
    time = acquisition_time(CUBE / "ang20170323t202244_obs_7000-7010")
    zenith, azimuth = solar_position(time, latitude, longitude, elevation)
    assert zenith.shape == (10, 10)
    np.testing.assert_allclose(zenith, sun_zenith, atol=5e-3)
    np.testing.assert_allclose(azimuth, sun_azimuth, atol=5e-3)


def test_sentinel2_sun_grid_against_pvlib():
    """The 23 x 23 sun grid of the granule vs pvlib at the node positions and SENSING_TIME."""
    tile = parse_mtd_tl(REALDATA / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml")
    rows, cols = np.mgrid[0:23, 0:23]
    x, y = 300000.0 + 5000.0 * cols, 8600020.0 - 5000.0 * rows  # ULX/ULY and steps of the XML
    longitude, latitude = pyproj.Transformer.from_crs(tile.crs, 4326, always_xy=True).transform(x, y)
    zenith, azimuth = solar_position(tile.sensing_time, latitude, longitude)
    np.testing.assert_allclose(zenith, tile.sun_zenith, atol=0.05)
    np.testing.assert_allclose(azimuth, tile.sun_azimuth, atol=0.1)


def test_refraction_lifts_the_sun():
    """Apparent zenith < geometric zenith (refraction, about 0.016 deg at 45 deg zenith)."""
    geometric, _ = solar_position("2020-06-21T12:00Z", 45.0, 0.0)
    apparent, _ = solar_position("2020-06-21T12:00Z", 45.0, 0.0, refraction=True)
    assert 0.005 < float(geometric - apparent) < 0.05


def test_subsolar_point_has_zero_zenith():
    """Independent closed form: at the June solstice (declination 23.44 deg) at local solar
    noon the sun is within 0.3 deg of the zenith at latitude 23.44 N (equation of time < 2 min)."""
    zenith, _ = solar_position("2021-06-21T12:00Z", 23.44, 0.0)
    assert float(zenith) < 0.6


def test_lazy_result_does_not_depend_on_chunks():
    like = grid_template(Affine(1000.0, 0, 500000.0, 0, -1000.0, 5000000.0), (40, 30), "EPSG:32633", chunks=7)
    small = solar_angles("2022-07-01T10:00Z", like)
    large = solar_angles("2022-07-01T10:00Z", like, chunks=40)
    assert small.sza.data.npartitions == 30
    xr.testing.assert_allclose(small.compute(), large.compute(), rtol=0, atol=1e-12)


def test_naive_time_and_ungeoreferenced_grid_are_refused():
    like = grid_template(Affine(1.0, 0, 0, 0, -1.0, 0), (4, 4), None)
    with pytest.raises(SensorInputError, match="no time zone"):
        solar_position("2022-07-01T10:00", 45.0, 10.0)
    with pytest.raises(SensorInputError, match="no CRS"):
        solar_angles("2022-07-01T10:00Z", like)


def test_dispatcher_solar_kind_needs_explicit_view():
    like = grid_template(Affine(30.0, 0, 500000.0, 0, -30.0, 5000000.0), (5, 6), "EPSG:32633")
    angles = read_angles("solar", "2022-07-01T10:00Z", like=like, view_zenith=0.0, view_azimuth=-90.0)
    assert set(angles.data_vars) == {"sza", "saa", "vza", "vaa"}
    assert float(angles.vaa[0, 0]) == 270.0 and float(angles.vza.max()) == 0.0
    with pytest.raises(SensorInputError, match="set view_zenith and view_azimuth"):
        read_angles("solar", "2022-07-01T10:00Z", like=like)  # the view geometry is never guessed
    with pytest.raises(SensorInputError, match="needs the image grid"):
        read_angles("solar", "2022-07-01T10:00Z", view_zenith=0.0, view_azimuth=0.0)
