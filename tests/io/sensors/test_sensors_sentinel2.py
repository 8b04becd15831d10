"""Sentinel-2 MTD_TL.xml angle grids (tests/data, tile T23LLF, 2019-04-25)."""

from __future__ import annotations

import re
from pathlib import Path

import dask.array as da
import numpy as np
import pytest
from affine import Affine
from scipy.interpolate import RegularGridInterpolator

from brdfcorr.errors import SensorInputError
from brdfcorr.geometry import relative_azimuth
from brdfcorr.io.sensors import grid_template, read_angles
from brdfcorr.io.sensors.sentinel2 import combine_detectors, fill_gaps, parse_mtd_tl, read_sentinel2_angles

REALDATA = Path(__file__).resolve().parents[2] / "data"  # real files and their licences (README.md there)
MTD = REALDATA / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"


def xml_grid(text: str, start_tag: str, which: str) -> np.ndarray:
    """A Zenith/Azimuth values grid cut from the XML text with regular expressions only."""
    block = text[text.index(start_tag):]
    block = block[block.index(f"<{which}>"):block.index(f"</{which}>")]
    rows = re.findall(r"<VALUES>(.*?)</VALUES>", block)
    return np.array([[float(v) for v in row.split()] for row in rows])


@pytest.fixture(scope="module")
def tile():
    return parse_mtd_tl(MTD)


@pytest.fixture(scope="module")
def text():
    return MTD.read_text()


def test_grids_sizes_and_geoposition(tile, text):
    np.testing.assert_array_equal(tile.sun_zenith, xml_grid(text, "<Sun_Angles_Grid>", "Zenith"))
    np.testing.assert_array_equal(tile.sun_azimuth, xml_grid(text, "<Sun_Angles_Grid>", "Azimuth"))
    assert tile.sun_zenith.shape == (23, 23)
    assert tile.sun_zenith[0, 0] == 35.7343 and tile.sun_zenith[0, 22] == 35.0607
    detector = xml_grid(text, '<Viewing_Incidence_Angles_Grids bandId="3" detectorId="5">', "Zenith")
    np.testing.assert_array_equal(tile.view_zenith["B04"][5], detector)
    assert sorted(tile.view_zenith["B04"]) == [2, 3, 4, 5, 6, 7, 8]
    assert len(tile.view_zenith) == 13
    assert tile.crs == "EPSG:32723"
    assert tile.sizes == {10: (10980, 10980), 20: (5490, 5490), 60: (1830, 1830)}
    assert tile.geopositions[20] == Affine(20.0, 0.0, 300000.0, 0.0, -20.0, 8600020.0)
    assert str(tile.sensing_time) == "2019-04-25 13:26:00.865611+00:00"


def test_detectors_combined(tile):
    zenith, azimuth = tile.view_zenith["B04"], tile.view_azimuth["B04"]
    stack = np.stack([zenith[d] for d in sorted(zenith)])
    count = np.isfinite(stack).sum(axis=0)
    combined_zenith, combined_azimuth = combine_detectors(zenith, azimuth)
    assert np.isfinite(combined_zenith).all() and np.isfinite(combined_azimuth).all()
    single = count == 1
    np.testing.assert_allclose(combined_zenith[single], np.nansum(stack, axis=0)[single])
    overlap = np.argwhere(count == 2)
    assert len(overlap) > 10  # adjacent detectors overlap at some nodes
    # Where detectors overlap, the direction of the mean of their view vectors
    # (tan(zenith) sin(azimuth), tan(zenith) cos(azimuth)), not zenith and azimuth averaged apart.
    azimuths = np.stack([azimuth[d] for d in sorted(azimuth)])
    for row, col in overlap:
        seen = np.isfinite(stack[:, row, col])
        slope, turn = np.tan(np.radians(stack[seen, row, col])), np.radians(azimuths[seen, row, col])
        east, north = np.mean(slope * np.sin(turn)), np.mean(slope * np.cos(turn))
        assert combined_zenith[row, col] == pytest.approx(np.degrees(np.arctan(np.hypot(east, north))), abs=1e-9)
        assert combined_azimuth[row, col] == pytest.approx(np.degrees(np.arctan2(east, north)) % 360.0, abs=1e-6)
        assert combined_zenith[row, col] <= stack[seen, row, col].max() + 1e-9
    assert 0.0 <= combined_azimuth.min() and combined_azimuth.max() < 360.0


def test_fill_gaps_takes_the_nearest_node():
    grid = np.array([[1.0, np.nan, np.nan, 4.0], [np.nan, np.nan, np.nan, np.nan], [9.0, np.nan, np.nan, 12.0]])
    filled = fill_gaps(grid)
    np.testing.assert_array_equal(filled, [[1, 1, 4, 4], [1, 1, 4, 4], [9, 9, 12, 12]])
    with pytest.raises(SensorInputError, match="no finite value"):
        fill_gaps(np.full((2, 2), np.nan))


def test_angles_on_the_60m_grid_match_independent_interpolation(tile):
    angles = read_sentinel2_angles(MTD, resolution=60, band="B04", chunks=512)
    assert {name: angles[name].dims for name in angles.data_vars} == dict.fromkeys(("sza", "saa", "vza", "vaa"), ("y", "x"))
    assert isinstance(angles.sza.data, da.Array) and angles.sza.shape == (1830, 1830)
    assert angles.rio.crs.to_epsg() == 32723
    assert tuple(angles.sza.rio.transform())[:6] == (60.0, 0.0, 300000.0, 0.0, -60.0, 8600020.0)
    # Node (i, j) at (300000 + 5000 j, 8600020 - 5000 i); pixel (r, c) centre at 30 + 60 c, ...
    nodes = (8600020.0 - 5000.0 * np.arange(23)[::-1], 300000.0 + 5000.0 * np.arange(23))
    rows, cols = np.array([10, 500, 917, 1820]), np.array([3, 700, 1200, 1829])
    y, x = 8600020.0 - 60.0 * (rows + 0.5), 300000.0 + 60.0 * (cols + 0.5)
    sza = RegularGridInterpolator(nodes, tile.sun_zenith[::-1])((y, x))
    # The view direction: its ground-projected vector (tan(vza) sin(vaa), tan(vza) cos(vaa))
    # interpolated component by component.
    zenith, azimuth = (np.radians(grid) for grid in combine_detectors(tile.view_zenith["B04"], tile.view_azimuth["B04"]))
    east, north = (RegularGridInterpolator(nodes, (np.tan(zenith) * trig(azimuth))[::-1])((y, x))
                   for trig in (np.sin, np.cos))
    picked = angles.isel(y=("p", rows), x=("p", cols)).compute()
    np.testing.assert_allclose(picked.sza.values, sza, atol=1e-9)
    np.testing.assert_allclose(picked.vza.values, np.degrees(np.arctan(np.hypot(east, north))), atol=1e-9)
    np.testing.assert_allclose(picked.vaa.values, np.degrees(np.arctan2(east, north)) % 360.0, atol=1e-7)
    # Ranges: the sun grid's range bounds the interpolated field.
    assert tile.sun_zenith.min() <= float(angles.sza.min()) and float(angles.sza.max()) <= tile.sun_zenith.max()
    # Tile means against the XML's own Mean_Sun_Angle and band-3 (B04) Mean_Viewing_Incidence_Angle.
    assert float(angles.sza.mean()) == pytest.approx(35.736120160094, abs=1e-3)
    assert float(angles.saa.mean()) == pytest.approx(43.3890691221155, abs=1e-2)
    # The view zenith 3.588 (zenith and azimuth interpolated apart: 3.648): at the detector seams the
    # staggered odd and even detectors look fore and aft (the along-track component of the view
    # vector steps by up to about 2 deg near nadir), and the vector interpolated across a seam's
    # cell passes near 0 there, while ESA's mean takes each pixel's own detector.
    assert float(angles.vza.mean()) == pytest.approx(3.68075161027702, abs=0.1)


def test_10m_grid_is_lazy_and_a_window_computes_alone():
    angles = read_sentinel2_angles(MTD)  # all bands averaged, full tile at 10 m
    assert angles.sza.shape == (10980, 10980) and angles.sza.data.npartitions == 36
    angles = read_sentinel2_angles(MTD, chunks=256)
    window = angles.isel(y=slice(6000, 6004), x=slice(100, 103)).compute()
    assert window.vza.shape == (4, 3)
    # Bilinear interpolation stays within the node values of the bands' detector grids.
    tile = parse_mtd_tl(MTD)
    nodes = np.concatenate([grid.ravel() for band in tile.view_zenith.values() for grid in band.values()])
    assert np.nanmin(nodes) <= float(window.vza.min()) and float(window.vza.max()) <= np.nanmax(nodes)
    assert float(window.vza.mean()) > 6.0  # x = 301 km: the west edge, far from the track (east)


def test_view_azimuth_points_towards_the_satellite(tile):
    """The view zenith grows away from the satellite ground track, so it decreases towards the
    satellite: the azimuth of -grad(vza) must be close to the stored view azimuth (up to the
    fore/aft tilt of the staggered detectors), and far from it when flipped."""
    vza, vaa = combine_detectors(tile.view_zenith["B04"], tile.view_azimuth["B04"])
    d_row, d_col = np.gradient(vza)  # rows run south, columns east
    downhill = np.degrees(np.arctan2(-d_col, d_row)) % 360.0  # (east, north) of -grad = (-d_col, +d_row)
    off_nadir = vza > 3.0  # the azimuth of a near-nadir view is ill-defined
    assert np.median(relative_azimuth(downhill, vaa)[off_nadir]) < 20.0
    assert np.median(relative_azimuth(downhill, (vaa + 180.0) % 360.0)[off_nadir]) > 160.0
    like = grid_template(Affine(2000.0, 0, 300000.0, 0, -2000.0, 8600020.0), (54, 54), "EPSG:32723")
    flipped = read_sentinel2_angles(MTD, like, band="B04", view_azimuth="from_sensor")
    direct = read_sentinel2_angles(MTD, like, band="B04")
    difference = relative_azimuth(flipped.vaa, direct.vaa)
    np.testing.assert_allclose(difference.values, 180.0, atol=1e-9)


def test_specular_direction_of_the_real_sun_is_phi_180(tile):
    saa = tile.sun_azimuth
    np.testing.assert_allclose(relative_azimuth(saa, (saa + 180.0) % 360.0), 180.0)
    # This morning overpass looks from the west-north-west of the sun: phi is far from both
    # hot spot and specular (sun azimuth 42-45 deg, view azimuth about 110 deg off nadir).
    _, vaa = combine_detectors(tile.view_zenith["B04"], tile.view_azimuth["B04"])
    off_nadir = combine_detectors(tile.view_zenith["B04"], tile.view_azimuth["B04"])[0] > 3.0
    phi = relative_azimuth(saa, vaa)[off_nadir]
    assert 30.0 < np.median(phi) < 90.0


def test_on_a_like_grid_and_via_the_dispatcher():
    like = grid_template(Affine(20.0, 0, 350000.0, 0, -20.0, 8550000.0), (64, 48), "EPSG:32723", chunks=32)
    angles = read_angles("sentinel2", MTD, like=like, band="B8A")
    assert angles.sza.shape == (64, 48) and angles.sza.data.npartitions == 4
    assert angles.attrs["view_bands"] == "B8A"
    full = read_sentinel2_angles(MTD, resolution=20, band="B8A", chunks=128)
    subset = full.sel(x=like.x, y=like.y)
    for name in ("sza", "saa", "vza", "vaa"):
        np.testing.assert_allclose(angles[name].values, subset[name].values, atol=1e-9)


def test_errors_name_band_and_element(tmp_path, text):
    with pytest.raises(SensorInputError, match="no viewing angle grids for band 'B13'"):
        read_sentinel2_angles(MTD, band="B13")
    with pytest.raises(SensorInputError, match="no image size/geoposition for resolution 30 m"):
        read_sentinel2_angles(MTD, resolution=30)
    start, end = text.index("<Sun_Angles_Grid>"), text.index("</Sun_Angles_Grid>") + len("</Sun_Angles_Grid>")
    broken = tmp_path / "MTD_TL.xml"
    broken.write_text(text[:start] + text[end:])
    with pytest.raises(SensorInputError, match=r"MTD_TL.xml: no <Sun_Angles_Grid> element"):
        read_sentinel2_angles(broken)
    truncated = tmp_path / "cut.xml"
    truncated.write_text(text[:5000])
    with pytest.raises(SensorInputError, match="cannot read the granule metadata"):
        parse_mtd_tl(truncated)


# A push-broom sensor at height H over a flat ground, its nadir line slightly inclined to north,
# looking a little forward: from ground point (x, y) the sensor lies at the horizontal offset
# (x0(y) - x, H tan(TILT)), so the view zenith is arctan(hypot(...) / H) and the view azimuth
# (clockwise from north, pixel to sensor) atan2(east, north): near the nadir line the azimuth
# turns from about 90 deg through north to 270 deg within a few hundred metres and the zenith has
# its minimum, TILT, there.
HEIGHT, TILT, CORNER = 786e3, 0.02, (300000.0, 5000040.0)


def _nadir_line_view(x, y):
    """Exact view zenith and azimuth [deg] of the geometry above at ground points (x, y) [m]."""
    x0 = CORNER[0] + 52500.0 + 0.1 * (y - (CORNER[1] - 55000.0))
    east, north = (x0 - x) / HEIGHT, np.full(np.shape(x), np.tan(np.radians(TILT)))
    return np.degrees(np.arctan(np.hypot(east, north))), np.degrees(np.arctan2(east, north)) % 360.0


def test_view_angles_across_the_nadir_line_match_the_closed_form_geometry(tmp_path):
    """The view grids (5 km nodes) of the closed-form geometry above, interpolated to 60 m pixels
    5 km either side of the nadir line, against the exact angles at the pixel centres: the view
    vector's components are linear in the ground position here, so interpolating them is exact
    up to the metadata's 4 decimals (here 5e-5 deg in zenith and direction, 0.08 deg in azimuth
    where the zenith is 0.02 deg). Zenith and azimuth interpolated apart were off by up to 0.16 deg
    in zenith (over 0.1 deg in a strip 2.5 km wide along the line), 99 deg in azimuth and 0.19 deg
    in direction over this window."""
    from brdfcorr.testing import write_mtd_tl

    nodes_y, nodes_x = np.meshgrid(CORNER[1] - 5000.0 * np.arange(23), CORNER[0] + 5000.0 * np.arange(23),
                                   indexing="ij")
    mtd = write_mtd_tl(tmp_path / "MTD_TL.xml", crs="EPSG:32632", corner=CORNER,
                       view=_nadir_line_view(nodes_x, nodes_y))
    transform = Affine(60.0, 0.0, CORNER[0] + 45000.0, 0.0, -60.0, CORNER[1] - 48000.0)
    like = grid_template(transform, (50, 250), "EPSG:32632", chunks=(50, 125))
    angles = read_sentinel2_angles(mtd, like, band="B04")
    assert isinstance(angles.vza.data, da.Array) and angles.vaa.dtype == np.float64
    assert angles.vza.attrs == {"units": "degree", "long_name": "view zenith angle"}
    x, y = np.meshgrid(like.x.values, like.y.values)
    vza, vaa = _nadir_line_view(x, y)
    assert vza.min() < 0.021 and np.ptp(vaa) > 170.0  # the window holds the nadir line
    np.testing.assert_allclose(angles.vza.values, vza, atol=1e-3)
    assert float(relative_azimuth(angles.vaa.values, vaa).max()) < 0.1
    # The view direction itself (the angle between the two unit vectors) within 0.001 deg.
    def direction(zenith, azimuth):
        z, a = np.radians(zenith), np.radians(azimuth)
        return np.stack([np.sin(z) * np.sin(a), np.sin(z) * np.cos(a), np.cos(z)])
    cosine = np.sum(direction(angles.vza.values, angles.vaa.values) * direction(vza, vaa), axis=0)
    assert np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))).max() < 1e-3
