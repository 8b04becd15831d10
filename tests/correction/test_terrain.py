"""Tests of brdfcorr.correction.terrain and of normalize's slope/aspect layers: closed forms of Horn's finite
differences, the local-frame rotation, the specular peak of a tilted roof, the new QA flag."""

from __future__ import annotations

from pathlib import Path

import dask
import dask.array as da
import numpy as np
import pytest
import rasterio
import rasterio.control
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from brdfcorr.correction import QA, normalize
from brdfcorr.correction.terrain import cos_incidence, local_angles, slope_aspect, slope_aspect_layers
from brdfcorr.errors import InputError
from brdfcorr.geometry import facet_inclination, relative_azimuth
from brdfcorr.io.sensors.envi import read_envi_obs_terrain
from brdfcorr.models import load_material, specular_peak, torrance_sparrow
from brdfcorr.params import ParameterTable
from brdfcorr.testing import example_table, georeference, synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")
REALDATA = Path(__file__).resolve().parents[1] / "data"  # real files and their licences (README.md there)


def _unit(zenith, azimuth):
    """East, north, up unit vector (independent of brdfcorr.correction.terrain: plain numpy radians)."""
    z, a = np.radians(zenith), np.radians(azimuth)
    return np.array([np.sin(z) * np.sin(a), np.sin(z) * np.cos(a), np.cos(z)])


def _angles(vector):
    east, north, up = vector
    return np.degrees(np.arccos(np.clip(up, -1, 1))), np.degrees(np.arctan2(east, north)) % 360


def _rotation(axis, angle):
    """Rotation matrix about a unit axis by angle [deg] (Rodrigues, written out as a matrix)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    t = np.radians(angle)
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K


# --- slope and aspect from a DEM (Horn 1981) ---------------------------------------------------

@pytest.mark.parametrize("east, north", [(0.3, 0.0), (0.0, -0.5), (-0.2, 0.4), (0.7, 0.7)])
def test_plane_has_its_slope_and_aspect_everywhere_including_the_edges(east, north):
    # Closed form: z = g_e * east + g_n * north has slope atan(|g|) and faces -g (downslope).
    dem = georeference(xr.DataArray(np.zeros((7, 9)), dims=("y", "x")))
    dem = dem + east * (dem["x"] - dem["x"][0]) + north * (dem["y"] - dem["y"][0])
    slope, aspect = slope_aspect(dem)
    expected_slope = np.degrees(np.arctan(np.hypot(east, north)))
    expected_aspect = np.degrees(np.arctan2(-east, -north)) % 360
    np.testing.assert_allclose(slope.values, expected_slope, rtol=0, atol=1e-10)
    np.testing.assert_allclose(aspect.values, expected_aspect, rtol=0, atol=1e-9)
    assert slope.attrs["units"] == "degree" and slope.rio.crs == dem.rio.crs


def test_quadratic_surface_gradient_is_exact_inside():
    # Central differences are exact for quadratics, and Horn's row weights average equal values:
    # z = a e^2 + b n^2 has gradient (2 a e, 2 b n) at the interior pixels.
    a, b, d = 0.01, -0.02, 2.0
    rows, cols = np.mgrid[0:9, 0:11].astype(float)
    e, n = cols * d, -rows * d
    slope, aspect = slope_aspect(a * e**2 + b * n**2, pixel_size=d)
    p, q = 2 * a * e, 2 * b * n
    inner = (slice(1, -1), slice(1, -1))
    np.testing.assert_allclose(slope.values[inner], np.degrees(np.arctan(np.hypot(p, q)))[inner], atol=1e-10)
    expected = np.degrees(np.arctan2(-p, -q)) % 360
    moving = np.hypot(p, q)[inner] > 0
    np.testing.assert_allclose(aspect.values[inner][moving], expected[inner][moving], atol=1e-9)


def test_quadratic_surface_gradient_is_one_sided_on_the_border():
    # docs/terrain.md: on the border the window extended by 2 z0 - z1 gives (z1 - z0) / dx, off by
    # a dx for z = a e^2 (first column +a dx, last column -a dx); likewise |b| |dy| on the first
    # and last rows. The same surface as above: up to 2.56 deg in slope, at the corner (0, 0).
    a, b, d = 0.01, -0.02, 2.0
    rows, cols = np.mgrid[0:9, 0:11].astype(float)
    e, n = cols * d, -rows * d
    slope, aspect = slope_aspect(a * e**2 + b * n**2, pixel_size=d)
    gradient = np.tan(np.radians(slope.values))
    p = -gradient * np.sin(np.radians(aspect.values)) - 2 * a * e  # error of the east gradient
    q = -gradient * np.cos(np.radians(aspect.values)) - 2 * b * n  # error of the north gradient
    np.testing.assert_allclose(p[:, 0], a * d, atol=1e-12)
    np.testing.assert_allclose(p[:, -1], -a * d, atol=1e-12)
    np.testing.assert_allclose(p[:, 1:-1], 0.0, atol=1e-12)
    np.testing.assert_allclose(q[0], abs(b) * d, atol=1e-12)
    np.testing.assert_allclose(q[-1], -abs(b) * d, atol=1e-12)
    np.testing.assert_allclose(q[1:-1], 0.0, atol=1e-12)
    error = np.abs(slope.values - np.degrees(np.arctan(np.hypot(2 * a * e, 2 * b * n))))
    assert error.max() == pytest.approx(2.56, abs=0.005) and error.argmax() == 0
    assert error[1:-1, 1:-1].max() < 1e-10


def test_dask_dem_stays_lazy_and_equals_numpy(no_compute):
    rng = np.random.default_rng(1)
    dem = rng.normal(size=(20, 24)).cumsum(axis=0)
    lazy = slope_aspect(da.from_array(dem, chunks=(7, 8)), pixel_size=(1.5, -1.5))
    assert isinstance(lazy.slope.data, da.Array) and lazy.slope.data.chunks == ((7, 7, 6), (8, 8, 8))
    eager = slope_aspect(dem, pixel_size=(1.5, -1.5))
    with dask.config.set(scheduler="sync"):
        np.testing.assert_array_equal(lazy.slope.values, eager.slope.values)
        np.testing.assert_array_equal(lazy.aspect.values, eager.aspect.values)


def _web_mercator_dem(rows: int, cols: int, pixel: float, gradient: float) -> xr.DataArray:
    """A DEM in EPSG:3857 whose upper left corner lies at 10 E, 52 N, rising ``gradient`` m per
    ground metre northwards; ground metres are map metres times cos(52 deg) (Mercator's scale
    1/cos(latitude), closed form), which holds to 1e-4 over a few hundred metres."""
    from pyproj import Transformer

    left, top = Transformer.from_crs("EPSG:4326", "EPSG:3857", always_xy=True).transform(10.0, 52.0)
    x, y = left + pixel * (np.arange(cols) + 0.5), top - pixel * (np.arange(rows) + 0.5)
    heights = np.broadcast_to(gradient * (y - y[-1])[:, None] * np.cos(np.radians(52.0)), (rows, cols))
    dem = xr.DataArray(heights.copy(), dims=("y", "x"), coords={"y": y, "x": x})
    return dem.rio.write_crs("EPSG:3857").rio.write_transform(dem.rio.transform(recalc=True))


def test_a_dem_in_web_mercator_has_ground_slopes():
    # Map metres of Web Mercator taken as ground metres made a 16.7 deg slope 10.5 deg at 52 N.
    slope, aspect = slope_aspect(_web_mercator_dem(7, 9, 10.0, 0.3))
    np.testing.assert_allclose(slope.values, np.degrees(np.arctan(0.3)), atol=0.01)
    np.testing.assert_allclose(aspect.values, 180.0, atol=1e-6)
    # Over 300 km the projection's scale varies by 7 %: no one pixel size serves it.
    with pytest.raises(InputError, match=r"DEM: the scale of its projection \(WGS 84 / Pseudo-Mercator\) varies by"):
        slope_aspect(_web_mercator_dem(30, 4, 10000.0, 0.0))


def test_a_dem_in_a_sinusoidal_grid_has_ground_slopes_along_its_curved_meridians():
    # MODIS sinusoidal on a sphere: x = R lon cos(lat), y = R lat. A step dy along the grid (x
    # fixed) changes both latitude and longitude; its ground length is dy sqrt(1 + (lon sin lat)^2)
    # (closed form: 1.2054 at 60 E, 40 N), which the parallel/meridional scale factors (1 and 1 here
    # along x and y for a meridian) do not give: they made a 4.74 deg slope 6.87 deg.
    radius, lon, lat = 6371007.181, np.radians(60.0), np.radians(40.0)
    x0, y0 = radius * lon * np.cos(lat), radius * lat
    y = y0 - 100.0 * (np.arange(7) + 0.5)
    x = x0 + 100.0 * (np.arange(9) + 0.5)
    dem = xr.DataArray(np.broadcast_to(0.1 * (y - y[-1])[:, None], (7, 9)).copy(), dims=("y", "x"),
                       coords={"y": y, "x": x})
    dem = dem.rio.write_crs("+proj=sinu +lon_0=0 +R=6371007.181 +units=m +no_defs")
    dem = dem.rio.write_transform(dem.rio.transform(recalc=True))
    ground_per_map = np.sqrt(1.0 + (lon * np.sin(lat)) ** 2)
    np.testing.assert_allclose(slope_aspect(dem).slope.values, np.degrees(np.arctan(0.1 / ground_per_map)),
                               atol=0.01)


def test_a_dem_in_a_local_crs_is_taken_in_its_metres():
    # A local (engineering) CRS has no geodetic CRS to measure a scale by: its metres are ground metres
    # (the scale check raised pyproj's CRSError on it).
    local = 'LOCAL_CS["site grid",LOCAL_DATUM["site",0],UNIT["metre",1],AXIS["X",EAST],AXIS["Y",NORTH]]'
    dem = georeference(xr.DataArray(np.zeros((7, 9)), dims=("y", "x")))
    dem = (dem + 0.1 * (dem["y"] - dem["y"][-1])).rio.write_crs(local)
    np.testing.assert_allclose(slope_aspect(dem).slope.values, np.degrees(np.arctan(0.1)), atol=1e-9)


def test_a_pixel_without_an_elevation_has_no_slope():
    # Horn's window leaves out its centre: a void inside the DEM had its neighbours' slope (and
    # was corrected with QA 0), while the documentation says NaN spreads to the 3 x 3 around it.
    rows, cols = np.mgrid[0:7, 0:9].astype(float)
    dem = 0.3 * cols
    dem[3, 4] = np.nan
    slope, aspect = slope_aspect(dem, pixel_size=1.0)
    assert np.isnan(slope.values[2:5, 3:6]).all() and np.isnan(aspect.values[3, 4])
    assert np.isfinite(slope.values).sum() == 7 * 9 - 9


def test_south_up_grid_gives_the_same_orientation():
    # The same terrain stored with rows going north (positive dy) must give the same slope/aspect.
    rows, cols = np.mgrid[0:6, 0:6].astype(float)
    north_up = 0.4 * cols - 0.1 * (-rows)  # rows go south
    south_up = north_up[::-1]
    a = slope_aspect(north_up, pixel_size=(1.0, -1.0))
    b = slope_aspect(south_up, pixel_size=(1.0, 1.0))
    np.testing.assert_allclose(a.aspect.values, b.aspect.values[::-1], atol=1e-12)


def test_dem_errors():
    with pytest.raises(InputError, match="no CRS"):
        slope_aspect(xr.DataArray(np.zeros((4, 4)), dims=("y", "x")))
    geographic = georeference(xr.DataArray(np.zeros((4, 4)), dims=("y", "x")), crs="EPSG:4326")
    with pytest.raises(InputError, match="geographic"):
        slope_aspect(geographic)
    # Ground control points and no geotransform: rioxarray's identity transform (a pixel of 1 m by
    # +1 m) would make the slope 10 times too steep (tangent) on 10 m pixels and mirror the aspect.
    gcps = [rasterio.control.GroundControlPoint(row, col, 500000.0 + 10 * col, 5400000.0 - 10 * row)
            for row, col in ((0, 0), (0, 4), (4, 0), (4, 4))]
    controlled = xr.DataArray(np.arange(16.0).reshape(4, 4), dims=("y", "x")).rio.write_gcps(gcps, "EPSG:32632")
    with pytest.raises(InputError, match=r"^DEM is georeferenced by ground control points, not a geotransform"):
        slope_aspect(controlled)
    assert np.isfinite(slope_aspect(controlled, pixel_size=10.0).slope.values).all()
    with pytest.raises(InputError, match="too small"):
        slope_aspect(np.zeros((1, 5)), pixel_size=1.0)
    with pytest.raises(InputError, match="2-D"):
        slope_aspect(np.zeros((2, 3, 3)), pixel_size=1.0)


def test_slope_aspect_layers_by_name_and_by_order():
    data = np.stack([np.full((2, 2), 200.0), np.full((2, 2), 30.0)])
    named = xr.DataArray(data, dims=("band", "y", "x"), attrs={"long_name": ("Aspect", "Slope")})
    slope, aspect = slope_aspect_layers(named)
    assert float(slope[0, 0]) == 30.0 and float(aspect[0, 0]) == 200.0
    slope, aspect = slope_aspect_layers(xr.DataArray(data[::-1], dims=("band", "y", "x")))
    assert float(slope[0, 0]) == 30.0 and float(aspect[0, 0]) == 200.0
    with pytest.raises(InputError, match="once"):
        slope_aspect_layers(named.assign_attrs(long_name=("slope", "slope 2")))
    with pytest.raises(InputError, match="2 bands"):
        slope_aspect_layers(named[:1])


# --- the local frame ------------------------------------------------------------------------------

def test_horizontal_surface_returns_the_angles_unchanged():
    rng = np.random.default_rng(2)
    sza, saa, vza, vaa = rng.uniform(0, 89, 50), rng.uniform(0, 360, 50), rng.uniform(0, 89, 50), rng.uniform(0, 360, 50)
    local = local_angles(sza, saa, vza, vaa, np.zeros(50), rng.uniform(0, 360, 50))
    for got, given_ in zip(local, (sza, saa, vza, vaa)):
        np.testing.assert_array_equal(got, given_)


@settings(max_examples=60, deadline=None)
@given(st.floats(0, 85), st.floats(0, 360), st.floats(0, 85), st.floats(0, 360), st.floats(0, 60), st.floats(0, 360))
def test_local_sun_zenith_is_the_incidence_angle(sza, saa, vza, vaa, slope, aspect):
    # Teillet et al. 1982, eq. 1; and the local zeniths are the angles from the normal (dot products).
    local = local_angles(sza, saa, vza, vaa, slope, aspect)
    normal = _unit(slope, aspect)
    np.testing.assert_allclose(np.cos(np.radians(local.sza)), cos_incidence(sza, saa, slope, aspect), atol=1e-12)
    np.testing.assert_allclose(np.cos(np.radians(local.vza)), normal @ _unit(vza, vaa), atol=1e-12)
    # The angle between sun and view (the phase angle) is a property of the directions alone.
    phase = np.degrees(np.arccos(np.clip(_unit(sza, saa) @ _unit(vza, vaa), -1, 1)))
    local_phase = np.degrees(np.arccos(np.clip(_unit(local.sza, local.saa) @ _unit(local.vza, local.vaa), -1, 1)))
    np.testing.assert_allclose(local_phase, phase, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(st.floats(0, 80), st.floats(0, 80), st.floats(0, 180), st.floats(0, 60), st.floats(0, 360),
       st.floats(0, 360))
def test_rotating_scene_and_surface_together_leaves_the_brdf_unchanged(ti, tr, phi, tilt, tilt_axis, spin):
    # A horizontal surface seen at (ti, tr, phi) [sun azimuth `spin`], rotated as a whole -- sun,
    # sensor and surface -- about a horizontal axis by `tilt`: the surface's frame angles are those
    # of the horizontal geometry, so every BRDF of them is unchanged (here roof-tile TS).
    rotation = _rotation([np.sin(np.radians(tilt_axis)), np.cos(np.radians(tilt_axis)), 0.0], tilt)
    sun, view, normal = (rotation @ v for v in (_unit(ti, spin), _unit(tr, spin + phi), np.array([0.0, 0.0, 1.0])))
    (sza, saa), (vza, vaa), (slope, aspect) = _angles(sun), _angles(view), _angles(normal)
    local = local_angles(sza, saa, vza, vaa, slope, aspect)
    np.testing.assert_allclose([local.sza, local.vza], [ti, tr], atol=1e-6)
    if 1e-3 < ti and 1e-3 < tr:  # the relative azimuth is undefined at a zenith of 0
        np.testing.assert_allclose(relative_azimuth(local.saa, local.vaa), phi, atol=1e-5)
    tile = load_material("roof_tile").params
    np.testing.assert_allclose(torrance_sparrow(local.sza, local.vza, relative_azimuth(local.saa, local.vaa), **tile),
                               torrance_sparrow(ti, tr, phi, **tile), rtol=1e-6)


@pytest.mark.parametrize("sza", [30.0, 50.0, 70.0])
def test_roof_tilted_towards_the_sun_by_the_half_angle_has_its_peak_at_nadir(sza):
    # The specular direction of a roof whose normal is the half vector of sun and nadir view is
    # the nadir: slope = sza / 2, aspect = saa. Its local geometry at nadir is (sza/2, sza/2, 180).
    saa = 160.0
    local = local_angles(sza, saa, 0.0, 0.0, sza / 2, saa)
    np.testing.assert_allclose([local.sza, local.vza, relative_azimuth(local.saa, local.vaa)],
                               [sza / 2, sza / 2, 180.0], atol=1e-9)
    # Along the principal plane (view towards or away from the sun) the facet inclination of the
    # specular reflection (paper 003 eq. 3) is 0 at nadir: the peak of every specular model is
    # there. A sharp peak (paper 000 eq. 3, sigma = 2 deg) has its maximum there (0.1 deg steps).
    signed = np.linspace(-80, 80, 1601)
    vza, vaa = np.abs(signed), np.where(signed < 0, saa + 180, saa)
    local = local_angles(sza, saa, vza, vaa, sza / 2, saa)
    visible = local.vza < 90  # beyond, the sensor is behind the roof
    signed, local = signed[visible], [a[visible] for a in local]
    local_phi = relative_azimuth(local[1], local[3])
    alpha = facet_inclination(local[0], local[2], local_phi)
    assert signed[np.argmin(alpha)] == 0.0 and alpha[np.argmin(alpha)] < 1e-9
    assert signed[np.argmax(specular_peak(local[0], local[2], local_phi, sigma=2.0))] == pytest.approx(0.0, abs=0.1)
    signed = np.linspace(-80, 80, 1601)
    # The horizontal roof's peak is at the mirror angle, on the forward side, not at nadir.
    flat = specular_peak(sza, vza, relative_azimuth(saa, vaa), sigma=2.0)
    assert signed[np.argmax(flat)] == pytest.approx(-sza, abs=0.1)


def test_local_angles_of_xarray_keep_dims_and_dask_stays_lazy(no_compute):
    sza = xr.DataArray(da.full((4, 5), 40.0, chunks=2), dims=("y", "x"))
    local = local_angles(sza, 180.0, 10.0, 90.0, 20.0, 180.0)
    assert local.sza.dims == ("y", "x") and isinstance(local.sza.data, da.Array)
    assert local.sza.name == "local_sza" and local.sza.attrs["units"] == "degree"


# --- normalize with slope and aspect ----------------------------------------------------------

@pytest.fixture(scope="module")
def scene():
    return synthetic_scene(ny=12, nx=16, dtype=np.float64)


def _normalize(scene, slope=None, aspect=None, **options):
    angles = {a: scene[a] for a in ANGLES}
    angles.update({k: v for k, v in (("slope", slope), ("aspect", aspect)) if v is not None})
    return normalize(scene["reflectance"], scene["classes"], angles, example_table(), **options)


@pytest.mark.parametrize("lazy", [False, True])
def test_slope_zero_is_bit_identical_to_no_slope(scene, lazy):
    zeros = xr.zeros_like(scene["sza"])
    aspect = xr.full_like(scene["sza"], 123.0)
    if lazy:
        scene = {k: v.chunk({"y": 5, "x": 7}) for k, v in scene.items()}
        zeros, aspect = zeros.chunk({"y": 5, "x": 7}), aspect.chunk({"y": 5, "x": 7})
    for reference in ({"sza": "observed"}, {"sza": "mean", "vza": 10.0, "raa": 60.0}):
        plain = _normalize(scene, reference=reference)
        tilted = _normalize(scene, reference=reference, slope=zeros, aspect=aspect)
        np.testing.assert_array_equal(tilted.reflectance.values, plain.reflectance.values)
        np.testing.assert_array_equal(tilted.qa.values, plain.qa.values)


def test_tilted_roof_is_normalized_to_the_horizontal_roof(scene):
    # Closed form: a roof of slope 25 facing 200 deg rendered with f in its own frame; normalized,
    # it is f(reference) of a horizontal roof: brightness * f_h(sza, 0, 0).
    tile = load_material("roof_tile").params
    table = ParameterTable(classes=[{"id": 1, "name": "roof_tile", "model": "torrance_sparrow", "params": tile}])
    slope, aspect = xr.full_like(scene["sza"], 25.0), xr.full_like(scene["sza"], 200.0)
    local = local_angles(*(scene[a] for a in ANGLES), slope, aspect)
    classes = xr.full_like(scene["classes"], 1)
    observed = scene["brightness"] * torrance_sparrow(local.sza, local.vza, relative_azimuth(local.saa, local.vaa), **tile)
    cube = observed.expand_dims(band=[1]).transpose("band", "y", "x")
    result = normalize(cube, classes, {**{a: scene[a] for a in ANGLES}, "slope": slope, "aspect": aspect}, table,
                       limits=None)
    expected = scene["brightness"] * torrance_sparrow(scene["sza"], 0.0, 0.0, **tile)
    valid = result.qa.values == 0
    assert valid.mean() > 0.9
    np.testing.assert_allclose(result.reflectance.values[0][valid], expected.values[valid], rtol=1e-5)


def test_surface_facing_away_is_flagged_and_nodata(scene):
    # A 70 deg slope facing away from the sun (saa 150 -> aspect 330) under a sun at 30-40 deg:
    # cos i = cos sza cos 70 - sin sza sin 70 < 0, the sun is behind it.
    slope = xr.full_like(scene["sza"], 70.0)
    aspect = xr.full_like(scene["sza"], 330.0)
    slope[0, 0], slope[0, 1], aspect[0, 2] = 0.0, 95.0, np.nan
    result = _normalize(scene, slope=slope, aspect=aspect)
    qa = result.qa.values
    assert QA.FACING_AWAY == 32 and "facing_away" in result.qa.attrs["flag_meanings"].split()
    assert (qa[1:] & QA.FACING_AWAY).all() and np.isnan(result.reflectance.values[:, 1:]).all()
    assert not qa[0, 0] & QA.FACING_AWAY
    assert qa[0, 1] & QA.INVALID_GEOMETRY and qa[0, 2] & QA.NODATA
    assert "facing_away" in result.qa.attrs["flag_meanings"].split()


def test_slope_without_aspect_is_an_error(scene):
    with pytest.raises(InputError, match="both or neither"):
        _normalize(scene, slope=xr.zeros_like(scene["sza"]))


# --- the obs_ort reader -------------------------------------------------------------------------

@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_obs_slope_aspect_reproduce_the_obs_cosine_i():
    # The obs file's own "Cosine(i)" band is Teillet's cos i of its slope, aspect and sun angles.
    path = REALDATA / "isofit_avirisng_profiling_cube" / "ang20170323t202244_obs_7000-7010"
    terrain = read_envi_obs_terrain(path)
    with rasterio.open(path) as source:
        bands = source.read().astype(float)
        names = source.descriptions
    sun_zenith, sun_azimuth, cosine_i = (bands[names.index(n)] for n in (
        "To-sun zenith (0 to 90 degrees from zenith)", "To-sun azimuth (0 to 360 degrees cw from N)", "Cosine(i)"))
    assert terrain.slope.attrs["source_band"] == "Slope" and terrain.aspect.attrs["source_band"] == "Aspect"
    np.testing.assert_allclose(cos_incidence(sun_zenith, sun_azimuth, terrain.slope.values, terrain.aspect.values),
                               cosine_i, atol=1e-9)


def _obs_bands(path):
    with rasterio.open(path) as source:
        bands = source.read().astype(float)
        names = source.descriptions
    return {key: bands[names.index(name)] for key, name in (
        ("sza", "To-sun zenith (0 to 90 degrees from zenith)"), ("saa", "To-sun azimuth (0 to 360 degrees cw from N)"),
        ("slope", "Slope"), ("aspect", "Aspect"), ("cosine_i", "Cosine(i)"))}


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_what_the_obs_cosine_i_checks_and_what_it_does_not():
    # docs/terrain.md: the profiling cube's match (previous test) is with placeholder Slope 90 and
    # Aspect 0, which cannot tell A from -A; on the topoflux file no aspect convention reproduces
    # Cosine(i) (0.774 off as stored, 0.69-0.73 under the others), and the file contradicts itself:
    # Cosine(i) > cos(sza - slope), the largest cos i of its slope, in 274 of its 750 pixels.
    cube = _obs_bands(REALDATA / "isofit_avirisng_profiling_cube" / "ang20170323t202244_obs_7000-7010")
    np.testing.assert_allclose(cube["slope"], 90.0, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(cube["aspect"], 0.0)
    np.testing.assert_allclose(cos_incidence(cube["sza"], cube["saa"], cube["slope"], -cube["aspect"]), cube["cosine_i"],
                               atol=1e-9)
    obs = _obs_bands(REALDATA / "isofit_avirisng_topoflux" / "ang20160910t185702_obs_ortdem_mod")
    a = obs["aspect"]
    off = {name: np.max(np.abs(cos_incidence(obs["sza"], obs["saa"], obs["slope"], aspect) - obs["cosine_i"]))
           for name, aspect in (("A", a), ("A+180", a + 180), ("-A", -a), ("90-A", 90 - a), ("A+90", a + 90),
                                ("A-90", a - 90))}
    assert off.pop("A") == pytest.approx(0.774, abs=5e-4)
    assert all(0.68 < value < 0.74 for value in off.values()), off
    excess = obs["cosine_i"] - np.cos(np.radians(obs["sza"] - obs["slope"]))
    assert excess.size == 750 and (excess > 0).sum() == 274
    assert excess.max() == pytest.approx(0.12, abs=0.005)


def test_obs_terrain_band_names_can_be_overridden_and_are_checked():
    path = REALDATA / "isofit_avirisng_topoflux" / "ang20160910t185702_obs_ortdem_mod"
    from brdfcorr.errors import SensorInputError

    with pytest.raises(SensorInputError, match="no obs band for slope"):
        read_envi_obs_terrain(path, band_names={"slope": "gradient"})
    with pytest.raises(SensorInputError, match="unknown layer"):
        read_envi_obs_terrain(path, band_names={"tilt": "slope"})
    terrain = read_envi_obs_terrain(path)
    assert terrain.slope.shape == (25, 30) and float(terrain.slope.max()) < 90


def test_a_dem_stored_with_a_scale_is_read_in_its_units(tmp_path):
    # An east-facing plane, 0.2 m of rise per m (11.31 deg), stored as uint16 decimetres with a GDAL
    # scale of 0.1 beside the same plane in float32 metres: both give the same slope.
    from affine import Affine

    from brdfcorr.io.opening import open_layer

    rows, columns = np.indices((20, 30))
    metres = 100.0 + 0.2 * 10.0 * columns  # 10-m pixels, rising eastwards
    profile = dict(driver="GTiff", height=20, width=30, count=1, crs="EPSG:32632",
                   transform=Affine(10.0, 0.0, 500_000.0, 0.0, -10.0, 5_400_000.0))
    with rasterio.open(tmp_path / "dem_dm.tif", "w", dtype="uint16", **profile) as dataset:
        dataset.write(np.round(metres * 10).astype(np.uint16), 1)
        dataset.scales = (0.1,)
    surface = slope_aspect(open_layer(tmp_path / "dem_dm.tif", "DEM")[0])
    np.testing.assert_allclose(surface.slope.values, np.degrees(np.arctan(0.2)), atol=1e-4)
    np.testing.assert_allclose(surface.aspect.values, 270.0, atol=1e-4)  # facing west: downhill is west
