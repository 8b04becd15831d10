"""An output replaces no input (issue 26): the sidecars GDAL reads beside an input (an ENVI header in
both namings, ``.aux.xml``) are inputs, and ``materials -o`` follows the overwrite rule of every output
and keeps a symbolic link a link. A refusal is exit code 2 with exactly one stderr line
``brdfcorr: error: ...`` naming the file, nothing written and the inputs byte-identical.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import rasterio
from _cli_lines import _correct_args, _one_line
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.io.paths import InputOverwriteError, SidecarClashError, check_outputs
from brdfcorr.params import ParameterTable
from brdfcorr.testing import file_digests

# The scene: a copy of the 32 x 32 template of tests/conftest.py, 4 bands of float32: 16 384 bytes of data.


# ------------------------------------------------------------------------ sidecars are inputs
def _envi_input(scene, header_name: str) -> Path:
    """The scene's image as an ENVI file ``in.img`` with its header at ``header_name``."""
    image = scene["dir"] / "in.img"
    rasterio.shutil.copy(scene["image"], image, driver="ENVI")
    if header_name != "in.hdr":
        (scene["dir"] / "in.hdr").rename(scene["dir"] / header_name)
    return image


@pytest.mark.parametrize("header, output", [("in.img.hdr", "in.img.bsq"), ("in.hdr", "in.bsq")])
def test_envi_output_header_never_replaces_an_input_header(scene, header, output):
    """GDAL finds an ENVI header as NAME.hdr or NAME.ext.hdr; the output in.img.bsq writes in.img.hdr."""
    image = _envi_input(scene, header)
    with rasterio.open(image) as dataset:  # GDAL reads the header of either naming
        assert dataset.driver == "ENVI" and dataset.count == 4
    before = file_digests(scene["dir"])
    args = _correct_args({**scene, "image": image}, scene["dir"] / output, "--format", "ENVI")
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, rf"output header \S*{re.escape(header)} is also an input")
    assert file_digests(scene["dir"]) == before
    assert not (scene["dir"] / output).exists()


def test_envi_output_header_never_becomes_an_input_header(scene):
    """The input in.img with its header in.hdr: an output in.img.bsq writes its header as in.img.hdr,
    the naming GDAL looks for first when it opens in.img, so that header would become the input's
    from then on (every later read of in.img scrambled). Refused, though no in.img.hdr exists yet."""
    image = _envi_input(scene, "in.hdr")
    before = file_digests(scene["dir"])
    args = _correct_args({**scene, "image": image}, scene["dir"] / "in.img.bsq", "--format", "ENVI")
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, r"output header \S*in\.img\.hdr would become the ENVI header GDAL reads with "
                             r"\S* \S*in\.img\b")
    assert file_digests(scene["dir"]) == before  # nothing written, nothing changed
    with rasterio.open(image) as dataset:  # the input still reads with its own header
        assert [Path(name).name for name in dataset.files if name.endswith(".hdr")] == ["in.hdr"]


def test_report_on_an_input_aux_xml_is_refused(scene):
    aux = Path(f"{scene['image']}.aux.xml")
    aux.write_text('<PAMDataset><Metadata><MDI key="a">1</MDI></Metadata></PAMDataset>\n')
    before = file_digests(scene["dir"])
    args = ["fit-classes", scene["image"], "--angles", scene["angles"], "--classes", scene["classes"],
            "-o", scene["out"] / "t.yaml", "--report", aux]
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, r"--report \S*image\.tif\.aux\.xml is also an input")
    assert file_digests(scene["dir"]) == before and list(scene["out"].iterdir()) == []


@pytest.mark.parametrize("suffix", [".hdr", ".aux.xml", ".ovr", ".msk"])
def test_guard_knows_every_sidecar(tmp_path, suffix):
    image = tmp_path / "image.img"
    image.write_bytes(b"\0")
    sidecar = Path(f"{image}{suffix}")
    sidecar.write_text("x")
    with pytest.raises(InputOverwriteError, match="is also an input"):
        check_outputs({"report": sidecar}, {"image": image})
    sidecar.unlink()  # absent: written, it would become the image's sidecar
    with pytest.raises(SidecarClashError, match=rf"report \S*image\.img{re.escape(suffix)} would become the .* "
                                                rf"GDAL reads with image \S*image\.img"):
        check_outputs({"report": sidecar}, {"image": image})


# -------------------------------------------------------------------------------- materials -o
def test_materials_output_follows_the_overwrite_rule(tmp_path):
    table = tmp_path / "table.yaml"
    table.write_text("# my notes\nclasses:\n  - {id: 1, name: tiles, material: roof_tile}\n")
    before = table.read_bytes()
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(table)])
    assert result.exit_code == 2
    _one_line(result.stderr, rf"output {re.escape(str(table))} exists; give --overwrite")
    assert table.read_bytes() == before
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(table), "--overwrite"])
    assert result.exit_code == 0, result.output
    assert ParameterTable.load(table).class_ids == (1, 2)


def test_materials_output_keeps_a_symbolic_link_a_link(tmp_path):
    real = tmp_path / "tables" / "real.yaml"
    real.parent.mkdir()
    ParameterTable().with_class({"id": 1, "material": "roof_tile"}).save(real)
    link = tmp_path / "table.yaml"
    link.symlink_to(real)
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(link), "--overwrite"])
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and link.resolve() == real.resolve()
    assert ParameterTable.load(real).class_ids == (1, 2)
    dangling = tmp_path / "nothing.yaml"
    dangling.symlink_to(tmp_path / "missing.yaml")
    result = CliRunner().invoke(main, ["materials", "red_concrete", "-o", str(dangling)])
    assert result.exit_code == 2
    _one_line(result.stderr, "is a symbolic link to no file")
    assert dangling.is_symlink() and not (tmp_path / "missing.yaml").exists()


def test_an_envi_output_beside_a_geotiff_of_its_name_is_allowed(tmp_path):
    # GDAL identifies a GeoTIFF by its own header and reads no ENVI .hdr with it: the header of an
    # output image.img (image.hdr) changes nothing image.tif reads, so it is no clash; its .aux.xml is.
    image = tmp_path / "image.tif"
    image.write_bytes(b"\0")
    check_outputs({"-o": tmp_path / "image.img", "header": tmp_path / "image.hdr"}, {"image": image})
    (tmp_path / "stack.vrt").write_text("<VRTDataset/>")  # a VRT likewise (GDAL knows it by its content)
    check_outputs({"header": tmp_path / "stack.hdr"}, {"image": tmp_path / "stack.vrt"})
    with pytest.raises(SidecarClashError):
        check_outputs({"tags": tmp_path / "image.tif.aux.xml"}, {"image": image})
