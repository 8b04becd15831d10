"""An ENVI header says only what is true (issue 26): it cannot say "sheared" or "no CRS", so such
outputs are refused (exit 2, one ``brdfcorr: error:`` line, nothing written), not written wrong; its
``description`` names the output, not its temporary file, and a folder name with ``}`` and a line
break cannot add header fields.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import rasterio
from _cli_lines import _correct_args, _one_line
from affine import Affine
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.testing import file_digests

# The scene: a copy of the 32 x 32 template of tests/conftest.py, 4 bands of float32: 16 384 bytes of data.


# ----------------------------------------------------------------------------- ENVI headers
def _regrid(scene, transform: Affine, crs) -> None:
    """Rewrite the scene's image, angles and class map with another geotransform and CRS."""
    for key in ("image", "angles", "classes"):
        with rasterio.open(scene[key]) as source:
            profile, values, descriptions = source.profile, source.read(), source.descriptions
        profile.update(transform=transform, crs=crs)
        scene[key].unlink()
        with rasterio.open(scene[key], "w", **profile) as target:
            target.write(values)
            target.descriptions = descriptions


@pytest.mark.parametrize("transform, crs, pattern", [
    (Affine(10.0, 3.0, 500_000.0, 0.0, -10.0, 5_400_000.0), "EPSG:32632", "the image's geotransform is sheared"),
    (Affine(10.0, 0.0, 500_000.0, 0.0, -10.0, 5_400_000.0), None, "the image has no CRS"),
    # GDAL writes these as rotation=90 and rotation=180 and reads them back as other grids: the
    # far column 310 m (x mirrored) and 620 m (turned by 180 degrees) from where it lies.
    (Affine(-10.0, 0.0, 500_320.0, 0.0, -10.0, 5_400_000.0), "EPSG:32632",
     "an ENVI header does not hold the image's geotransform"),
    (Affine(-10.0, 0.0, 500_320.0, 0.0, 10.0, 5_399_680.0), "EPSG:32632",
     "an ENVI header does not hold the image's geotransform"),
    # GDAL reads EPSG:2263 (US survey feet) back in international feet: 0.6 m off at 980 000 ft.
    (Affine(10.0, 0.0, 980_000.0, 0.0, -10.0, 200_000.0), "EPSG:2263",
     r"an ENVI header does not hold the image's CRS \(EPSG:2263: GDAL reads it back as another"),
])
def test_envi_refuses_what_its_header_cannot_say(scene, transform, crs, pattern):
    _regrid(scene, transform, crs)
    output = scene["out"] / "c.img"
    before = file_digests(scene["dir"])
    result = CliRunner().invoke(main, _correct_args(scene, output, "--format", "ENVI"))
    assert result.exit_code == 2, result.output
    _one_line(result.stderr, rf"ENVI output {re.escape(str(output))}: {pattern}")
    assert list(scene["out"].iterdir()) == [] and file_digests(scene["dir"]) == before
    # A GeoTIFF holds both as they are.
    result = CliRunner().invoke(main, _correct_args(scene, scene["out"] / "c.tif"))
    assert result.exit_code == 0, result.output
    with rasterio.open(scene["out"] / "c.tif") as written:
        assert written.transform == transform and written.crs == (crs and rasterio.crs.CRS.from_string(crs))


def test_envi_writes_a_south_up_grid_that_reads_back_as_written(scene):
    south_up = Affine(10.0, 0.0, 500_000.0, 0.0, 10.0, 5_399_680.0)
    _regrid(scene, south_up, "EPSG:32632")
    result = CliRunner().invoke(main, _correct_args(scene, scene["out"] / "c.img", "--format", "ENVI"))
    assert result.exit_code == 0, result.output
    with rasterio.open(scene["out"] / "c.img") as written:
        assert written.transform == south_up


def _header_fields(path: Path) -> dict[str, str]:
    """An ENVI header's fields (``key = value``, a ``{...}`` value may span lines)."""
    text = path.read_text()
    assert text.startswith("ENVI\n")
    return {key.strip(): value.strip() for key, value in
            re.findall(r"^([^=\n{}]+?)\s*=\s*(\{[^}]*\}|[^\n]*)$", text[5:], flags=re.M)}


def test_envi_header_names_the_output_and_no_folder_adds_fields(scene):
    folder = scene["out"] / "x}\ndata gain values = {2, 2, 2, 2}"
    folder.mkdir()
    output = folder / "c.img"
    result = CliRunner().invoke(main, _correct_args(scene, output, "--format", "ENVI"))
    assert result.exit_code == 0, result.output
    fields = _header_fields(folder / "c.hdr")
    assert "data gain values" not in fields
    assert fields["description"] == "{\nbrdfcorr output c.img}" and "partial" not in fields["description"]
    assert fields["bands"] == "4" and fields["band names"] == "{\n480 nm,\n560 nm,\n660 nm,\n830 nm}"
    with rasterio.open(output) as envi, rasterio.open(scene["image"]) as image:
        assert envi.count == image.count == 4  # not doubled


def test_files_gdal_would_read_with_an_output_are_refused_or_replaced(scene):
    """A header ``c.img.hdr`` (which GDAL prefers to the ``c.hdr`` written), overviews ``.ovr`` and
    a mask ``.msk`` left beside an output were read with the new file: values 0.6 off, no CRS,
    the old overviews, half its pixels masked; the header ``c.hdr`` of another data file (``c.bsq``)
    was replaced. Without --overwrite they are refused, with it removed (or replaced)."""
    envi = ("--format", "ENVI")
    for target, name, extra in (("c.img", "c.img.hdr", envi), ("c.img", "c.img.ovr", envi), ("c.tif", "c.tif.msk", ()),
                                ("c.tif", "c.tif.ovr", ()), ("c.img", "c.hdr", envi)):  # the header of a c.bsq
        output, stale = scene["out"] / target, scene["out"] / name
        stale.write_bytes(b"left from an earlier file")
        result = CliRunner().invoke(main, _correct_args(scene, output, *extra))
        assert result.exit_code == 2, result.output
        _one_line(result.stderr, rf"output {re.escape(str(stale))} exists; give --overwrite to replace it")
        result = CliRunner().invoke(main, _correct_args(scene, output, *extra, "--overwrite"))
        assert result.exit_code == 0, result.output
        assert not stale.exists() or name == "c.hdr"  # replaced by the output's own header
        with rasterio.open(output) as written, rasterio.open(scene["image"]) as image:
            assert written.crs == image.crs and written.transform == image.transform
            assert [Path(f).name for f in written.files if Path(f).suffix in (".ovr", ".msk")] == []
        for path in scene["out"].iterdir():
            path.unlink()


def test_a_crs_no_operation_relates_is_another_place():
    # A local CRS read back as another: rasterio's transform raised GDAL's "cannot find coordinate
    # operations" through the command (exit 1) instead of the refusal (exit 2).
    from rasterio.crs import CRS

    from brdfcorr.io.envi_output import _same_place

    local = CRS.from_wkt('LOCAL_CS["site grid",LOCAL_DATUM["site",0],UNIT["metre",1],AXIS["Easting",EAST],'
                         'AXIS["Northing",NORTH]]')
    assert _same_place(CRS.from_epsg(32632), local, 1000.0, 2000.0, 1.0) is False
    assert _same_place(CRS.from_epsg(32632), CRS.from_epsg(32632), 500000.0, 5400000.0, 10.0) is True
