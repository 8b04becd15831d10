"""Measurement tables: reading, validation messages, filters, goniometer grid, synthesis."""

import hashlib
import warnings

import numpy as np
import pytest

from brdfcorr.errors import InputError, MeasurementError
from brdfcorr.fit.measurements import (
    Measurements,
    filter_measurements,
    read_measurements,
    selection_mask,
    write_measurements,
)
from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
from brdfcorr.models.materials import load_material

HEADER = "theta_i,theta_r,phi,brdf,sigma\n"


def write(tmp_path, text, name="m.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_read_values_and_line_numbers(tmp_path):
    path = write(
        tmp_path,
        "# EGO, roof tile, 550 nm\n" + HEADER + "30,0,180,0.0262,0.001\n\n30, 5 ,180,0.0266,0.0011\n",
    )
    data = read_measurements(path)
    np.testing.assert_array_equal(data.theta_r, [0.0, 5.0])
    np.testing.assert_array_equal(data.brdf, [0.0262, 0.0266])
    np.testing.assert_array_equal(data.sigma, [0.001, 0.0011])
    assert data.rows.tolist() == [3, 5]  # comment (1), header (2), blank line (4) skipped
    assert data.source == str(path) and len(data) == 2


def test_header_is_flexible_and_sigma_optional(tmp_path):
    path = write(tmp_path, "\ufeffBRDF (1/sr),Phi [deg],wavelength,Theta_R [deg],theta_i\n0.1,180,550,10,20\n")
    data = read_measurements(path)
    assert data.sigma is None
    assert (data.theta_i[0], data.theta_r[0], data.phi[0], data.brdf[0]) == (20, 10, 180, 0.1)


@pytest.mark.parametrize("header, unit", [("theta_i [rad],theta_r [rad],phi [rad],brdf", "'rad'"),
                                          ("theta_i,theta_r,phi,brdf [%]", "'%'"),
                                          ("theta_i,theta_r,phi,brdf,wavelength (um)", "'um'")])
def test_a_header_naming_another_unit_is_refused(tmp_path, header, unit):
    # Read as degrees, sr^-1 and nm, the values would be wrong without a word (radians as degrees
    # fitted f_vol = 50 for 0.02; percent gave weights 100 times too large).
    path = write(tmp_path, f"{header}\n0.5,0.2,3.1,3.0{',0.55' if 'wavelength' in header else ''}\n")
    with pytest.raises(MeasurementError, match=f"is in {unit}; brdfcorr reads angles in degrees"):
        read_measurements(path)
    spelled = write(tmp_path, "theta_i [ Degrees ],theta_r [°],phi (deg),brdf [sr^-1],sigma (1 / sr)\n30,0,180,0.1,0.01\n",
                    name="spelled.csv")
    assert len(read_measurements(spelled)) == 1


def test_write_read_round_trip_and_input_untouched(tmp_path):
    truth = load_material("red_concrete")
    original = synthesize_measurements(truth.model, truth.params, *goniometer_angles(), seed=2)
    path = write_measurements(tmp_path / "gonio.csv", original)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    again = read_measurements(path)
    for name in ("theta_i", "theta_r", "phi", "brdf", "sigma"):
        np.testing.assert_allclose(getattr(again, name), getattr(original, name), rtol=1e-9)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest
    assert [p.name for p in tmp_path.iterdir()] == ["gonio.csv"]  # no temporary left behind


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("theta_i,theta_r,brdf\n30,0,0.1\n", r"missing column\(s\) phi"),
        ("theta_i,theta_r,phi,brdf,phi\n30,0,180,0.1,1\n", r"duplicated column\(s\) phi"),
        (HEADER + "30,0,180,abc,0.1\n", r"column brdf is not a number at line 2 \(e.g. 'abc'\)"),
        (HEADER + "30,0,180,,0.1\n", r"column brdf is not a number at line 2 \(e.g. ''\)"),
        (HEADER + "30,0,180,0.1\n", r"expected 5 fields, as in the header, at line 2"),
        (HEADER + "30,95,180,0.1,0.01\n30,90,180,0.1,0.01\n", r"theta_r outside \[0, 90\) deg at line 2, line 3"),
        (HEADER + "-1,5,180,0.1,0.01\n", r"theta_i outside \[0, 90\) deg at line 2"),
        (HEADER + "30,5,181,0.1,0.01\n", r"phi outside \[0, 180\] deg at line 2"),
        (HEADER + "30,5,180,-0.1,0.01\n", "brdf negative at line 2"),
        (HEADER + "30,5,180,nan,0.01\n", "brdf is NaN or infinite at line 2"),
        (HEADER + "30,5,180,0.1,0\n", "sigma not positive at line 2"),
        ("", "empty file"),
        ("# only a comment\n", "empty file"),
        (HEADER, "no measurements after the header"),
        # every band pooled into one fit, its errors sqrt(3) too small, without a word
        ("theta_i,theta_r,phi,brdf,wavelength_nm\n30,5,180,0.1,550\n30,5,180,0.2,660\n",
         r"column 'wavelength_nm' holds several bands; name the band centres \[nm\] 'wavelength'"),
        ("theta_i,theta_r,phi,brdf,band\n30,5,180,0.1,1\n30,5,180,0.2,2\n", "column 'band' holds several bands"),
        # phi in radians beside zeniths in degrees: forward rows (pi) read as backscatter (3.1 deg)
        (HEADER + "30,40,3.14159,0.1,0.01\n30,40,0,0.1,0.01\n",
         r"phi looks like radians \(every value within \[0, 2 pi\], up to 3.14, not on half degrees\) beside "
         r"zeniths in degrees"),
    ],
)
def test_bad_tables_name_file_column_and_lines(tmp_path, text, match):
    path = write(tmp_path, text)
    with pytest.raises(MeasurementError, match=match) as caught:
        read_measurements(path)
    message = str(caught.value)
    assert message.startswith(str(path)) and "\n" not in message
    assert isinstance(caught.value, InputError) and isinstance(caught.value, ValueError)


def test_all_problems_reported_at_once_and_long_lists_shortened(tmp_path):
    rows = "".join(f"30,{95 + i},180,-0.1,0.01\n" for i in range(8))
    with pytest.raises(MeasurementError) as caught:
        read_measurements(write(tmp_path, HEADER + rows))
    message = str(caught.value)
    assert "theta_r outside [0, 90) deg at line 2, line 3, line 4, line 5, line 6 and 3 more" in message
    assert "brdf negative at line 2" in message


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(MeasurementError, match="no such file"):
        read_measurements(tmp_path / "absent.csv")
    with pytest.raises(MeasurementError, match="is a directory"):
        read_measurements(tmp_path)


def test_binary_file(tmp_path):
    path = tmp_path / "image.csv"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00")
    with pytest.raises(MeasurementError, match="not a UTF-8 text"):
        read_measurements(path)


def test_filters():
    theta_i, theta_r, phi = goniometer_angles()
    # The rows at a zenith of 0 have no azimuth (any phi gives the same BRDF): kept whatever phi they
    # were written with (a nadir row written with phi = 0 was dropped, one with 180 kept).
    data = synthesize_measurements("lambertian", {"t0": 0.1}, theta_i, theta_r, np.where(theta_r == 0, 0.0, phi),
                                   seed=0)
    forward = filter_measurements(data, min_phi=90)
    undefined = (data.theta_i == 0) | (data.theta_r == 0)
    assert np.all(forward.phi[(forward.theta_i > 0) & (forward.theta_r > 0)] >= 90)
    assert len(forward) == np.count_nonzero((data.phi >= 90) | undefined) == np.count_nonzero(data.phi >= 90) + 3
    assert forward.filters == ("phi >= 90",)
    narrow = filter_measurements(data, min_phi=90, max_phi=170, max_zenith=60)
    assert np.all(((narrow.phi <= 170) | (narrow.theta_r == 0)) & (narrow.theta_i <= 60) & (narrow.theta_r <= 60))
    assert narrow.filters == ("phi >= 90 and phi <= 170 and theta_i, theta_r <= 60",)
    assert filter_measurements(data) is data
    mask, description = selection_mask(data, min_phi=90)
    assert description == "phi >= 90" and mask.sum() == len(forward)
    with pytest.raises(MeasurementError, match="no measurement has phi >= 181"):
        filter_measurements(data, min_phi=181)


def test_goniometer_grid_counts():
    theta_i, theta_r, phi = goniometer_angles()
    # Principal plane: 3 zeniths x (16 forward at 0..75 + 15 backward at 5..75) = 93;
    # azimuth scans: 4 cuts x 36 azimuths 0..175 = 144. With phi >= 90: 3 x 16 + 4 x 18 = 120,
    # within the 122-145 measurements a sample of paper 003 (section 4).
    assert theta_i.size == 93 + 144
    assert np.count_nonzero(phi >= 90) == 120
    assert set(theta_i) == {30.0, 50.0, 65.0}
    assert np.all((theta_r >= 0) & (theta_r < 90) & (phi >= 0) & (phi <= 180))


def test_synthesis_noise_is_relative_and_reported_as_sigma():
    truth = load_material("roof_tile")
    angles = goniometer_angles()
    exact = synthesize_measurements(truth.model, truth.params, *angles, relative_noise=0.0)
    np.testing.assert_allclose(exact.brdf, truth.brdf(*angles), rtol=1e-12)
    assert exact.sigma is None
    noisy = synthesize_measurements(truth.model, truth.params, *angles, relative_noise=0.04, seed=7)
    np.testing.assert_allclose(noisy.sigma, 0.04 * exact.brdf)
    pulls = (noisy.brdf - exact.brdf) / noisy.sigma
    # 237 standard-normal draws: mean within 4 standard errors, sample std within ~5 %.
    assert abs(pulls.mean()) < 4 / np.sqrt(pulls.size)
    assert 0.8 < pulls.std() < 1.2
    again = synthesize_measurements(truth.model, truth.params, *angles, relative_noise=0.04, seed=7)
    np.testing.assert_array_equal(again.brdf, noisy.brdf)


def test_measurements_from_arrays_validate_and_select():
    data = Measurements([30, 40, 50], [10, 20, 30], [180, 170, 90], [0.1, 0.2, 0.3], source="lab")
    picked = data.select(data.phi > 100, "phi > 100")
    assert len(picked) == 2 and picked.filters == ("phi > 100",) and picked.rows is None
    assert picked.geometry.theta_i.tolist() == [30.0, 40.0]
    with pytest.raises(MeasurementError, match="lab: sigma not positive at index 1"):
        Measurements([30, 40], [10, 20], [180, 170], [0.1, 0.2], sigma=[0.01, -0.01], source="lab")


def test_wavelength_column(tmp_path):
    path = write(tmp_path, HEADER.strip() + ",wavelength\n30,0,180,0.02,0.001,450\n30,0,180,0.03,0.001,550\n"
                 "30,5,180,0.031,0.001,550\n")
    data = read_measurements(path)
    assert data.wavelengths == (450.0, 550.0)
    green = data.at_wavelength(550)
    assert len(green) == 2 and green.rows.tolist() == [3, 4]
    assert green.filters == ("wavelength = 550 nm",)
    again = read_measurements(write_measurements(tmp_path / "copy.csv", data))
    np.testing.assert_array_equal(again.wavelength, data.wavelength)
    with pytest.raises(MeasurementError, match="no measurements at 650 nm; wavelengths: 450, 550"):
        data.at_wavelength(650)
    with pytest.raises(MeasurementError, match="wavelength not finite and positive at line 2"):
        read_measurements(write(tmp_path, HEADER.strip() + ",wavelength\n30,0,180,0.02,0.001,-450\n"))
    with pytest.raises(MeasurementError, match="no wavelength column"):
        read_measurements(write(tmp_path, HEADER + "30,0,180,0.02,0.001\n")).at_wavelength(550)


def test_wavelengths_in_micrometres_are_refused(tmp_path):
    # 0.65 (a micrometre typed into a nanometre column) made a fit "at 0.65 nm" and a table from
    # 0.65 to 550 nm without a word.
    with pytest.raises(MeasurementError, match=r"wavelength below 100 nm at line 3 \(e\.g\. 0\.65\): micrometres\?"):
        read_measurements(write(tmp_path, HEADER.strip() + ",wavelength\n30,0,180,0.02,0.001,550\n"
                                "30,0,180,0.03,0.001,0.65\n"))


def test_angles_in_radians_are_refused_from_files_and_arrays(tmp_path):
    # Read as degrees, a table in radians fitted w = 0.77 deg^-1 (for 0.037) with only a warning.
    truth = load_material("roof_tile")
    data = synthesize_measurements(truth.model, truth.params, *goniometer_angles(), relative_noise=0.03, seed=0)
    radians = [np.radians(values) for values in (data.theta_i, data.theta_r, data.phi)]
    with pytest.raises(MeasurementError, match=r"the angles look like radians \(theta_i, theta_r up to 1\.\d+, phi up to "
                                               r"3\.14\); brdfcorr needs degrees"):
        Measurements(*radians, data.brdf, data.sigma)
    rows = "".join(f"{ti:.6f},{tr:.6f},{phi:.6f},{f:.6g},{s:.6g}\n"
                   for ti, tr, phi, f, s in zip(*radians, data.brdf, data.sigma))
    with pytest.raises(MeasurementError, match="look like radians"):
        read_measurements(write(tmp_path, HEADER + rows))
    with pytest.raises(MeasurementError, match="look like radians"):  # zeniths in radians, phi in degrees
        Measurements(radians[0], radians[1], data.phi, data.brdf, data.sigma)
    with pytest.raises(MeasurementError, match="look like radians"):  # the backscatter plane only
        Measurements(radians[0], radians[1], 0.0 * data.phi, data.brdf, data.sigma)
    Measurements([0.0, 0.0], [0.0, 0.15], [0.0, 0.0], [0.1, 0.1])  # near the zenith in degrees: allowed


def test_rows_repeated_in_every_column_are_named(tmp_path):
    # A table pasted twice: each row counted twice shrinks the fit's errors by sqrt(2) in silence.
    rows = "30,0,180,0.0262,0.001\n30,5,180,0.0266,0.0011\n"
    with pytest.warns(UserWarning, match=r"the rows at line 4, line 5 repeat earlier ones in every column"):
        data = read_measurements(write(tmp_path, HEADER + rows + rows))
    assert len(data) == 4  # read as they are: the user decides
    # A repeated geometry with its own BRDF is a measurement of its own: no warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_measurements(write(tmp_path, HEADER + rows + "30,0,180,0.0270,0.001\n", name="again.csv"))


def test_one_band_named_in_a_column_and_a_hotspot_scan_in_degrees_are_read(tmp_path):
    # A constant band column is one band (as asked); phi of 0-3 deg on half degrees near the hotspot
    # is degrees. Both were refused by the first form of the checks of test_bad_tables_....
    one_band = read_measurements(write(tmp_path, "theta_i,theta_r,phi,brdf,band\n30,5,180,0.1,3\n30,6,180,0.2,3\n"))
    assert len(one_band) == 2 and one_band.wavelength is None
    hotspot = read_measurements(write(tmp_path, HEADER + "30,40,0,0.1,0.01\n30,40,1.5,0.1,0.01\n30,40,3,0.1,0.01\n",
                                      "hotspot.csv"))
    assert hotspot.phi.tolist() == [0.0, 1.5, 3.0]
    full_circle = HEADER + "30,40,0.5236,0.1,0.01\n30,40,5.5,0.1,0.01\n"  # radians over 0-2 pi
    with pytest.raises(MeasurementError, match="phi looks like radians"):
        read_measurements(write(tmp_path, full_circle, "circle.csv"))
