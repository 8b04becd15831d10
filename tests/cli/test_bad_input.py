"""Every way a real input can be wrong ends in one clear message, exit code 2 and no damage.

Each case of the tables below builds one bad input beside a good synthetic scene
(:mod:`brdfcorr.testing`), runs the command line and checks

1. the exit code (2: bad input, config, parameter or an output that cannot be written);
2. stderr is exactly one line, ``brdfcorr: error: ...``, matching the expected message, which names
   the file, key, band or class at fault (and no traceback);
3. no file at the output path and no file at all (not even a temporary one) in the output
   directory, or no output directory at all for chain runs;
4. every input file is byte-identical afterwards (SHA-256 of every file of the scene directory).

Pixel-level problems that are not input errors by design (``DESIGN.md``; QA table of
:mod:`brdfcorr.correction`) are checked at the end: NaN/inf reflectance and zeniths outside [0, 90)
become nodata and are counted.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.params import ParameterTable
from brdfcorr.testing import file_digests, synthetic_scene, write_scene_chain

NY, NX = 32, 40


@pytest.fixture(scope="module")
def template(tmp_path_factory, write_example_scene) -> Path:
    """A good scene written once; every test copies it (tests never share files they might damage)."""
    return write_example_scene(tmp_path_factory.mktemp("template") / "scene", synthetic_scene(ny=NY, nx=NX))["dir"]


# ------------------------------------------------------------------------------------- helpers
def _read(path: Path) -> tuple[np.ndarray, dict]:
    with rasterio.open(path) as dataset:
        return dataset.read(), {**dataset.profile, "descriptions": dataset.descriptions}


def _write(path: Path, data: np.ndarray, profile: dict, **changes) -> Path:
    """A GeoTIFF with ``data`` and the profile of another raster, with ``changes`` applied."""
    profile = {**profile, "count": data.shape[0], "dtype": data.dtype.name, **changes}
    descriptions = profile.pop("descriptions", None)
    if data.dtype.kind == "f" and profile.get("nodata") is not None and not np.isnan(profile["nodata"]):
        profile["nodata"] = None
    with rasterio.open(path, "w", **profile) as dataset:
        dataset.write(data)
        if descriptions is not None and len(descriptions) == data.shape[0]:
            dataset.descriptions = descriptions  # band centres ("480 nm") go with the bands
    return path


def _derived(scene, role: str, name: str, transform=None, **changes) -> Path:
    """A copy of the scene's ``role`` raster named ``name``, values changed by ``transform``."""
    data, profile = _read(scene[role])
    if transform is not None:
        data = transform(data)
    return _write(scene["dir"] / name, np.ascontiguousarray(data), profile, **changes)


def _table(scene, text: str, name: str = "bad.yaml") -> Path:
    path = scene["dir"] / name
    path.write_text(text)
    return path


def _correct_args(scene, **replace) -> list[str]:
    """``brdfcorr correct`` on the scene; ``replace`` swaps an option's value (None drops it)."""
    options = {"--angles": scene["angles"], "--classes": scene["classes"], "--params": scene["params"],
               "-o": scene["output"], "--chunk": 16}
    image = replace.pop("image", scene["image"])
    options.update(replace)
    args = ["correct", str(image)]
    for key, value in options.items():
        if value is not None:
            args += [key, str(value)]
    return args


def _one_error_line(result) -> str:
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("brdfcorr: error: "), lines[0]
    assert "Traceback" not in result.output
    return lines[0]


# ---------------------------------------------------------------------------- brdfcorr correct
def _angle_table(factor: float = 1.0, offset: float = 0.0):
    return lambda data: (data * factor + offset).astype(data.dtype)


TABLE_TS = ("classes: [{id: 1, name: tile, model: torrance_sparrow, "
            "params: {t0: 0.02, t1: 0.2, w: 0.036, n: 1.77, k: 0.25%s}}]")

CORRECT_CASES = {
    # --- files
    "image missing": (lambda s: _correct_args(s, image=s["dir"] / "nope.tif"),
                      r"image file \S*nope\.tif does not exist"),
    "image not a raster": (
        lambda s: _correct_args(s, image=_table(s, "not a GeoTIFF\n", "notes.tif")),
        r"cannot read image file \S*notes\.tif"),
    "image truncated": (
        lambda s: _correct_args(s, image=_truncated(s["image"], s["dir"] / "cut.tif")),
        r"cut\.tif"),
    # a fill value nobody declared, in a corner chunk (the scale check reads the central one):
    # multiplied by the factor, -9999 became -11 235 in the output, exit 0
    "image with an undeclared -9999 fill": (
        lambda s: _correct_args(s, image=_derived(s, "image", "filled.tif", _fill_corner(-9999.0))),
        r"image \S*filled\.tif: 100 values of a chunk lie below -0\.5, .*most often -9999.*"
        r"-a_nodata -9999 IMAGE IMAGE\.vrt"),
    "counts with an undeclared -9999 fill": (
        lambda s: _correct_args(s, image=_counts_with_fill(s), **{"--scale": 0.0001}),
        r"image \S*counts\.tif: 100 values of a chunk lie below -0\.5, .*most often -0\.9999.*"
        r"-a_nodata -9999 IMAGE"),
    # a NetCDF of subdatasets (GDAL: 0 bands) ended in "internal error: IndexError" (exit 1)
    "image is an EMIT granule other than L2A RFL": (
        lambda s: _correct_args(s, image=_netcdf_container(s["dir"] / "EMIT_L1B_OBS_001_20230101T000000_1_001.nc")),
        r"image file \S*EMIT_L1B_OBS_\S*\.nc holds several subdatasets and no raster band; give one raster "
        r"\(an EMIT granule other than the L2A reflectance"),
    # corrected again, an output took the factor a second time (exit 0)
    "image is a brdfcorr output": (
        lambda s: _correct_args(s, image=_corrected_once(s)),
        r"image \S*once\.tif is a brdfcorr output, normalized already to sza=.*; correct the image it was made from"),
    # a misspelt --angle-option, or one of the wrong type, was an internal error (exit 1)
    "angle option misspelt": (
        lambda s: _correct_args(s, **{"--angles-kind": "envi_obs", "--angle-option": "view_azimut=from_sensor"}),
        r"angle option 'view_azimut' is no option of angle kind 'envi_obs'; its options: view_azimuth, band_names"),
    "angle option band_names not a mapping": (
        lambda s: _correct_args(s, **{"--angles-kind": "envi_obs", "--angle-option": "band_names=solar_zn"}),
        r"band_names must map layers \(sza, saa, vza, vaa\) to band-name texts"),
    "angles missing": (lambda s: _correct_args(s, **{"--angles": s["dir"] / "nope_angles.tif"}),
                       r"angle file \S*nope_angles\.tif does not exist"),
    "angles not a raster": (lambda s: _correct_args(s, **{"--angles": s["params"]}),
                            r"cannot read angle file \S*params\.yaml"),
    "classes missing": (lambda s: _correct_args(s, **{"--classes": s["dir"] / "nope_classes.tif"}),
                        r"class map file \S*nope_classes\.tif does not exist"),
    # --- angle rasters
    # 3 bands are sza, vza, raa (MODIS/VIIRS, tests/io/test_relative_azimuth.py): 2 are no angle raster.
    "angles with 2 bands": (
        lambda s: _correct_args(s, **{"--angles": _derived(s, "angles", "angles2.tif", lambda d: d[:2])}),
        r"angle file \S*angles2\.tif has 2 bands; it needs 4 \(sza, saa, vza, vaa\) or 3 \(sza, vza, raa\)"),
    "sza, saa, vza as sza, vza, raa": (
        lambda s: _correct_args(s, **{"--angles": _derived(s, "angles", "angles3.tif", lambda d: d[:3])}),
        r"vza \(\S*angles3\.tif\): no vza value in \[0, 90\) deg"),
    "angles in radians": (
        lambda s: _correct_args(s, **{"--angles": _derived(s, "angles", "angles_rad.tif", np.deg2rad)}),
        r"angles_rad\.tif.*: the angles look like radians \(sza 0\.5.*\); brdfcorr needs degrees"),
    "angles scaled by 100": (
        lambda s: _correct_args(s, **{"--angles": _derived(s, "angles", "angles_x100.tif", _angle_table(100))}),
        r"angles_x100\.tif.*: no sza value in \[0, 90\) deg \(found 3000\.\.4000\); are the angles scaled"),
    "one separate angle file missing": (
        lambda s: _correct_args(s, **{"--angles": None, "--sza": s["angles"], "--saa": s["angles"],
                                      "--vza": s["angles"]}),
        r"missing angle file\(s\): vaa"),
    "angles on a smaller grid": (
        lambda s: _correct_args(s, **{"--angles": _derived(s, "angles", "angles_small.tif",
                                                           lambda d: d[:, :-2], height=NY - 2)}),
        r"angles_small\.tif\) is not on the grid of image \(\S*image\.tif\): shape"),
    "angles in another CRS": (
        lambda s: _correct_args(s, **{"--angles": _derived(s, "angles", "angles_crs.tif", crs="EPSG:32633")}),
        r"angles_crs\.tif\) is not on the grid of image .*: CRS EPSG:32633 differs from EPSG:32632"),
    "image in another CRS": (
        lambda s: _correct_args(s, image=_derived(s, "image", "image_crs.tif", crs="EPSG:4326")),
        r"classes \(\S*classes\.tif\) is not on the grid of image \(\S*image_crs\.tif\): CRS"),
    # --- class maps
    "class map shifted": (
        lambda s: _correct_args(s, **{"--classes": _shifted(s)}),
        r"classes \(\S*classes_shift\.tif\) is not on the grid of image .*: transform"),
    "class map float": (
        lambda s: _correct_args(s, **{"--classes": _derived(s, "classes", "classes_float.tif",
                                                            lambda d: d.astype(np.float32))}),
        r"class map \S*classes_float\.tif has data type float32; it needs integer class ids"),
    "class map with 2 bands": (
        lambda s: _correct_args(s, **{"--classes": _derived(s, "classes", "classes2.tif",
                                                            lambda d: np.concatenate([d, d]))}),
        r"class map \S*classes2\.tif has 2 bands; it needs 1"),
    # --- parameter tables
    "table missing": (lambda s: _correct_args(s, **{"--params": s["dir"] / "nope.yaml"}),
                      r"cannot read parameter table \S*nope\.yaml"),
    "table not YAML": (lambda s: _correct_args(s, **{"--params": _table(s, "classes: [\n")}),
                       r"bad\.yaml: not valid YAML \(line 2, column 1\)"),
    "table not a mapping": (lambda s: _correct_args(s, **{"--params": _table(s, "- 1\n- 2\n")}),
                            r"bad\.yaml: expected a mapping with 'classes', got list"),
    "table unknown model": (
        lambda s: _correct_args(s, **{"--params": _table(
            s, "classes: [{id: 1, name: tile, model: torrance, params: {t0: 0.1}}]")}),
        r"bad\.yaml: class 1 \(tile\): unknown surface model 'torrance'; known: torrance_sparrow"),
    "table unknown parameter": (
        lambda s: _correct_args(s, **{"--params": _table(s, TABLE_TS % ", sigma: 3")}),
        r"bad\.yaml: class 1 \(tile\): torrance_sparrow: unknown parameter 'sigma'"),
    "table missing parameter": (
        lambda s: _correct_args(s, **{"--params": _table(
            s, "classes: [{id: 1, name: tile, model: torrance_sparrow, params: {t0: 0.02, t1: 0.2, n: 1.7, k: 0.2}}]")}),
        r"bad\.yaml: class 1 \(tile\): torrance_sparrow: missing parameter\(s\) w"),
    "table out of bounds": (
        lambda s: _correct_args(s, **{"--params": _table(s, (TABLE_TS % "").replace("n: 1.77", "n: -1.77"))}),
        r"bad\.yaml: class 1 \(tile\): torrance_sparrow: parameter n = -1\.77 is invalid"),
    "table NaN": (
        lambda s: _correct_args(s, **{"--params": _table(s, (TABLE_TS % "").replace("w: 0.036", "w: .nan"))}),
        r"bad\.yaml: class 1 \(tile\): torrance_sparrow: parameter w = nan is invalid"),
    "table per-band list of the wrong length": (
        lambda s: _correct_args(s, **{"--params": _table(
            s, "classes: [{id: 4, name: flat, model: lambertian, params: {t0: [0.1, 0.2, 0.3]}}]")}),
        r"bad\.yaml: class 4 \(flat\): parameter t0 has 3 per-band values but the image has 4 bands "
        r"\(image \S*image\.tif\)"),
    "table wavelengths do not cover the image": (
        lambda s: _correct_args(s, **{"--params": _table(
            s, "classes: [{id: 4, name: flat, model: lambertian, wavelengths: [500, 700], "
               "params: {t0: [0.1, 0.2]}}]")}),
        r"bad\.yaml: class 4 \(flat\): parameter t0: band centre 480 nm is outside the table's "
        r"wavelengths \[500, 700\] nm.*\(image \S*image\.tif\)"),
    "table with a python tag (YAML loaded safely)": (
        lambda s: _correct_args(s, **{"--params": _table(
            s, "classes: !!python/object/apply:os.system ['touch pwned']\n")}),
        r"bad\.yaml: not valid YAML \(line 1, column 10\): the tag !!python/object/apply:os\.system is not allowed"),
    "wavelengths for another band count": (
        lambda s: _correct_args(s, **{"--wavelengths": "480,560,660"}),
        r"image\.tif: 3 wavelengths from the given wavelengths for 4 bands"),
    # --- options
    "required option missing": (lambda s: _correct_args(s, **{"-o": None}),
                                r"^brdfcorr: error: correct: .*'--output'.* \(see --help of correct\)$"),  # click's words between
    "option with a bad value": (lambda s: _correct_args(s, **{"--ref-sza": "noon"}),
                                r"correct: .*'noon' is not a number, 'mean', 'observed' or 'hls'"),
    "option of the wrong type": (lambda s: _correct_args(s, **{"--ref-vza": "ten"}),
                                 r"correct: .*'--ref-vza'.*'ten'"),
    # --- outputs
    "output is the image": (lambda s: _correct_args(s, **{"-o": s["image"]}),
                            r"output \S*image\.tif is also an input; inputs are never overwritten"),
    "QA output is the angle file": (lambda s: _correct_args(s, **{"--qa": s["angles"]}),
                                    r"output \S*angles\.tif is also an input"),
    "output directory missing": (lambda s: _correct_args(s, **{"-o": s["out"] / "sub" / "c.tif"}),
                                 r"output directory \S*sub does not exist"),
}


def _netcdf_container(path: Path) -> Path:
    """A NetCDF-4 file of two 2-D variables: to GDAL a container of subdatasets, no band of its own."""
    import xarray as xr

    layers = {name: (("y", "x"), np.zeros((4, 5), "float32")) for name in ("obs", "mask")}
    xr.Dataset(layers).to_netcdf(path, engine="h5netcdf")
    return path


def _corrected_once(scene) -> Path:
    """The scene's image corrected, beside the inputs (the output directory stays empty)."""
    once = scene["dir"] / "once.tif"
    result = CliRunner().invoke(main, _correct_args(scene, **{"-o": once}))
    assert result.exit_code == 0, result.output
    return once


def _fill_corner(value: float):
    """A transform filling the first 5 x 5 pixels of every band with ``value`` (no nodata declared)."""
    def fill(data):
        data = data.copy()
        data[:, :5, :5] = value
        return data
    return fill


def _counts_with_fill(scene) -> Path:
    """The image as int16 reflectance x 10 000 without a scale tag, -9999 in a corner, undeclared."""
    counts = lambda data: _fill_corner(-9999)(np.round(data * 10_000).astype(np.int16))  # noqa: E731
    return _derived(scene, "image", "counts.tif", counts, dtype="int16", nodata=None)


def _truncated(source: Path, target: Path) -> Path:
    """The first half of a GeoTIFF (a copy interrupted half-way): the header reads, tiles do not."""
    data = source.read_bytes()
    target.write_bytes(data[: len(data) // 2])
    return target


def _shifted(scene) -> Path:
    """The class map moved by one pixel to the east."""
    data, profile = _read(scene["classes"])
    profile["transform"] = profile["transform"] * rasterio.Affine.translation(1, 0)
    return _write(scene["dir"] / "classes_shift.tif", data, profile)


@pytest.mark.parametrize("case", list(CORRECT_CASES))
def test_correct_bad_input(scene, case, monkeypatch):
    build, pattern = CORRECT_CASES[case]
    monkeypatch.chdir(scene["dir"])  # a YAML tag that ran code would leave ./pwned here
    args = build(scene)
    before = file_digests(scene["dir"])
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    line = _one_error_line(result)
    assert re.search(pattern, line), line
    assert not scene["output"].exists()
    assert list(scene["out"].iterdir()) == [], "nothing, not even a temporary file, in the output directory"
    assert file_digests(scene["dir"]) == before, "inputs must be byte-identical"
    assert not (scene["dir"] / "pwned").exists()


def test_existing_output_needs_overwrite(scene):
    """An existing output is refused without --overwrite (and left as it was), replaced with it."""
    scene["output"].write_bytes(b"an earlier result")
    before = file_digests(scene["dir"])
    result = CliRunner().invoke(main, _correct_args(scene))
    assert result.exit_code == 2
    assert re.search(r"output \S*corrected\.tif exists; give --overwrite to replace it", _one_error_line(result))
    assert scene["output"].read_bytes() == b"an earlier result"
    assert file_digests(scene["dir"]) == before

    result = CliRunner().invoke(main, _correct_args(scene) + ["--overwrite"])
    assert result.exit_code == 0, result.output
    with rasterio.open(scene["output"]) as dataset:
        assert dataset.count == 4 and dataset.shape == (NY, NX)
    assert sorted(p.name for p in scene["out"].iterdir()) == ["corrected.tif"]
    assert file_digests(scene["dir"]) == before


# ----------------------------------------------------------------------- brdfcorr fit-classes
FIT_CASES = {
    "angles in radians": (
        lambda s: {"--angles": _derived(s, "angles", "angles_rad.tif", np.deg2rad)},
        r"angles_rad\.tif.*: the angles look like radians"),
    "class map float": (
        lambda s: {"--classes": _derived(s, "classes", "classes_float.tif", lambda d: d.astype(np.float32))},
        r"class map \S*classes_float\.tif has data type float32"),
    "output is the image": (lambda s: {"-o": s["image"]},
                            r"-o \S*image\.tif is also an input; inputs are never overwritten"),
    "report is the class map": (lambda s: {"--report": s["classes"]}, r"--report \S*classes\.tif is also an input"),
    "image with an undeclared -9999 fill": (
        lambda s: {"image": _derived(s, "image", "filled.tif", _fill_corner(-9999.0))},
        r"image \S*filled\.tif: \d+ values of a chunk lie below -0\.5"),
    "two images, one angle file": (
        lambda s: {"image2": s["image"]},
        r"2 image\(s\), 1 --angles and 1 --classes: give one angle raster and one class map per image"),
}


@pytest.mark.parametrize("case", list(FIT_CASES))
def test_fit_classes_bad_input(scene, case):
    build, pattern = FIT_CASES[case]
    options = {"--angles": scene["angles"], "--classes": scene["classes"], "-o": scene["out"] / "fitted.yaml",
               **build(scene)}
    args = ["fit-classes", str(options.pop("image", scene["image"]))] + (
        [str(options.pop("image2"))] if "image2" in options else [])
    for key, value in options.items():
        args += [key, str(value)]
    before = file_digests(scene["dir"])
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    line = _one_error_line(result)
    assert re.search(pattern, line), line
    assert list(scene["out"].iterdir()) == []
    assert file_digests(scene["dir"]) == before


def test_fit_output_is_the_measurements(scene):
    measurements = scene["dir"] / "tile.csv"
    measurements.write_text("theta_i,theta_r,phi,brdf\n30,30,180,0.5\n30,10,180,0.1\n30,50,90,0.05\n")
    before = file_digests(scene["dir"])
    result = CliRunner().invoke(main, ["fit", str(measurements), "-o", str(measurements)])
    assert result.exit_code == 2
    assert re.search(r"-o \S*tile\.csv is also an input; inputs are never overwritten", _one_error_line(result))
    assert file_digests(scene["dir"]) == before


# ------------------------------------------------------------------------------- brdfcorr run
def _chain(scene, text: str | None = None, **sections) -> Path:
    """The chain config over the one scene of ``scene`` (brdfcorr.testing.write_scene_chain)."""
    return write_scene_chain(scene["dir"], text, **sections)


def _with_second_image(scene):
    """``scene`` with a second image beside its own (image2.tif, another stem)."""
    shutil.copy(scene["dir"] / "image.tif", scene["dir"] / "image2.tif")
    return scene


def _chain_text(scene, text: str) -> Path:
    path = scene["dir"].parent / "chain.yaml"
    path.write_text(text)
    return path


RUN_CASES = {
    "unknown key": (
        lambda s: _chain(s, outputs={"directory": "chain_out", "compres": "zstd"}),
        r"chain\.yaml: outputs\.compres: unknown key; allowed keys: cog, compress, directory"),
    "unknown section": (
        lambda s: _chain(s, output={"directory": "x"}),
        r"chain\.yaml: output: unknown key; allowed keys: engine, inputs, name, outputs"),
    "glob matching nothing": (
        lambda s: _chain(s, inputs={"images": ["scene/image.tif", "scnee/*.tif"],
                                    "angles": {"path": "{dir}/angles.tif"}, "classes": "{dir}/classes.tif"}),
        r"chain\.yaml: inputs\.images: 'scnee/\*\.tif' matches no file \(fix or remove the pattern\)"),
    "no image at all": (
        lambda s: _chain(s, inputs={"images": ["scene/*.jp2"], "angles": {"path": "{dir}/angles.tif"},
                                    "classes": "{dir}/classes.tif"}),
        r"chain\.yaml: inputs\.images matches no file \(scene/\*\.jp2\)"),
    "output equal to an input": (
        lambda s: _chain(s, outputs={"directory": "scene", "naming": "{stem}.tif", "qa_naming": "{stem}_qa.tif"}),
        r"outputs: corrected output \S*scene/image\.tif of scene image would overwrite an input"),
    "one file named twice": (  # was "scenes image and image would both write"; use {scene} or {stem}
        lambda s: _chain(s, inputs={"images": ["scene/image.tif", "scene/../scene/image.tif"],
                                    "angles": {"path": "{dir}/angles.tif"}, "classes": "{dir}/classes.tif"}),
        r"inputs\.images names one file twice, as \S*scene/image\.tif and \S*scene/\.\./scene/image\.tif: name it once"),
    "output names without the scene": (  # the advice named {stem}, the pattern's own placeholder
        lambda s: _chain(_with_second_image(s), inputs={"images": ["scene/image*.tif"], "scene_regex": "(?P<scene>i)mage",
                                    "angles": {"path": "{dir}/angles.tif"}, "classes": "{dir}/classes.tif"},
                         outputs={"directory": "out", "naming": "{stem}_brdf.tif"}),
        r"outputs: scenes i \(\S*scene/image\.tif\) and i \(\S*scene/image2\.tif\) would both write \S*out/i_qa\.tif; "
        r"add \{stem\} or \{parent\} to outputs\.qa_naming \('\{scene\}_qa\.tif'\), or use a scene_regex"),
    "bad scene regex": (
        lambda s: _chain(s, inputs={"images": ["scene/image.tif"], "scene_regex": "(?P<scene>.+",
                                    "angles": {"path": "{dir}/angles.tif"}, "classes": "{dir}/classes.tif"}),
        r"inputs\.scene_regex: not a regular expression"),
    "unknown placeholder": (
        lambda s: _chain(s, inputs={"images": ["scene/image.tif"], "angles": {"path": "{folder}/angles.tif"},
                                    "classes": "{dir}/classes.tif"}),
        r"inputs\.angles\.path: pattern '\{folder\}/angles\.tif' uses \{folder\}; allowed placeholders"),
    "not YAML": (lambda s: _chain_text(s, "inputs: {images: [a\n"), r"chain\.yaml: not valid YAML \(line 2"),
    "python tag (YAML loaded safely)": (
        lambda s: _chain_text(s, "inputs: !!python/object/apply:os.system ['touch pwned']\n"),
        r"chain\.yaml: not valid YAML \(line 1, column 9\): the tag !!python/object/apply:os\.system is not allowed"),
    "not a mapping": (lambda s: _chain_text(s, "just text\n"),
                      r"chain\.yaml: expected a mapping of sections \(inputs, outputs, \.\.\.\), got str"),
    "fit output is the parameter table": (
        lambda s: _chain(s, outputs={"directory": "scene"},
                         steps={"fit": {"source": "imagery", "output": "params.yaml"}, "correct": {}}),
        r"chain\.yaml: steps\.fit\.output \S*scene/params\.yaml would overwrite an input"),
    "bad parameter table": (
        lambda s: _chain(s, parameters={"table": str(_table(s, TABLE_TS % ", sigma: 3"))}),
        r"bad\.yaml: class 1 \(tile\): torrance_sparrow: unknown parameter 'sigma'"),
}


@pytest.mark.parametrize("case", list(RUN_CASES))
def test_run_bad_config(scene, case, monkeypatch):
    build, pattern = RUN_CASES[case]
    monkeypatch.chdir(scene["dir"].parent)
    chain = build(scene)
    before = file_digests(scene["dir"])
    result = CliRunner().invoke(main, ["run", str(chain)])
    assert result.exit_code == 2, result.output
    line = _one_error_line(result)
    assert re.search(pattern, line), line
    assert not (scene["dir"].parent / "chain_out").exists()
    assert file_digests(scene["dir"]) == before
    assert not (scene["dir"].parent / "pwned").exists()


def test_bad_override_value(scene):
    chain = _chain(scene)
    result = CliRunner().invoke(main, ["run", str(chain), "--set", "engine.workers=many"])
    assert result.exit_code == 2
    assert re.search(r"engine\.workers: Input should be a valid integer.*\(got 'many'\)", _one_error_line(result))


# ---------------------------------------------------------------------- internal errors, --debug
def test_internal_error_is_one_line_exit_1_and_traceback_only_with_debug(scene, monkeypatch):
    """A bug (any exception that is not a BrdfcorrError) is exit 1, not 2: the input may be fine."""
    import brdfcorr.tasks.correct

    def broken(*args, **kwargs):
        raise ZeroDivisionError("simulated bug")

    monkeypatch.setattr(brdfcorr.tasks.correct, "normalize", broken)
    result = CliRunner().invoke(main, _correct_args(scene))
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        "brdfcorr: internal error: ZeroDivisionError: simulated bug (rerun with --debug for the traceback)"]
    result = CliRunner().invoke(main, ["--debug"] + _correct_args(scene))
    assert result.exit_code == 1
    assert "Traceback (most recent call last)" in result.stderr and "in broken" in result.stderr
    assert result.stderr.splitlines()[-1] == "brdfcorr: internal error: ZeroDivisionError: simulated bug"
    assert list(scene["out"].iterdir()) == []


def test_debug_shows_the_traceback_of_a_bad_input_too(scene):
    result = CliRunner().invoke(main, ["--debug"] + _correct_args(scene, image=scene["dir"] / "nope.tif"))
    assert result.exit_code == 2
    assert "Traceback (most recent call last)" in result.stderr and "InputError" in result.stderr
    assert result.stderr.splitlines()[-1].startswith("brdfcorr: error: image file ")


def test_every_command_shares_the_handler(monkeypatch):
    """Commands without their own decorator (``models``) still map a bug to exit 1."""
    import brdfcorr.models

    def broken():
        raise RuntimeError("simulated registry bug")

    monkeypatch.setattr(brdfcorr.models, "parameter_table_rows", broken)
    result = CliRunner().invoke(main, ["models"])
    assert result.exit_code == 1
    assert result.stderr.splitlines()[-1].startswith("brdfcorr: internal error: RuntimeError: simulated registry bug")


def test_help_documents_the_exit_codes():
    result = CliRunner().invoke(main, ["--help"])
    text = " ".join(result.output.split())
    assert "Exit codes: 0 success; 2 bad input" in text and "1 internal error" in text and "3 run: some scenes failed" in text


# ----------------------------------------------------- pixel-level problems: nodata, counted, QA
def test_nan_and_inf_reflectance_become_nodata_and_are_counted(scene):
    data, profile = _read(scene["image"])
    data[0, 3, 5] = np.nan
    data[2, 7, 9] = np.inf
    data[3, 11, 13] = -np.inf
    data[1, 11, 13] = np.nan  # NaN and inf in one pixel
    image = _write(scene["dir"] / "image_bad.tif", data, profile)
    qa_path = scene["out"] / "qa.tif"
    result = CliRunner().invoke(main, _correct_args(scene, image=image, **{"--qa": qa_path}))
    assert result.exit_code == 0, result.output
    corrected, _ = _read(scene["output"])
    qa, _ = _read(qa_path)
    bad = np.zeros((NY, NX), bool)
    bad[3, 5] = bad[7, 9] = bad[11, 13] = True
    assert (qa[0][bad] & 1).all() and not (qa[0][~bad] & 1).any()  # QA bit 1: nodata
    # The band with NaN/inf is nodata (NaN) in the output, never inf; the other bands are corrected.
    assert np.isnan(corrected[0, 3, 5]) and np.isnan(corrected[2, 7, 9]) and np.isnan(corrected[3, 11, 13])
    assert np.isfinite(corrected[1, 3, 5]) and np.isfinite(corrected[0, 7, 9])
    assert np.isfinite(corrected[:, ~bad]).all()
    assert "3 nodata" in result.output.splitlines()[-1]


def test_zeniths_outside_the_domain_are_flagged_not_fatal(scene):
    """A few pixels with sza >= 90 (sun below the horizon) or a negative vza: QA invalid_geometry
    (16) and nodata output, counted; the rest of the scene is corrected (``DESIGN.md``)."""
    data, profile = _read(scene["angles"])
    data[0, 0, :4] = 90.0
    data[0, 1, :4] = 120.0
    data[2, 2, :4] = -5.0
    angles = _write(scene["dir"] / "angles_edge.tif", data, profile)
    qa_path = scene["out"] / "qa.tif"
    result = CliRunner().invoke(main, _correct_args(scene, **{"--angles": angles, "--qa": qa_path}))
    assert result.exit_code == 0, result.output
    corrected, _ = _read(scene["output"])
    qa, _ = _read(qa_path)
    invalid = np.zeros((NY, NX), bool)
    invalid[:3, :4] = True
    assert ((qa[0] & 16) > 0).tolist() == invalid.tolist()
    assert np.isnan(corrected[:, invalid]).all() and np.isfinite(corrected[:, ~invalid]).all()
    assert "12 nodata" in result.output.splitlines()[-1]


def test_run_isolates_a_scene_with_bad_angles(scene, monkeypatch):
    """In a batch, a scene whose angles are in radians fails with the message in the report (exit
    3, the documented contract of ``run``) and writes nothing; the good scene is corrected."""
    import json

    bad = scene["dir"].parent / "bad_scene"
    shutil.copytree(scene["dir"], bad)
    data, profile = _read(bad / "angles.tif")
    _write(bad / "angles.tif", np.deg2rad(data).astype(data.dtype), profile)
    monkeypatch.chdir(scene["dir"].parent)
    chain = _chain(scene, inputs={"images": ["*/image.tif"], "angles": {"path": "{dir}/angles.tif"},
                                  "classes": "{dir}/classes.tif", "scene_regex": None})
    before = {**file_digests(scene["dir"]), **{f"bad/{k}": v for k, v in file_digests(bad).items()}}
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 3, result.output
    output_dir = scene["dir"].parent / "chain_out"
    report = json.loads((output_dir / "run_report.json").read_text())
    status = {item["scene"]: item for item in report["scenes"]}
    assert status["scene_image"]["status"] == "ok"
    assert status["bad_scene_image"]["status"] == "failed"
    assert "the angles look like radians" in status["bad_scene_image"]["error"]
    assert sorted(p.name for p in output_dir.iterdir()) == ["run_report.json", "scene_image_brdf.tif",
                                                            "scene_image_qa.tif"]
    assert {**file_digests(scene["dir"]), **{f"bad/{k}": v for k, v in file_digests(bad).items()}} == before


def test_only_non_finite_values_are_nodata_even_when_the_band_sum_overflows():
    """Finite float32 values whose band sum overflows (3e38 + 3e38) are data, not nodata; a pixel
    with +inf is nodata. Class 0 (no class, kept: factor 1) so the values pass unchanged."""
    from brdfcorr.correction import QA, normalize

    cube = np.full((2, 1, 3), 0.5, dtype=np.float32)
    cube[:, 0, 0] = 3e38
    cube[1, 0, 1] = np.inf
    zeros = np.zeros((1, 3))
    table = ParameterTable(classes=[{"id": 1, "name": "flat", "model": "lambertian", "params": {"t0": 0.1}}])
    angles = {"sza": zeros + 30, "saa": zeros, "vza": zeros + 10, "vaa": zeros}
    corrected, qa = normalize(cube, np.zeros((1, 3), np.uint8), angles, table)
    assert qa.values.tolist() == [[0 | 2, QA.NODATA | 2, 2]]  # 2: no class
    np.testing.assert_array_equal(corrected.values[:, 0, 0], cube[:, 0, 0])
    assert corrected.values[0, 0, 1] == 0.5 and np.isnan(corrected.values[1, 0, 1])


TOPOFLUX = Path(__file__).parents[1] / "data" / "isofit_avirisng_topoflux"


def test_a_flip_of_the_azimuths_a_sensor_reader_gives_is_refused(tmp_path):
    # The envi_obs reader gives JPL's to-sensor azimuths (pixel -> sensor) as brdfcorr wants them:
    # flipped, the real line's 852 nm band came out up to 2.4 % off, without a word (and with the
    # reader's view_azimuth=from_sensor the two flips cancelled).
    from brdfcorr.analysis.view_angles import ViewAngleOptions
    from brdfcorr.chain.config import ChainConfig
    from brdfcorr.errors import ConfigError, InputError
    from brdfcorr.fit.settings import Sampling
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.assess import assess_files
    from brdfcorr.tasks.fit import SceneFiles, fit_class_files

    image, obs = TOPOFLUX / "ang20160910t185702_2rdn_img", TOPOFLUX / "ang20160910t185702_obs_ortdem_mod"
    result = CliRunner().invoke(main, ["correct", str(image), "--angles", str(obs), "--angles-kind", "envi_obs",
                                       "--params", "roy2016", "--flip-view-azimuth", "-o", str(tmp_path / "o.tif")])
    assert result.exit_code == 2
    assert re.fullmatch(r"brdfcorr: error: --flip-view-azimuth is for angle rasters stored another way \(angles kind "
                        r"geotiff\): the envi_obs reader gives view azimuths from the pixel towards the sensor "
                        r"already; leave it out \(docs/sensors\.md\)", _one_error_line(result))
    assert list(tmp_path.iterdir()) == []
    sources = dict(image=image, classes=None, angles=obs, angles_kind="envi_obs")
    with pytest.raises(InputError, match=r"^flip_view_azimuth=True is for angle rasters stored another way"):
        fit_class_files([SceneFiles(**sources)], "ross_thick_li_sparse", sampling=Sampling(flip_view_azimuth=True))
    with pytest.raises(InputError, match="the envi_obs reader gives view azimuths"):
        assess_files(SceneSources(**sources), tmp_path / "after.tif",
                     view_options=ViewAngleOptions(flip_view_azimuth=True))
    chain = {"inputs": {"images": ["line.img"], "angles": {"kind": "envi_obs", "path": "line_obs"},
                        "flip_view_azimuth": True}, "parameters": {"table": "roy2016"}, "steps": {"correct": {}},
             "outputs": {"directory": "out"}}
    with pytest.raises(ConfigError, match="inputs.flip_view_azimuth is for angle rasters stored another way"):
        ChainConfig.from_dict(chain)
    # Angle rasters (kind geotiff) take the flag, as documented, and so does the solar kind, whose view
    # azimuth is the number given.
    SceneSources(**{**sources, "angles_kind": "geotiff"}).check_flip(True)
    SceneSources(**{**sources, "angles_kind": "solar"}).check_flip(True)
