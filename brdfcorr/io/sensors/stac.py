"""Sentinel-2 L2A STAC items whose assets are local files, read as product folders (:func:`find_stac_item`).

A STAC item (SpatioTemporal Asset Catalog, item specification 1.0; the ``eo``, ``raster`` and
``sat`` extensions) of a Sentinel-2 L2A granule, as the public catalogues publish them (Element
84's Earth Search ``sentinel-2-l2a``, Microsoft's Planetary Computer), lists one asset per band
(a GeoTIFF or JPEG 2000 file), the scene classification and the granule metadata
(``MTD_TL.xml``, the angle grids). With the assets downloaded beside the item (hrefs relative to
the item file, or absolute local paths), the item is a :class:`~brdfcorr.io.sensors.folders.ProductFolder`
like a SAFE folder: ``brdfcorr nbar item.json`` and :func:`brdfcorr.tasks.series.open_products`
take it.

How the assets are recognised: a band by its asset's key, else by the name of its one ``eo:bands``
entry (STAC 1.1's ``bands``), each either the band's name (``B04``: the Planetary Computer) or its
common name (``red``, ``nir08``: Earth Search v1, :data:`COMMON_NAMES`); where two assets hold a
band, the one keyed by it (Earth Search v1's COG ``blue`` before its JPEG 2000 copy ``blue-jp2``,
whose ``eo:bands`` name is ``blue`` too); the scene classification by the name or key ``SCL``/``scl``;
the granule metadata by the key ``granule_metadata`` (Earth Search) or ``granule-metadata``
(Planetary Computer), else by a file named ``MTD_TL.xml``. The scaling of each band is its
asset's ``raster:bands`` ``scale`` and ``offset`` (reflectance = DN x scale + offset); an asset
without them takes ESA's (1/10000, and -0.1 from processing baseline 04.00, the item's
``s2:processing_baseline``), with a note. An item flagged ``earthsearch:boa_offset_applied: true``
(``sentinel:boa_offset_applied`` in Earth Search v0) holds files from which Element 84 took the
-1000 DN offset already while its ``raster:bands`` still say -0.1: its bands are read with offset 0,
with a note (the flag is wrong for some items, Element84/earth-search issues 33, 66 and 71: a
scene whose vegetation turns dark or negative was offset twice or not at all). Remote hrefs
(``https://``, ``s3://``) are refused: download the assets first, or load the cube with a STAC
loader (stackstac, odc-stac).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import rasterio

from brdfcorr.errors import SensorInputError
from brdfcorr.io.files import read_regular
from brdfcorr.io.sensors.bands import SENTINEL2_WAVELENGTHS, sentinel2_band
from brdfcorr.io.sensors.folders import (
    OFFSET_RANGE,
    QUANTIFICATION_RANGE,
    SCL_MASKED,
    ProductFolder,
    sentinel2_band_names,
)
from brdfcorr.io.sensors.inputs import is_stac_item

__all__ = ["find_stac_item", "is_stac_item"]

#: Keys of the granule metadata asset in the public catalogues (Earth Search, Planetary Computer).
METADATA_KEYS = ("granule_metadata", "granule-metadata")
#: Sentinel-2 bands by the common names (STAC ``eo`` extension) that key their assets and name
#: their ``eo:bands`` entries in Earth Search v1's ``sentinel-2-l2a`` items (e.g. item
#: ``S2A_39QTA_20230628_0_L2A``: asset ``red``, ``eo:bands`` ``[{"name": "red", ...}]``, file B04.tif).
#: The entries' ``common_name`` is not read: ``rededge1`` to ``rededge3`` all carry ``rededge``.
COMMON_NAMES = {"coastal": "B01", "blue": "B02", "green": "B03", "red": "B04", "rededge1": "B05",
                "rededge2": "B06", "rededge3": "B07", "nir": "B08", "nir08": "B8A", "nir09": "B09",
                "swir16": "B11", "swir22": "B12"}


def _item(path: Path) -> dict:
    """The item's JSON object, checked to be a STAC item with assets."""
    text = read_regular(path, "STAC item", SensorInputError).decode("utf-8", errors="replace")
    try:
        item = json.loads(text)
    except json.JSONDecodeError as error:
        raise SensorInputError(f"{path}: not a STAC item (no JSON: {error})") from None
    if not isinstance(item, dict) or item.get("type") != "Feature" or not isinstance(item.get("assets"), dict):
        raise SensorInputError(f"{path}: not a STAC item (a JSON object of type Feature with assets)")
    properties = item.get("properties") or {}
    platform = str(properties.get("platform", "")) + str(properties.get("constellation", ""))
    if "sentinel-2" not in platform.lower():
        raise SensorInputError(f"{path}: a STAC item of {platform or 'an unnamed platform'}; brdfcorr reads "
                               "Sentinel-2 L2A items (platform sentinel-2a/b/c)")
    return item


def _band(text: str | None) -> str | None:
    """The Sentinel-2 band (``B04``) a band name or common name (:data:`COMMON_NAMES`) names, ``SCL``
    for ``SCL``/``scl``, or None."""
    if (text or "").upper() == "SCL":
        return "SCL"
    return COMMON_NAMES.get(text or "") or sentinel2_band(text)


def _eo_name(asset: Mapping) -> str | None:
    """The name of an asset's one ``eo:bands`` (or STAC 1.1 ``bands``) entry, or None."""
    for field in ("eo:bands", "bands"):
        entries = asset.get(field)
        if isinstance(entries, list) and len(entries) == 1 and isinstance(entries[0], dict) and entries[0].get("name"):
            return str(entries[0]["name"])
    return None


def _assets(item: Mapping) -> dict[str, tuple[str, Mapping]]:
    """(key, asset) of the item's assets by what they hold: band names, ``SCL``, ``granule metadata``;
    a band by the asset keyed by it, else by the first whose ``eo:bands`` entry names it (module docstring)."""
    by_key: dict[str, tuple[str, Mapping]] = {}
    by_name: dict[str, tuple[str, Mapping]] = {}
    for key, asset in item["assets"].items():
        if not isinstance(asset, dict):
            continue
        if (band := _band(key)) is not None:
            by_key.setdefault(band, (key, asset))
        if (band := _band(_eo_name(asset))) is not None:
            by_name.setdefault(band, (key, asset))
    assets = {**by_name, **by_key}
    metadata = [(key, asset) for key, asset in item["assets"].items() if isinstance(asset, dict)
                and (key in METADATA_KEYS or str(asset.get("href", "")).endswith("MTD_TL.xml"))]
    if metadata:
        assets["granule metadata"] = metadata[0]
    return assets


def _local_file(item_path: Path, key: str, asset: Mapping) -> Path:
    """The local file of an asset: its href relative to the item's folder, or an absolute path."""
    href = str(asset.get("href", ""))
    if "://" in href and not href.startswith("file://"):
        raise SensorInputError(f"{item_path}: asset {key} is remote ({href}); download the assets beside the "
                               "item first (hrefs relative to it), or load the cube with a STAC loader (stackstac, "
                               "odc-stac)")
    file = item_path.parent / href.removeprefix("file://")
    if not href or not file.is_file():
        raise SensorInputError(f"{item_path}: asset {key}: no file at {file}")
    return file


#: Item properties by which Earth Search (v1, v0) says the files hold DN - 1000 already.
OFFSET_APPLIED = ("earthsearch:boa_offset_applied", "sentinel:boa_offset_applied")


def _scaling(item_path: Path, key: str, asset: Mapping, baseline: float | None,
             offset_applied: bool = False) -> tuple[float, float, str | None]:
    """(scale, offset, note) of a band asset: its ``raster:bands`` entry's, else ESA's by baseline;
    the offset 0 where the item says it is applied to the files already (``offset_applied``)."""
    entries = asset.get("raster:bands")
    entry = entries[0] if isinstance(entries, list) and entries and isinstance(entries[0], dict) else {}
    if "scale" in entry:
        scale, offset = float(entry["scale"]), float(entry.get("offset", 0.0))
        note = None
    else:
        if baseline is None:
            raise SensorInputError(f"{item_path}: asset {key} has no raster:bands scale and the item no "
                                   "s2:processing_baseline: its scaling is unknown")
        scale, offset = 1e-4, (-0.1 if baseline >= 4.0 else 0.0)
        note = f"no raster:bands scaling: ESA's of processing baseline {baseline:05.2f}"
    if offset_applied and offset:
        offset = 0.0
        note = "earthsearch:boa_offset_applied: the files hold the -0.1 offset already; read with offset 0"
    if not 1.0 / QUANTIFICATION_RANGE[1] <= scale <= 1.0 / QUANTIFICATION_RANGE[0] or \
            not OFFSET_RANGE[0] <= offset <= OFFSET_RANGE[1]:
        raise SensorInputError(f"{item_path}: asset {key}: scale {scale:g} and offset {offset:g} are no Sentinel-2 "
                               f"L2A scaling (ESA: 0.0001 and -0.1)")
    return scale, offset, note


def _resolution(file: Path) -> float:
    with rasterio.open(file) as dataset:
        return float(abs(dataset.transform.a))


def find_stac_item(path: str | Path, *, resolution: int = 20, bands: Sequence[str] | None = None,
                   masked: Sequence[int] | None = None) -> ProductFolder:
    """A Sentinel-2 L2A STAC item with local assets as a product folder (module docstring).

    Parameters are those of :func:`brdfcorr.io.sensors.folders.find_sentinel2_l2a`.

    Raises
    ------
    SensorInputError
        Not a Sentinel-2 STAC item; a band, the SCL or the granule metadata missing; a remote or
        missing asset file; a scaling that is no Sentinel-2 L2A scaling.
    """
    path = Path(path)
    item = _item(path)
    names = sentinel2_band_names(path, resolution, bands)
    assets = _assets(item)
    missing = [name for name in (*names, "SCL", "granule metadata") if name not in assets]
    if missing:
        raise SensorInputError(f"{path}: the item has no asset for {', '.join(missing)} (assets are known by "
                               "their key or eo:bands name: a band name, B04, or a common name, red)")
    properties = item.get("properties") or {}
    raw_baseline = properties.get("s2:processing_baseline")
    baseline = float(raw_baseline) if raw_baseline is not None else None
    offset_applied = any(properties.get(name) is True for name in OFFSET_APPLIED)
    files, scalings = {}, []
    for name in names:
        key, asset = assets[name]
        files[name] = _local_file(path, key, asset)
        scalings.append(_scaling(path, key, asset, baseline, offset_applied))
    grid = next((file for file in files.values() if _resolution(file) == resolution), None)
    if grid is None:
        raise SensorInputError(f"{path}: no band asset at {resolution} m to define the grid")
    notes = sorted({note for *_, note in scalings if note})
    return ProductFolder(
        path=path, kind="sentinel2_l2a", sensor="sentinel2", bands=files,
        wavelengths=tuple(SENTINEL2_WAVELENGTHS[name] for name in names),
        scales=tuple(scale for scale, _, _ in scalings), offsets=tuple(offset for _, offset, _ in scalings),
        resolution=float(resolution), grid=grid, mask=_local_file(path, *assets["SCL"]),
        masked=tuple(SCL_MASKED if masked is None else masked),
        angles=_local_file(path, *assets["granule metadata"]), angles_kind="sentinel2",
        notes=(f"STAC item {item.get('id', path.stem)}", *notes),
    )
