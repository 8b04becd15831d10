"""ENVI output (issue 16): ``correct --format ENVI`` and chains with ``outputs.format: ENVI`` write a
data file and its header atomically, with the GeoTIFF's numbers and georeference and the wavelengths
in the header; extensions must fit the format; an ENVI input's header is not copied into tags."""

from __future__ import annotations

import re

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.io import band_wavelengths, open_image
from brdfcorr.testing import synthetic_scene

WAVELENGTHS = [480.0, 560.0, 660.0, 830.0]  # synthetic_scene's default band centres [nm]


@pytest.fixture(scope="module")
def files(tmp_path_factory, write_example_scene):
    return write_example_scene(tmp_path_factory.mktemp("envi"), synthetic_scene(ny=40, nx=48, wavelengths=WAVELENGTHS))


def _correct(files, output, *extra, image=None):
    args = ["correct", image or files["image"], "--angles", files["angles"], "--classes", files["classes"],
            "--params", files["params"], "-o", output, "--chunk", 16, "--no-progress", *extra]
    return CliRunner().invoke(main, [str(a) for a in args])


def _header(path) -> dict[str, str]:
    """The fields of an ENVI header (``key = value``, ``{...}`` values may span lines)."""
    text = path.read_text()
    assert text.startswith("ENVI")
    return {key.strip(): " ".join(value.split()) for key, value in
            re.findall(r"^([^=\n]+?)\s*=\s*(\{[^}]*\}|[^\n]*)", text, flags=re.MULTILINE)}


def _numbers(field: str) -> list[float]:
    return [float(value) for value in field.strip("{}").split(",")]


@pytest.fixture(scope="module")
def geotiff(files, tmp_path_factory):
    output = tmp_path_factory.mktemp("gtiff") / "out.tif"
    result = _correct(files, output)
    assert result.exit_code == 0, result.output
    return output


@pytest.mark.parametrize("interleave", ["bsq", "bil"])
def test_envi_output_equals_the_geotiff_and_has_a_header(files, geotiff, tmp_path, interleave):
    output = tmp_path / "out.img"
    result = _correct(files, output, "--format", "ENVI", "--interleave", interleave)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.hdr", "out.img", "out.img.aux.xml"]  # no .partial
    with rasterio.open(output) as envi, rasterio.open(geotiff) as gtiff:
        assert envi.driver == "ENVI" and envi.dtypes == gtiff.dtypes == ("float32",) * 4
        assert envi.crs == gtiff.crs and envi.transform == gtiff.transform
        np.testing.assert_array_equal(envi.read(), gtiff.read())  # NaN where the GeoTIFF has NaN
        assert envi.tags()["brdf_reference"] == gtiff.tags()["brdf_reference"]  # provenance in .aux.xml
        assert envi.descriptions == gtiff.descriptions

    header = _header(tmp_path / "out.hdr")
    assert header["interleave"] == interleave
    assert header["data type"] == "4"  # float32
    assert header["data ignore value"] == "nan"
    assert header["wavelength units"] == "Nanometers"
    assert _numbers(header["wavelength"]) == WAVELENGTHS
    assert header["map info"].startswith("{UTM") and "coordinate system string" in header
    assert "band names" in header
    np.testing.assert_array_equal(band_wavelengths(open_image(output), output), WAVELENGTHS)
    # The header alone gives them too (without the .aux.xml's tags).
    (tmp_path / "out.img.aux.xml").unlink()
    np.testing.assert_array_equal(band_wavelengths(open_image(output), output), WAVELENGTHS)


@pytest.mark.parametrize("name, extra", [("out.tif", ["--format", "ENVI"]), ("out.img", []),
                                         ("out.bsq", ["--format", "GTiff"])])
def test_an_extension_of_another_format_is_refused(files, tmp_path, name, extra):
    result = _correct(files, tmp_path / name, *extra)
    assert result.exit_code == 2, result.output
    assert len(result.output.strip().splitlines()) == 1 and "does not fit format" in result.output
    assert list(tmp_path.iterdir()) == []


def test_envi_without_extension_writes_name_and_name_hdr(files, tmp_path):
    result = _correct(files, tmp_path / "cube", "--format", "ENVI")
    assert result.exit_code == 0, result.output
    assert {"cube", "cube.hdr"} <= {p.name for p in tmp_path.iterdir()}
    assert not [p for p in tmp_path.iterdir() if "partial" in p.name]


def test_chain_writes_envi_outputs(tmp_path, make_scenes, write_chain):
    scenes = make_scenes(tmp_path, count=2)
    chain = write_chain(tmp_path, outputs={"directory": "out", "format": "ENVI",
                                           "naming": "{parent}_brdf.img", "qa_naming": "{parent}_qa.tif"})
    result = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert result.exit_code == 0, result.output
    for name in scenes:
        output = tmp_path / "out" / f"{name}_brdf.img"
        with rasterio.open(output) as dataset:
            assert dataset.driver == "ENVI" and dataset.count == 4
        assert _header(tmp_path / "out" / f"{name}_brdf.hdr")["interleave"] == "bsq"
        with rasterio.open(tmp_path / "out" / f"{name}_qa.tif") as dataset:
            assert dataset.driver == "GTiff"
    assert not [p for p in (tmp_path / "out").iterdir() if "partial" in p.name]
    # A second run resumes: the outputs (and their fingerprints in .aux.xml) are recognised.
    again = CliRunner().invoke(main, ["run", str(chain), "--no-progress"])
    assert again.exit_code == 0, again.output


def test_chain_envi_default_naming_and_mismatch(tmp_path):
    from brdfcorr.chain.config import OutputsConfig
    from brdfcorr.errors import ConfigError

    assert OutputsConfig(directory="out", format="ENVI").naming == "{scene}_brdf.img"
    for bad in ({"format": "ENVI", "naming": "{scene}.tif"}, {"naming": "{scene}.img"},
                {"format": "ENVI", "cog": True}):
        with pytest.raises((ValueError, ConfigError)):
            OutputsConfig(directory="out", **bad)


def _envi_copy(files, image, **header):
    """The example image as an ENVI file ``image`` with ``header`` items; returns its path."""
    with rasterio.open(files["image"]) as source:
        profile, data = source.profile, source.read()
    for key in ("tiled", "blockxsize", "blockysize", "compress", "interleave"):
        profile.pop(key, None)
    with rasterio.open(image, "w", **{**profile, "driver": "ENVI"}) as envi:
        envi.write(data)
        envi.update_tags(ns="ENVI", **header)
    return image


def test_envi_input_header_is_not_copied_into_geotiff_tags(files, tmp_path):
    image = _envi_copy(files, tmp_path / "input.img", wavelength="{480, 560, 660, 830}", fwhm="{10, 10, 10, 10}",
                       wavelength_units="Nanometers")
    output = tmp_path / "out.tif"
    result = _correct(files, output, image=image)
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as dataset:
        tags = dataset.tags()
    assert not [key for key in tags if re.fullmatch(r"Band_\d+", key)]
    for key in ("interleave", "file_type", "map_info", "samples", "data_type", "band_names"):
        assert key not in tags, key
    assert tags["wavelength"] == "480,560,660,830" and tags["wavelength_units"] == "nm"  # brdfcorr's own
    # The band widths are brdfcorr's own too (in nm, as the centres), and read back as the image's.
    assert tags["fwhm"] == "10,10,10,10"
    np.testing.assert_array_equal(open_image(output)["fwhm"].values, [10.0] * 4)
    assert "fwhm" not in open_image(output).attrs

    # ... and the ENVI output of an ENVI input carries the input's fwhm in its header.
    result = _correct(files, tmp_path / "out.bsq", "--format", "ENVI", image=image)
    assert result.exit_code == 0, result.output
    assert _numbers(_header(tmp_path / "out.hdr")["fwhm"]) == [10.0] * 4


PRECISE = [452.3456789, 560.25, 660.125, 831.45678]  # band centres :g wrote as 452.346, ..., 831.457


@pytest.mark.parametrize("name, extra", [("out.tif", []), ("out.img", ["--format", "ENVI"])])
def test_band_centres_read_back_exactly_from_either_format(tmp_path, write_example_scene, name, extra):
    files = write_example_scene(tmp_path / "scene", synthetic_scene(ny=16, nx=16, wavelengths=PRECISE))
    output = tmp_path / name
    result = _correct(files, output, *extra)
    assert result.exit_code == 0, result.output
    np.testing.assert_array_equal(open_image(output)["wavelength"].values, PRECISE)
    with rasterio.open(output) as written:
        assert [float(text.split()[0]) for text in written.descriptions] == PRECISE


def test_an_envi_output_s_header_is_the_one_place_of_its_fields(files, tmp_path):
    # GDAL reads an .aux.xml over the header: the copy it kept there (every header field, the
    # temporary file's name, the wavelengths among the tags) outlived a later edit of the header.
    output = tmp_path / "out.img"
    result = _correct(files, output, "--format", "ENVI")
    assert result.exit_code == 0, result.output
    aux = (tmp_path / "out.img.aux.xml").read_text()
    assert 'domain="ENVI"' not in aux and ".partial" not in aux and 'key="wavelength' not in aux
    header = tmp_path / "out.hdr"
    text = header.read_text()
    assert "wavelength = {480, 560, 660, 830}" in text and "data ignore value = nan" in text
    header.write_text(text.replace("wavelength = {480, 560, 660, 830}", "wavelength = {481, 561, 661, 831}")
                      .replace("data ignore value = nan", "data ignore value = 0"))
    np.testing.assert_array_equal(open_image(output)["wavelength"].values, [481, 561, 661, 831])
    with rasterio.open(output) as edited:
        assert edited.nodata == 0 and edited.tags()["brdf_reference"]  # the provenance stays in the .aux.xml


def test_the_band_widths_of_an_envi_input_in_micrometres_reach_a_geotiff_and_read_back(files, tmp_path):
    # FWHM were carried to ENVI outputs only: an AVIRIS-NG line corrected to a GeoTIFF lost them.
    image = _envi_copy(files, tmp_path / "input.img", wavelength="{0.48, 0.56, 0.66, 0.83}",
                       fwhm="{0.0101, 0.0102, 0.0103, 0.0104}", wavelength_units="Micrometers")
    widths = [10.1, 10.2, 10.3, 10.4]
    geotiff = tmp_path / "out.tif"
    assert _correct(files, geotiff, image=image).exit_code == 0
    with rasterio.open(geotiff) as dataset:
        assert [float(value) for value in dataset.tags()["fwhm"].split(",")] == pytest.approx(widths, rel=1e-12)
    np.testing.assert_allclose(open_image(geotiff)["fwhm"].values, widths, rtol=1e-12)


def test_a_fwhm_tag_that_is_not_one_width_per_band_is_refused(files, tmp_path):
    from brdfcorr.errors import InputError

    with rasterio.open(files["image"]) as source:
        profile, data = source.profile, source.read()
    image = tmp_path / "widths.tif"
    with rasterio.open(image, "w", **profile) as written:
        written.write(data)
        written.update_tags(wavelength="480,560,660,830", fwhm="10,10")
    with pytest.raises(InputError, match="not one positive width per band"):
        open_image(image)
