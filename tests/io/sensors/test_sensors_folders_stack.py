"""The band stack of a product folder (``brdfcorr nbar --keep-stack``) is an output like every other
(issue 26): guarded (:func:`brdfcorr.io.paths.check_outputs`: no product file, no directory) and
written to temporary names renamed when complete, its mask before the VRT that reads it, so a
failed write leaves no stack and an existing one untouched."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

from brdfcorr.errors import OutputError
from brdfcorr.io.paths import InputOverwriteError
from brdfcorr.io.sensors import folders
from brdfcorr.io.sensors.folders import find_product, write_stack
from brdfcorr.testing import file_digests, write_landsat_c2


@pytest.fixture
def product(tmp_path):
    """A synthetic Landsat 7 C2 L2 folder (its first QA_PIXEL row cloud), found with its default mask."""
    return find_product(write_landsat_c2(tmp_path / "in", size=16, angle_bands=True))


def test_the_stack_reads_the_masked_dns_and_leaves_no_temporary_file(product, tmp_path):
    target = tmp_path / "out" / "stack.vrt"
    target.parent.mkdir()
    assert write_stack(product, target) == target
    assert sorted(path.name for path in target.parent.iterdir()) == ["stack.vrt", "stack_mask.tif"]
    # Independent expectation: each band's stored DNs, 0 (no data) where a masked QA_PIXEL bit is set.
    with rasterio.open(product.mask) as dataset:
        qa = dataset.read(1)
    masked = (qa & sum(1 << bit for bit in product.masked)) != 0
    assert masked[0].all() and not masked[1:].any()  # the folder's cloud row
    with rasterio.open(target) as stack:
        assert stack.count == len(product.bands)
        for index, path in enumerate(product.bands.values(), start=1):
            with rasterio.open(path) as band:
                expected = np.where(masked, 0, band.read(1))
            np.testing.assert_array_equal(stack.read(index), expected)


def test_a_failed_write_leaves_the_old_stack_and_no_temporary_file(product, tmp_path, monkeypatch):
    target = tmp_path / "stack.vrt"
    write_stack(product, target)
    before = file_digests(tmp_path)

    def failing(*args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(folders, "_stack_xml", failing)
    with pytest.raises(OutputError, match=r"cannot write .*stack\.vrt: No space left on device"):
        write_stack(product, target)
    # The stack and its mask are untouched, and nothing half-written stays beside them.
    assert file_digests(tmp_path) == before
    fresh = tmp_path / "fresh" / "stack.vrt"
    fresh.parent.mkdir()
    with pytest.raises(OutputError, match="stack.vrt: No space left on device"):
        write_stack(product, fresh)
    assert list(fresh.parent.iterdir()) == []  # neither the VRT nor its mask


def test_a_failed_mask_write_leaves_nothing(product, tmp_path, monkeypatch):
    def failing(product, grid, target, chunks):
        target.write_bytes(b"II*\x00")  # a few bytes of a GeoTIFF, then the disk is full
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(folders, "_write_mask", failing)
    with pytest.raises(OutputError, match=r"cannot write .*stack_mask\.tif: No space left on device"):
        write_stack(product, tmp_path / "stack.vrt")
    assert [path.name for path in tmp_path.iterdir()] == ["in"]


def test_a_stack_or_mask_that_is_a_product_file_is_refused_untouched(product, tmp_path):
    before = file_digests(tmp_path / "in")
    band = next(iter(product.bands.values()))
    link = tmp_path / "band.vrt"
    link.symlink_to(band)  # a link to a product band: the band itself
    with pytest.raises(InputOverwriteError, match="band stack .*band.vrt is also an input"):
        write_stack(product, link)
    (tmp_path / "other_mask.tif").symlink_to(product.mask)  # the mask would replace the QA_PIXEL file
    with pytest.raises(InputOverwriteError, match="band stack's mask .*other_mask.tif is also an input"):
        write_stack(product, tmp_path / "other.vrt")
    assert not (tmp_path / "other.vrt").exists()
    (tmp_path / "folder.vrt").mkdir()
    with pytest.raises(OutputError, match="is a directory"):
        write_stack(product, tmp_path / "folder.vrt")
    assert file_digests(tmp_path / "in") == before
