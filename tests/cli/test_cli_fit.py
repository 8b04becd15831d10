"""`brdfcorr fit`: the printed table, the parameter table it writes/appends, figures, bad input."""

import hashlib

import numpy as np
import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.fit.goniometer import fit_measurements
from brdfcorr.fit.measurements import filter_measurements, read_measurements, write_measurements
from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def csv_path(tmp_path_factory):
    truth = load_material("roof_tile")
    data = synthesize_measurements(truth.model, truth.params, *goniometer_angles(), seed=11)
    return write_measurements(tmp_path_factory.mktemp("gonio") / "roof_tile.csv", data)


def run(*args):
    result = CliRunner().invoke(main, [str(arg) for arg in args])
    return result


def test_fit_prints_table_writes_parameter_table_and_figures(csv_path, tmp_path):
    before = hashlib.sha256(csv_path.read_bytes()).hexdigest()
    table_path = tmp_path / "params.yaml"
    result = run(
        "fit", csv_path, "--fix", "k=0.25", "--min-phi", "90", "-o", table_path,
        "--class-id", 3, "--class-name", "roof_tile", "--plot-dir", tmp_path / "plots",
    )
    assert result.exit_code == 0, result.output
    assert "120 of 237 measurements (phi >= 90)" in result.output
    assert "t0 [sr^-1]" in result.output and "chi2/dof" in result.output
    assert "0.25 (fixed)" in result.output and "±" in result.output
    assert "correlations:" in result.output
    assert result.stderr == ""

    # The same fit through the library gives exactly the numbers written to the table.
    expected = fit_measurements(
        "torrance_sparrow", filter_measurements(read_measurements(csv_path), min_phi=90),
        fixed={"k": 0.25},
    )
    table = ParameterTable.load(table_path)
    assert table.class_ids == (3,)
    assert table[3].name == "roof_tile" and table[3].model == "torrance_sparrow"
    assert table[3].params == expected.params
    assert table[3].params["k"] == 0.25
    # ... and the correction code reads them unchanged, for any band.
    bands = table.for_bands(n_bands=2)[3].params
    for name, value in expected.params.items():
        np.testing.assert_array_equal(bands[name], [value, value])

    for suffix in ("principal_plane", "azimuth"):
        figure = tmp_path / "plots" / f"roof_tile_{suffix}.png"
        assert figure.read_bytes()[:8] == PNG_SIGNATURE
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == [
        "roof_tile_azimuth.png", "roof_tile_principal_plane.png"
    ]
    assert hashlib.sha256(csv_path.read_bytes()).hexdigest() == before  # input untouched


def test_fit_appends_and_replaces_classes(csv_path, tmp_path):
    table_path = tmp_path / "params.yaml"
    first = run("fit", csv_path, "--fix", "k=0.25", "--min-phi", "90", "-o", table_path)
    assert first.exit_code == 0, first.output
    assert "wrote class 1 (roof_tile)" in first.output  # default id 1, default name the CSV stem
    original = ParameterTable.load(table_path)[1]

    second = run("fit", csv_path, "--model", "torrance_sparrow_simplified", "--fix", "k=0.25",
                 "--max-zenith", "60", "-o", table_path, "--class-name", "tile_simplified", "--overwrite")
    assert second.exit_code == 0, second.output
    table = ParameterTable.load(table_path)
    assert table.class_ids == (1, 2)  # appended with the next free id
    assert table[1] == original  # the existing class is not touched
    assert table[2].model == "torrance_sparrow_simplified"

    third = run("fit", csv_path, "--fix", "k=0.25", "-o", table_path, "--class-id", 2, "--class-name", "again",
                "--overwrite")
    assert third.exit_code == 0, third.output
    assert "replaced class 2 (again)" in third.output
    table = ParameterTable.load(table_path)
    assert table.class_ids == (1, 2) and table[2].name == "again"


def test_free_k_prints_a_warning_line(csv_path):
    result = run("fit", csv_path, "--min-phi", "90")
    assert result.exit_code == 0
    warnings = [line for line in result.stderr.splitlines() if line]
    # One line per warning; with k free the optimum may also end on k's bound (k = 0), said on its own line.
    assert warnings and all(line.startswith("brdfcorr: warning: torrance_sparrow: ") for line in warnings)
    assert warnings[0].startswith("brdfcorr: warning: torrance_sparrow: parameters not identifiable")


def test_measurements_in_percent_give_a_warning_line_naming_the_likely_cause(tmp_path):
    truth = load_material("spectralon_50")  # albedo about 0.5: as reflectance factors (x pi) above 1
    data = synthesize_measurements(truth.model, truth.params, *goniometer_angles(), seed=3)
    path = tmp_path / "factors.csv"
    path.write_text("theta_i,theta_r,phi,brdf\n" + "".join(
        f"{ti:g},{tr:g},{ph:g},{np.pi * value:.6g}\n" for ti, tr, ph, value in zip(data.theta_i, data.theta_r, data.phi,
                                                                               data.brdf)))
    result = run("fit", path, "--fix", "k=0.25", "--min-phi", "90")
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stderr.splitlines() if "albedo" in line]
    assert len(lines) == 1 and lines[0].startswith("brdfcorr: warning: torrance_sparrow: ")
    assert "reflectance factors (pi * BRDF: divided by pi the albedo is 0.5" in lines[0]


def test_unweighted_fit_says_how_its_errors_were_estimated(tmp_path):
    path = tmp_path / "lab.csv"
    path.write_text("theta_i,theta_r,phi,brdf\n" + "".join(
        f"30,{view},180,{0.05 + 0.001 * (view % 3)}\n" for view in range(0, 80, 5)
    ))
    result = run("fit", path, "--model", "lambertian")
    assert result.exit_code == 0, result.output
    assert "unweighted (no sigma column)" in result.output
    assert "robust to noise that differs between measurements (HC3)" in result.output


BAD_TABLES = [
    ("theta_i,theta_r,brdf\n30,0,0.1\n", "missing column(s) phi"),
    ("theta_i,theta_r,phi,brdf\n30,0,180,x\n", "column brdf is not a number at line 2"),
    ("theta_i,theta_r,phi,brdf\n30,0,180,0.1\n95,0,180,0.1\n", "theta_i outside [0, 90) deg at line 3"),
    ("theta_i,theta_r,phi,brdf\n30,0,180,-0.1\n", "brdf negative at line 2"),
    ("theta_i,theta_r,phi,brdf\n30,0,180,NaN\n", "brdf is NaN or infinite at line 2"),
    ("theta_i,theta_r,phi,brdf,sigma\n30,0,180,0.1,0\n", "sigma not positive at line 2"),
    ("", "empty file"),
]


@pytest.mark.parametrize(("text", "message"), BAD_TABLES)
def test_bad_measurement_files_give_one_error_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    output = tmp_path / "params.yaml"
    result = run("fit", path, "-o", output)
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output
    assert lines[0].startswith(f"brdfcorr: error: {path}: ")
    assert message in lines[0]
    assert not output.exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--fix", "k"], "Invalid value for '--fix': 'k': expected NAME=VALUE"),
        (["--fix", "q=1"], "unknown parameter 'q'"),
        (["--bound", "w=0.1"], "Invalid value for '--bound': 'w=0.1': expected NAME=LOW:HIGH"),
        (["--model", "phong"], "unknown BRDF model 'phong'"),
        (["--min-phi", "181"], "no measurement has phi >= 181"),
        # A name given twice with different values: which was meant? (the last was kept unseen)
        (["--fix", "k=0.25", "--fix", "k=0.3"], "k is given twice, as k=0.25 and k=0.3: give it once"),
        (["--init", "w=0.03", "--init", "w=0.04"], "w is given twice, as w=0.03 and w=0.04"),
        (["--bound", "w=0:1", "--bound", "w=0:0.5"], "w is given twice, as w=0:1 and w=0:0.5"),
        # The physical bound w > 0, not the optimizer's floor above it (5e-08), which it named before.
        (["--init", "w=0"], "starting value w = 0 is outside its physical range w > 0 [deg^-1]"),
    ],
)
def test_bad_options_give_one_error_line(csv_path, args, message):
    result = run("fit", csv_path, *args)
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and message in lines[0]


def test_fit_classes_refuses_a_fixed_name_given_twice_with_different_values(tmp_path):
    # Refused as the options are parsed, before any file is read (they need not exist).
    result = run("fit-classes", tmp_path / "image.tif", "--angles", tmp_path / "angles.tif",
                 "--classes", tmp_path / "classes.tif", "-o", tmp_path / "table.yaml",
                 "--fix", "k=0.25", "--fix", "k=0.3")
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "--fix" in lines[0] and "k is given twice, as k=0.25 and k=0.3" in lines[0]


def test_a_start_between_an_open_bound_and_the_optimizers_floor_is_fitted(csv_path):
    result = run("fit", csv_path, "--min-phi", "90", "--fix", "k=0.25", "--init", "w=1e-12")
    assert result.exit_code == 0, result.output
    assert "0.25 (fixed)" in result.output


def test_a_name_repeated_with_the_same_value_is_one_setting(csv_path):
    result = run("fit", csv_path, "--min-phi", "90", "--fix", "k=0.25", "--fix", "k=0.25")
    assert result.exit_code == 0, result.output
    assert "0.25 (fixed)" in result.output


def test_missing_measurement_file(tmp_path):
    result = run("fit", tmp_path / "absent.csv")
    assert result.exit_code == 2
    assert result.stderr.strip() == f"brdfcorr: error: {tmp_path / 'absent.csv'}: no such file"


def test_bad_existing_parameter_table_is_reported_before_fitting(csv_path, tmp_path):
    table_path = tmp_path / "params.yaml"
    table_path.write_text("classes: [{id: 1, name: x, model: torrance_sparrow, params: {w: 1}}]\n")
    result = run("fit", csv_path, "-o", table_path, "--overwrite")
    assert result.exit_code == 2
    assert str(table_path) in result.stderr and len(result.stderr.splitlines()) == 1
    assert "missing parameter" in result.stderr


def test_spectral_table_fits_each_wavelength(tmp_path):
    truth = load_material("blue_concrete")
    angles = goniometer_angles()
    parts = [
        synthesize_measurements(truth.model, truth.params, *angles, seed=seed, wavelength=wavelength)
        for seed, wavelength in enumerate((450.0, 850.0))
    ]
    lines = ["theta_i,theta_r,phi,brdf,sigma,wavelength"]
    for part in parts:
        lines += [
            ",".join(f"{value:.10g}" for value in row)
            for row in zip(part.theta_i, part.theta_r, part.phi, part.brdf, part.sigma, part.wavelength)
        ]
    path = tmp_path / "blue.csv"
    path.write_text("\n".join(lines) + "\n")
    table_path = tmp_path / "params.yaml"
    result = run("fit", path, "--fix", "k=0.25", "--min-phi", "90", "-o", table_path)
    assert result.exit_code == 0, result.output
    assert "2 wavelengths fitted separately" in result.output
    entry = ParameterTable.load(table_path)[1]
    assert entry.wavelengths == [450.0, 850.0]
    assert len(entry.params["w"]) == 2 and entry.params["k"] == 0.25

    single = run("fit", path, "--fix", "k=0.25", "--min-phi", "90", "--wavelength", "850",
                 "-o", table_path, "--class-id", 2, "--overwrite")
    assert single.exit_code == 0, single.output
    expected = fit_measurements(
        "torrance_sparrow",
        filter_measurements(read_measurements(path).at_wavelength(850.0), min_phi=90),
        fixed={"k": 0.25},
    )
    assert ParameterTable.load(table_path)[2].params == expected.params
    assert ParameterTable.load(table_path)[1].params["w"][1] == expected.params["w"]

    missing = run("fit", path, "--wavelength", "550")
    assert missing.exit_code == 2
    assert "no measurements at 550 nm; wavelengths: 450, 850" in missing.stderr


def test_wavelengths_a_fraction_of_a_nanometre_apart_keep_their_own_labels_and_figures(tmp_path):
    # 550 and 550.0001 nm (a spectroradiometer's grid) printed as "550" twice and drew their figures
    # into one file name, the second over the first.
    truth = load_material("blue_concrete")
    angles = goniometer_angles()
    lines = ["theta_i,theta_r,phi,brdf,sigma,wavelength"]
    for seed, wavelength in enumerate((550.0, 550.0001)):
        part = synthesize_measurements(truth.model, truth.params, *angles, seed=seed, wavelength=wavelength)
        lines += [",".join(f"{value:.10g}" for value in row)
                  for row in zip(part.theta_i, part.theta_r, part.phi, part.brdf, part.sigma, part.wavelength)]
    path = tmp_path / "close.csv"
    path.write_text("\n".join(lines) + "\n")
    result = run("fit", path, "--fix", "k=0.25", "--min-phi", "90", "--plot-dir", tmp_path / "figures")
    assert result.exit_code == 0, result.output
    assert "550.0001" in result.output
    figures = sorted(p.name for p in (tmp_path / "figures").iterdir())
    assert len(figures) == len(set(figures)) and any("550.0001nm" in name for name in figures)
    assert len([name for name in figures if "550nm" in name]) == len([name for name in figures if "550.0001nm" in name])


def _two_surfaces_csv(path):
    """A table of Ross-Thick-Li-Sparse measurements at 550 nm and the roof tile's at 850 nm."""
    from brdfcorr.models import get_model

    angles = goniometer_angles()
    tile = load_material("roof_tile")
    parts = [synthesize_measurements(get_model("ross_thick_li_sparse"), {"f_iso": 0.1, "f_vol": 0.05, "f_geo": 0.02},
                                     *angles, relative_noise=0.03, seed=0, wavelength=550.0),
             synthesize_measurements(tile.model, tile.params, *angles, relative_noise=0.03, seed=1, wavelength=850.0)]
    lines = ["theta_i,theta_r,phi,brdf,sigma,wavelength"]
    for part in parts:
        lines += [",".join(f"{value:.10g}" for value in row)
                  for row in zip(part.theta_i, part.theta_r, part.phi, part.brdf, part.sigma, part.wavelength)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_auto_on_wavelengths_that_choose_differently_says_so_and_breaks_the_tie_by_the_errors(tmp_path):
    # 550 nm chooses the kernels, 850 nm the Torrance-Sparrow lobe: the 1-1 tie went to the first
    # wavelength's choice, and the other wavelength was fitted with it without a word. The summed
    # held-out errors decide now (each table printed gives them), and the other wavelength is named.
    path = _two_surfaces_csv(tmp_path / "two.csv")
    result = run("fit", path, "--model", "auto")
    assert result.exit_code == 0, result.output
    assert "model torrance_sparrow" in result.output
    assert "550 nm: --model auto chose ross_thick_li_sparse here; torrance_sparrow, the choice over the " \
           "wavelengths, is fitted at every wavelength" in result.output + result.stderr


def test_auto_refuses_a_fixed_name_no_candidate_has(tmp_path):
    path = _two_surfaces_csv(tmp_path / "two.csv")
    result = run("fit", path, "--model", "auto", "--fix", "N=3")
    assert result.exit_code == 2
    assert "the fixed value of N is a parameter of none of the models --model auto tries" in result.stderr
