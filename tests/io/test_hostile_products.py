"""Hostile products and clusters that do not answer (issue 26, items 8-10 and 12-14): each case ends
in exit code 2, exactly one stderr line ``brdfcorr: error: ...`` naming the cause, no file in the
output directory and inputs byte-identical.

- scheduler addresses (``--scheduler``, ``DASK_SCHEDULER_ADDRESS``, ``engine.address``): no
  address at all, a port where a silent TCP server or an HTTP server listens (both hung past
  200 s), a scheduler without workers (waited forever);
- NEON AOP HDF5 and EMIT NetCDF metadata that leaves nothing to correct, or would be silently
  wrong: a NaN or infinite ``Scale_Factor``, a NaN sun zenith in the logs, a NaN
  ``Data_Ignore_Value`` (the fill became reflectance -1), view rasters in radians, attributes of
  the wrong type, items declared with 2e9 entries (MemoryError), a string or NaN geotransform, a
  fractional or NaN GLT, a GLT declared 60000 x 60000, an obs granule with another GLT;
- angle, slope and aspect layers with no finite value (all NaN, all inf), complex rasters (and
  arrays given to ``normalize``), a NaN geotransform, an all-NaN band in ``fit-classes``.

The fixtures write small files in the layouts of NEON's DP1.30006.001 HDF5 and EMIT's V001 NetCDF
(as tests/io/sensors/test_sensors_neon.py and tests/io/sensors/test_sensors_emit.py do; brdfcorr/io/sensors/neon.py and
emit.py name the items).
"""

from __future__ import annotations

import http.server
import re
import socket
import threading
from pathlib import Path

import distributed
import h5netcdf  # noqa: F401  (the "hdf5" extra: a test dependency)
import h5py
import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine

from brdfcorr.io import cluster
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable
from brdfcorr.testing import example_table, synthetic_scene

NY, NX = 16, 16


@pytest.fixture(scope="module")
def template(tmp_path_factory, write_example_scene) -> Path:
    return write_example_scene(tmp_path_factory.mktemp("hostile_products") / "scene",
                               synthetic_scene(ny=NY, nx=NX))["dir"]


# refused(scene, args, pattern, env=None) and correct_args(scene, ...): tests/conftest.py.
# ----------------------------------------------------------------------- 12, 13. schedulers
@pytest.fixture
def short_timeouts(monkeypatch):
    """Seconds, not the library's 10 and 60: the cases below must fail, the sooner the better."""
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 1.0)
    monkeypatch.setattr(cluster, "WORKER_TIMEOUT", 1.0)


@pytest.fixture
def silent_server():
    """A TCP server on 127.0.0.1 that accepts connections and never says a word."""
    server = socket.create_server(("127.0.0.1", 0))
    accepted: list[socket.socket] = []
    stop = threading.Event()

    def serve():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join()
    for connection in accepted:
        connection.close()
    server.close()


class _QuietHandler(http.server.BaseHTTPRequestHandler):
    def log_message(self, *args):  # the server's request log is no stderr line of ours
        pass


@pytest.fixture
def http_server():
    """An HTTP server on 127.0.0.1 (it answers dask's handshake with HTTP 400)."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _QuietHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.mark.parametrize("address, pattern", [
    ("notanaddress", r"--scheduler: 'notanaddress' is no dask scheduler address"),
    ("tcp://[::1", r"--scheduler: 'tcp://\[::1' is no dask scheduler address"),
])
def test_scheduler_address_that_is_none(scene, short_timeouts, address, pattern, refused, correct_args):
    refused(scene, correct_args(scene, "--scheduler", address), pattern)


def test_garbage_dask_scheduler_address_variable(scene, short_timeouts, refused, correct_args):
    refused(scene, correct_args(scene), r"--scheduler: '\?\?garbage\?\?' is no dask scheduler address",
            env={"DASK_SCHEDULER_ADDRESS": "??garbage??"})


@pytest.mark.parametrize("server", ["silent_server", "http_server"])
def test_scheduler_port_where_no_scheduler_listens(scene, short_timeouts, server, request, refused, correct_args):
    address = request.getfixturevalue(server)
    refused(scene, correct_args(scene, "--scheduler", address),
            rf"--scheduler: cannot reach the dask scheduler at {re.escape(address)}: "
            r"(no answer within 1 s|something answers there, but not as a dask scheduler)")


def test_scheduler_without_workers(scene, short_timeouts, refused, correct_args):
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as local:
        address = local.scheduler_address
        refused(scene, correct_args(scene, "--scheduler", address),
                rf"--scheduler: the dask scheduler at {re.escape(address)} has no workers \(none joined within 1 s\)")


def test_chain_engine_address_of_a_silent_server(tmp_path, short_timeouts, silent_server):
    from brdfcorr.errors import InputError

    with pytest.raises(InputError, match=rf"engine.address: cannot reach the dask scheduler at {silent_server}"):
        with cluster.connect_cluster(silent_server, setting="engine.address"):
            pass


# --------------------------------------------------------------- 8, 10, 13, 14. NEON AOP HDF5

NEON_ROWS, NEON_COLS = 7, 9
NEON_TRANSFORM = Affine(1.0, 0.0, 368000.0, 0.0, -1.0, 4307000.0)
MAP_INFO = "UTM, 1.000, 1.000, 368000.00, 4307000.00, 1.0, 1.0, 18, North, WGS-84, units=Meters, rotation=0.000"
NEON_FILL = -9999


def _neon_cube() -> np.ndarray:
    """(rows, columns, bands) int16 as NEON stores it (reflectance x 10000), two filled pixels."""
    cube = np.random.default_rng(1).integers(200, 6000, size=(NEON_ROWS, NEON_COLS, 4)).astype("int16")
    cube[0, 0, :] = NEON_FILL
    cube[3, 5, :] = NEON_FILL
    return cube


def _neon_view() -> tuple[np.ndarray, np.ndarray]:
    """to-sensor zenith and azimuth [deg]: 0-10 deg across the line, the sensor towards 95 deg
    left of the middle column and 275 deg right of it."""
    columns = np.arange(NEON_COLS) - (NEON_COLS - 1) / 2
    vza = np.broadcast_to(np.abs(columns) * 2.5, (NEON_ROWS, NEON_COLS)).astype("float32").copy()
    vaa = np.where(columns < 0, 95.0, 275.0)[None, :].repeat(NEON_ROWS, 0).astype("float32")
    return vza, vaa


def _write_neon(path: Path, edit=None) -> Path:
    """A reflectance file in NEON's DP1.30006.001 layout; ``edit(group)`` then damages
    ``/SERC/Reflectance`` in place."""
    vza, vaa = _neon_view()
    with h5py.File(path, "w") as h5file:
        group = h5file.create_group("SERC/Reflectance")
        data = group.create_dataset("Reflectance_Data", data=_neon_cube(), chunks=(4, 4, 4))
        data.attrs.update({"Scale_Factor": 10000.0, "Data_Ignore_Value": float(NEON_FILL)})
        metadata = group.create_group("Metadata")
        metadata.create_dataset("Spectral_Data/Wavelength", data=[381.6, 561.2, 851.7, 1601.4]).attrs["Units"] = \
            "nanometers"
        metadata.create_dataset("Spectral_Data/FWHM", data=[5.1, 5.3, 5.5, 6.0])
        metadata.create_dataset("Coordinate_System/Map_Info", data=MAP_INFO.encode())
        metadata.create_dataset("Coordinate_System/EPSG Code", data=b"32618")
        for name, values in (("to-sensor_Zenith_Angle", vza), ("to-sensor_Azimuth_Angle", vaa)):
            metadata.create_dataset(name, data=values).attrs["Data_Ignore_Value"] = float(NEON_FILL)
        metadata.create_dataset("Logs/162512/Solar_Zenith_Angle", data=34.5)
        metadata.create_dataset("Logs/162512/Solar_Azimuth_Angle", data=151.25)
        if edit is not None:
            edit(group)
    return path


def _classes(path: Path, transform: Affine, shape: tuple[int, int], crs: str) -> Path:
    """Class 1 everywhere on the given grid."""
    with rasterio.open(path, "w", driver="GTiff", width=shape[1], height=shape[0], count=1, dtype="uint8",
                       nodata=255, crs=crs, transform=transform) as target:
        target.write(np.ones((1, *shape), "uint8"))
    return path


def _product_scene(tmp_path: Path, transform: Affine, shape: tuple[int, int], crs: str) -> dict[str, Path]:
    directory = tmp_path / "scene"
    directory.mkdir()
    (tmp_path / "out").mkdir()
    tile = load_material("roof_tile")
    ParameterTable(classes=[{"id": 1, "name": "roof_tile", "model": "torrance_sparrow",
                             "params": tile.params}]).save(directory / "params.yaml")
    return {"dir": directory, "classes": _classes(directory / "classes.tif", transform, shape, crs),
            "params": directory / "params.yaml", "out": tmp_path / "out", "output": tmp_path / "out" / "corrected.tif"}


@pytest.fixture
def neon(tmp_path):
    """``neon(edit)``: a NEON scene whose file ``edit`` damaged, and the command that corrects it."""
    scene = _product_scene(tmp_path, NEON_TRANSFORM, (NEON_ROWS, NEON_COLS), "EPSG:32618")

    def make(edit=None, name="NEON_D02_SERC_DP1_20210801_162512_reflectance.h5"):
        path = _write_neon(scene["dir"] / name, edit)
        args = ["correct", path, "--angles", path, "--angles-kind", "neon", "--classes", scene["classes"],
                "--params", scene["params"], "-o", scene["output"], "--no-limits", "--no-progress"]
        return scene, args

    return make


def _set_attr(dataset: str, name: str, value):
    def edit(group):
        group[dataset].attrs[name] = value
    return edit


def _replace(name: str, **create):
    """Replace the dataset ``name`` of the group (``create``: h5py's create_dataset arguments)."""
    def edit(group):
        del group[name]
        group.create_dataset(name, **create)
    return edit


@pytest.mark.parametrize("edit, pattern", [
    pytest.param(_set_attr("Reflectance_Data", "Scale_Factor", np.nan),
                 r"Reflectance_Data Scale_Factor nan must be a finite number > 0", id="scale-factor-nan"),
    pytest.param(_set_attr("Reflectance_Data", "Scale_Factor", np.inf),
                 r"Reflectance_Data Scale_Factor inf must be a finite number > 0", id="scale-factor-inf"),
    pytest.param(_set_attr("Reflectance_Data", "Scale_Factor", "ten thousand"),
                 r"Reflectance_Data Scale_Factor: 'ten thousand' is no number", id="scale-factor-text"),
    pytest.param(_set_attr("Reflectance_Data", "Data_Ignore_Value", [1.0, 2.0]),
                 r"Reflectance_Data Data_Ignore_Value: 2 values \(2,\) where one number is expected",
                 id="ignore-value-array"),
    pytest.param(_replace("Metadata/Logs/162512/Solar_Zenith_Angle", data=np.nan),
                 r"Metadata/Logs/162512: Solar_Zenith_Angle nan; the sun angles must be finite", id="sun-zenith-nan"),
    pytest.param(_replace("Metadata/Logs/162512/Solar_Azimuth_Angle", data=b"south"),
                 r"Logs/162512/Solar_Azimuth_Angle: 'south' is no number", id="sun-azimuth-text"),
    pytest.param(_replace("Metadata/Spectral_Data/Wavelength", shape=(2_000_000_000,), dtype="f8", chunks=(4096,)),
                 r"Metadata/Spectral_Data/Wavelength declares 2000000000 entries", id="wavelength-2e9"),
    pytest.param(_replace("Metadata/Spectral_Data/Wavelength", data=np.array([b"blue", b"green", b"red", b"nir"])),
                 r"Metadata/Spectral_Data/Wavelength holds \|S5 values; real numbers are expected", id="wavelength-text"),
    pytest.param(_replace("Metadata/Logs/162512/Solar_Zenith_Angle", shape=(2_000_000_000,), dtype="f8",
                          chunks=(4096,)),
                 r"Logs/162512/Solar_Zenith_Angle declares 2000000000 entries", id="sun-zenith-2e9"),
    pytest.param(_replace("Metadata/Coordinate_System/Map_Info", data=MAP_INFO.replace("368000.00", "nan").encode()),
                 r"Map_Info .*: the geotransform \(.*nan.*\) holds non-finite values", id="map-info-nan"),
    pytest.param(_replace("Reflectance_Data", data=_neon_cube().astype("complex64")),
                 r"Reflectance_Data holds complex64 values; real numbers are expected", id="complex-cube"),
    pytest.param(lambda group: [_replace(name, data=np.radians(values))(group) for name, values in
                                zip(("Metadata/to-sensor_Zenith_Angle", "Metadata/to-sensor_Azimuth_Angle"),
                                    _neon_view())],
                 r"the view angle rasters look like radians \(to-sensor_Zenith_Angle up to 0\.175, "
                 r"to-sensor_Azimuth_Angle up to 4\.8\); brdfcorr needs degrees", id="view-radians"),
    pytest.param(_replace("Metadata/to-sensor_Zenith_Angle", data=np.full((NEON_ROWS, NEON_COLS), np.inf, "f4")),
                 r"reflectance\.h5 \(neon\): no finite vza value \(all NaN, inf or nodata\): nothing could be corrected",
                 id="view-zenith-all-inf"),
])
def test_neon_metadata_that_leaves_nothing_or_a_wrong_number(neon, edit, pattern, refused):
    scene, args = neon(edit)
    refused(scene, args, pattern)


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_neon_ignore_value_that_is_no_number_falls_back_to_neons_fill(neon, value, invoke):
    """NEON documents -9999 as its fill: with a NaN (or inf) Data_Ignore_Value the stored -9999
    pixels are still nodata (they were reflectance -1), the output equal to that of the file as
    NEON writes it."""
    scene, args = neon()
    assert invoke(args)[0] == 0
    with rasterio.open(scene["output"]) as output:
        expected = output.read()
    scene["output"].unlink()
    _, args = neon(_set_attr("Reflectance_Data", "Data_Ignore_Value", value), name="ignore_nan.h5")
    code, stderr = invoke(args)
    assert code == 0, stderr
    with rasterio.open(scene["output"]) as output:
        corrected = output.read()
    cube = _neon_cube()
    assert np.isnan(corrected[:, cube[..., 0] == NEON_FILL]).all()
    assert np.isfinite(corrected[:, cube[..., 0] != NEON_FILL]).all()
    np.testing.assert_array_equal(corrected, expected)


def test_truncated_neon_file_is_one_line_without_hdf5_diagnostics(neon, refused):
    """GDAL's HDF5 library printed 22 lines of HDF5-DIAG per attempt before the error."""
    scene, args = neon()
    path = Path(args[1])
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    refused(scene, args, r"cannot read image file \S+reflectance\.h5: an HDF5 file that HDF5 cannot open "
                        r"\(.*truncated.*\)")


# --------------------------------------------------------------------- 8, 9, 13, 14. EMIT NetCDF
DOWNTRACK, CROSSTRACK = 8, 6
ORTHO_Y, ORTHO_X = 9, 11
EMIT_FILL = -9999.0
GEOTRANSFORM = [-116.2, 0.000542232520256, 0.0, 36.4, 0.0, -0.000542232520256]
OBS_BANDS = ["Path length (sensor-to-ground in meters)", "To-sensor azimuth (0 to 360 degrees CW from N)",
             "To-sensor zenith (0 to 90 degrees from zenith)", "To-sun azimuth (0 to 360 degrees CW from N)",
             "To-sun zenith (0 to 90 degrees from zenith)"]


def _glt(seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Every swath pixel placed once at a shuffled cell of the ortho grid, the rest 0 (1-based)."""
    cells = np.random.default_rng(seed).permutation(ORTHO_Y * ORTHO_X)[: DOWNTRACK * CROSSTRACK]
    rows, cols = np.meshgrid(np.arange(DOWNTRACK), np.arange(CROSSTRACK), indexing="ij")
    glt_x, glt_y = np.zeros((ORTHO_Y, ORTHO_X), "int32"), np.zeros((ORTHO_Y, ORTHO_X), "int32")
    glt_y.flat[cells], glt_x.flat[cells] = rows.ravel() + 1, cols.ravel() + 1
    return glt_x, glt_y


def _obs(sza: float = 40.0) -> np.ndarray:
    """(downtrack, crosstrack, 5) obs: sun fixed, view zenith across track, one filled pixel."""
    obs = np.zeros((DOWNTRACK, CROSSTRACK, len(OBS_BANDS)), "float32")
    across = np.arange(CROSSTRACK) - (CROSSTRACK - 1) / 2
    obs[..., 0] = 400000.0
    obs[..., 1] = np.where(across < 0, 100.0, 280.0)[None, :]
    obs[..., 2] = (np.abs(across) * 3.0)[None, :]
    obs[..., 3] = 160.0
    obs[..., 4] = sza
    obs[5, 1, :] = EMIT_FILL
    return obs


def _write_granule(path: Path, name: str, cube: np.ndarray, band_parameters: dict, glt=None,
                   geotransform=GEOTRANSFORM) -> Path:
    """A granule in EMIT's V001 NetCDF layout: root variable, sensor_band_parameters, location."""
    glt_x, glt_y = _glt() if glt is None else glt
    attrs = {"spatial_ref": rasterio.crs.CRS.from_epsg(4326).to_wkt()}
    if geotransform is not None:
        attrs["geotransform"] = geotransform
    xr.Dataset({name: (("downtrack", "crosstrack", "bands"), cube)}, attrs=attrs).to_netcdf(
        path, engine="h5netcdf", encoding={name: {"_FillValue": np.float32(EMIT_FILL)}})
    xr.Dataset({key: ("bands", values) for key, values in band_parameters.items()}).to_netcdf(
        path, mode="a", group="sensor_band_parameters", engine="h5netcdf")
    if isinstance(glt_x, tuple):  # a declared shape: datasets without data, as a hostile granule has
        with h5py.File(path, "a") as h5file:
            for key in ("glt_x", "glt_y"):
                h5file.create_dataset(f"location/{key}", shape=glt_x, dtype="int32", chunks=(1024, 1024))
        return path
    xr.Dataset({"glt_x": (("ortho_y", "ortho_x"), glt_x), "glt_y": (("ortho_y", "ortho_x"), glt_y)}).to_netcdf(
        path, mode="a", group="location", engine="h5netcdf")
    return path


@pytest.fixture
def emit(tmp_path):
    """``emit(...)``: EMIT granules (reflectance and obs) damaged as asked, and the command."""
    transform = Affine.from_gdal(*GEOTRANSFORM)
    scene = _product_scene(tmp_path, transform, (ORTHO_Y, ORTHO_X), "EPSG:4326")

    def make(*, glt=None, obs_glt=None, obs=None, geotransform=GEOTRANSFORM, granule="20230612T201034_2316313_005"):
        cube = np.random.default_rng(4).uniform(0.02, 0.6, (DOWNTRACK, CROSSTRACK, 3)).astype("float32")
        rfl = _write_granule(scene["dir"] / f"EMIT_L2A_RFL_001_{granule}.nc", "reflectance", cube,
                             {"wavelengths": np.array([551.4, 660.1, 857.8])}, glt, geotransform)
        obs = _write_granule(scene["dir"] / f"EMIT_L1B_OBS_001_{granule}.nc", "obs",
                             _obs() if obs is None else obs,
                             {"observation_bands": np.array(OBS_BANDS, dtype=object)},
                             glt if obs_glt is None else obs_glt, geotransform)
        args = ["correct", rfl, "--angles", obs, "--angles-kind", "emit", "--classes", scene["classes"],
                "--params", scene["params"], "-o", scene["output"], "--no-limits", "--no-progress"]
        return scene, args

    return make


def _fractional_glt():
    glt_x, glt_y = (layer.astype("float64") for layer in _glt())
    glt_x[glt_x > 0] += 0.4  # EMIT's rule takes integers; truncating 3.4 to 3 shifted pixels
    return glt_x, glt_y


def _nan_glt():
    glt_x, glt_y = (layer.astype("float64") for layer in _glt())
    glt_y[0, :] = np.nan
    return glt_x, glt_y


@pytest.mark.parametrize("case, pattern", [
    ({"obs": _obs(sza=np.nan)}, r"OBS\S+\.nc \(emit\): no finite sza value \(all NaN, inf or nodata\)"),
    ({"obs": np.where(np.arange(len(OBS_BANDS)) == 2, np.inf, _obs()).astype("float32")},
     r"OBS\S+\.nc \(emit\): no finite vza value"),
    ({"glt": _fractional_glt()}, r"RFL\S+\.nc: location/glt_x holds fractional indices \(e\.g\. \d\.4 at cell "
                                 r"\(\d+, \d+\)\); GLT indices are integers"),
    ({"glt": _nan_glt()}, r"RFL\S+\.nc: location/glt_y holds 11 NaN or infinite values; GLT indices are integers"),
    ({"obs_glt": _glt(seed=7)}, r"OBS\S+\.nc: its GLT \(location/glt_x, glt_y\) differs from that of \S+RFL\S+\.nc: "
                                r"the obs granule is not of the reflectance granule's scene"),
    ({"geotransform": ", ".join(map(str, GEOTRANSFORM))},
     r"RFL\S+\.nc: geotransform '-116\.2, 0\.000542\S*, 0\.0, 36\.4.*' is str\d+ data, not 6 numbers \(GDAL order\)"),
    ({"geotransform": [np.nan, *GEOTRANSFORM[1:]]},
     r"RFL\S+\.nc: the geotransform \(nan, 0\.000542233, 0, 36\.4, 0, -0\.000542233\) holds "
     r"non-finite values"),
    ({"glt": ((60000, 60000), None)}, r"RFL\S+\.nc: location/glt_x declares 60000 x 60000 cells for a swath of "
                                      r"8 x 6 pixels; an orthorectified grid of at most 3072 cells is expected"),
], ids=["sza-all-nan", "vza-all-inf", "glt-fractional", "glt-nan", "obs-other-glt", "geotransform-text",
        "geotransform-nan", "glt-60000"])
def test_emit_granules_that_leave_nothing_or_a_wrong_number(emit, case, pattern, refused):
    scene, args = emit(**case)
    refused(scene, args, pattern)


def test_emit_float_glt_of_integers_is_taken_as_integers(emit, invoke):
    """A GLT stored as floats that are all integers is EMIT's GLT: the same output as int32's."""
    scene, args = emit()
    assert invoke(args)[0] == 0
    with rasterio.open(scene["output"]) as output:
        expected = output.read()
    scene["output"].unlink()
    scene, args = emit(glt=tuple(layer.astype("float64") for layer in _glt()), granule="20230612T201034_2316313_006")
    code, stderr = invoke(args)
    assert code == 0, stderr
    with rasterio.open(scene["output"]) as output:
        corrected = output.read()
    assert np.isfinite(corrected).sum() == 3 * (DOWNTRACK * CROSSTRACK - 1)  # every pixel but the filled one
    np.testing.assert_array_equal(corrected, expected)


# -------------------------------------------------------- 8, 14. GeoTIFF layers and fit-classes
def _rewrite(source: Path, target: Path, change, **profile) -> Path:
    """``target``: ``source`` with its (band, y, x) values passed through ``change`` and its
    profile updated by ``profile``."""
    with rasterio.open(source) as dataset:
        values, options = dataset.read(), {**dataset.profile, **profile}
        descriptions = dataset.descriptions
    values = change(values)
    with rasterio.open(target, "w", **{**options, "count": values.shape[0]}) as dataset:
        dataset.write(values.astype(options["dtype"]))
        if len(descriptions) == values.shape[0]:
            dataset.descriptions = descriptions
    return target


def _with_band(values: np.ndarray, band: int, value: float) -> np.ndarray:
    values = values.copy()
    values[band] = value
    return values


@pytest.mark.parametrize("layer, band, value", [("sza", 0, np.nan), ("vza", 2, np.inf), ("saa", 1, -np.inf)])
def test_angle_layer_without_a_finite_value(scene, layer, band, value, refused, correct_args):
    """A constant sza of 95 deg was exit 2 while an all-NaN one gave 100 % nodata with exit 0."""
    angles = _rewrite(scene["angles"], scene["dir"] / "angles_empty.tif", lambda v: _with_band(v, band, value))
    refused(scene, correct_args(scene, angles=("--angles", angles)),
            rf"angles_empty\.tif.*: no finite {layer} value \(all NaN, inf or nodata\): nothing could be corrected")


@pytest.mark.parametrize("role", ["image", "angles"])
def test_complex_raster_is_refused(scene, role, refused, correct_args):
    source = scene[role]
    complex_file = _rewrite(source, scene["dir"] / f"{role}_complex.tif", lambda v: v + 0.5j, dtype="complex64",
                            nodata=None)
    args = correct_args(scene, image=complex_file) if role == "image" else \
        correct_args(scene, angles=("--angles", complex_file))
    refused(scene, args, rf"{role}_complex\.tif holds complex values \(complex64\); brdfcorr reads real numbers")


def test_nan_geotransform_is_named_as_such(scene, refused, correct_args):
    with rasterio.open(scene["angles"]) as dataset:
        transform = dataset.transform
    angles = _rewrite(scene["angles"], scene["dir"] / "angles_nan_origin.tif", lambda v: v,
                      transform=Affine(transform.a, 0.0, float("nan"), 0.0, transform.e, transform.f))
    refused(scene, correct_args(scene, angles=("--angles", angles)),
            r"angles_nan_origin\.tif\)?: its geotransform \(10, 0, nan, 0, -10, 5\.4e\+06\) holds non-finite values")


def test_fit_classes_names_a_band_without_finite_values(scene, refused):
    """It was "class 1: 0 samples < 50, view zenith spread 0.0 deg" without the band."""
    image = _rewrite(scene["image"], scene["dir"] / "image_nan_band.tif", lambda v: _with_band(v, 2, np.nan))
    refused(scene, ["fit-classes", image, "--angles", scene["angles"], "--classes", scene["classes"],
                   "-o", scene["out"] / "fitted.yaml"],
            r"band 3 \(660 nm\): no finite reflectance at any sampled pixel of any class \(\d+ classes; "
            r"all NaN, inf or nodata\); leave the band out of the image")


def test_normalize_refuses_complex_arrays():
    """The library's own entry: a complex reflectance gave a complex "corrected" cube."""
    from brdfcorr.correction import normalize
    from brdfcorr.errors import InputError

    angles = {name: np.full((3, 3), 20.0) for name in ("sza", "saa", "vza", "vaa")}
    with pytest.raises(InputError, match=r"complex values in reflectance \(complex64\); real numbers are expected"):
        normalize(np.ones((4, 3, 3), "complex64"), np.ones((3, 3), "uint8"), angles, example_table())
    with pytest.raises(InputError, match=r"complex values in vza \(complex128\)"):
        normalize(np.ones((4, 3, 3), "float32"), np.ones((3, 3), "uint8"),
                  {**angles, "vza": angles["vza"] + 1j}, example_table())


@pytest.mark.parametrize("layer", ["slope", "aspect"])
def test_slope_aspect_layer_without_a_finite_value(scene, layer, refused, correct_args):
    """Such a layer was left to the correction: 100 % nodata with exit 0."""
    surface = np.stack([np.full((NY, NX), 5.0), np.full((NY, NX), 180.0)])
    surface[0 if layer == "slope" else 1] = np.nan
    path = _rewrite(scene["angles"], scene["dir"] / "slope_aspect.tif", lambda v: surface)
    refused(scene, correct_args(scene, "--slope-aspect", path),
            rf"slope/aspect file \S+slope_aspect\.tif: no finite {layer} value \(all NaN, inf or nodata\)")


def test_a_cluster_that_loses_its_last_worker_stops_the_run_in_one_line(monkeypatch):
    """Issue 39: a scheduler whose only worker dies keeps the run's tasks waiting forever; the
    run is stopped once it has had no worker for WORKER_TIMEOUT, with one line naming it."""
    import time

    import dask
    import dask.array as da

    from brdfcorr.errors import InputError

    monkeypatch.setattr(cluster, "WORKER_TIMEOUT", 1.0)

    def slow(block):
        time.sleep(0.2)
        return block

    outcome: dict = {}

    def run(address):  # in a thread: without the watch, the computation would wait forever
        try:
            with cluster.connect_cluster(address, setting="--scheduler") as client:
                stopper.start()
                dask.compute(da.ones((100, 4), chunks=(1, 4)).map_blocks(slow).sum(), scheduler=client)
        except InputError as error:
            outcome["error"] = error

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as local:
        address = local.scheduler_address
        stopper = threading.Timer(0.5, local.scale, args=(0,))  # the worker leaves mid-run
        runner = threading.Thread(target=run, args=(address,), daemon=True)
        runner.start()
        # 100 chunks of 0.2 s on one thread would take 20 s: the run stops about a second after the loss
        runner.join(timeout=15.0)
        stopped = not runner.is_alive()
        stopper.join()
    assert stopped, "the run still waits for a worker"
    assert str(outcome["error"]) == (f"--scheduler: the dask scheduler at {address} lost its last worker and none "
                                     "joined within 1 s; the run was stopped (restart workers and run again)")
