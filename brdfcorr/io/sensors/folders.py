"""Product folders as delivered: a Sentinel-2 L2A SAFE folder and a Landsat Collection-2 L2 folder.

:func:`find_product` finds a product's reflectance bands, its quality mask, its scaling and its
angle source; :func:`write_stack` writes the bands on one grid, masked, as one GDAL virtual raster
(and its mask GeoTIFF) that the correction reads (:func:`brdfcorr.tasks.nbar.nbar_files`).

Sentinel-2 L2A (ESA, S2 MSI Level-2A Product Format Specification; processing baseline 04.00
note, COPE-SERCO-RP-21-1141): ``<name>.SAFE/MTD_MSIL2A.xml`` (``PROCESSING_BASELINE``,
``BOA_QUANTIFICATION_VALUE``, ``BOA_ADD_OFFSET`` per ``band_id``) and
``GRANULE/<granule>/MTD_TL.xml`` (angle grids) with ``IMG_DATA/R10m|R20m|R60m/*_<band>_<res>m.jp2``.
Reflectance = (DN + BOA_ADD_OFFSET) / BOA_QUANTIFICATION_VALUE; from baseline 04.00 the offset is
-1000 (taken from the metadata; -1000 where a baseline >= 04.00 product lists none, 0 before
04.00). DN 0 is no data. The scene classification (SCL, 20 m) masks :data:`SCL_MASKED`.

Landsat Collection 2 Level-2 (USGS, LSDS-1619 L2 Data Format Control Book): ``<id>_SR_B<n>.TIF``
with reflectance = DN x 2.75e-5 - 0.2 (:data:`LANDSAT_SCALE`, :data:`LANDSAT_OFFSET`), DN 0 fill,
``<id>_QA_PIXEL.TIF`` (bits :data:`QA_PIXEL_MASKED`) and ``<id>_ANG.txt``; the view angles come
from the angle bands where delivered, else from the ANG.txt ephemeris
(:func:`brdfcorr.io.sensors.landsat.read_landsat_angles`, ``view_from_ang="ephemeris"``).

HLS v2.0 S30/L30 granules (``HLS.S30.<tile>.<time>.v2.0.B04.tif``) hold NBAR already: they are
recognized and refused here in one line (:func:`brdfcorr.io.sensors.hls.hls_refusal`); see
:mod:`brdfcorr.io.sensors.hls`.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import threading
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import escape

import rasterio
import rioxarray
import xarray as xr
from pyproj import Transformer
from rasterio.enums import Resampling
from rasterio.vrt import WarpedVRT

from brdfcorr.errors import OutputError, SensorInputError
from brdfcorr.io.files import atomic_path, read_xml, write_cause
from brdfcorr.io.paths import check_outputs
from brdfcorr.io.sensors.bands import LANDSAT_OLI_WAVELENGTHS, SENTINEL2_WAVELENGTHS, ProductBands, band_list
from brdfcorr.io.sensors.grids import check_covers
from brdfcorr.io.sensors.hls import find_hls_granule, hls_refusal
from brdfcorr.io.sensors.landsat import find_angle_bands
from brdfcorr.io.sensors.sentinel2 import BAND_NAMES
from brdfcorr.io.writer import local_scheduler

__all__ = ["ProductFolder", "find_product", "find_sentinel2_l2a", "find_landsat_c2_l2", "write_stack", "open_stack",
           "band_stacks",
           "hls_refusal", "SCL_MASKED", "QA_PIXEL_MASKED", "LANDSAT_SCALE", "LANDSAT_OFFSET", "QUANTIFICATION_RANGE",
           "OFFSET_RANGE"]

#: Scene classification (SCL) values masked by default: 0 no data, 1 saturated or defective,
#: 3 cloud shadow, 8 cloud (medium probability), 9 cloud (high probability), 10 thin cirrus.
#: Kept: 2 dark area / topographic shadow, 4 vegetation, 5 bare soil, 6 water, 7 unclassified,
#: 11 snow or ice.
SCL_MASKED = (0, 1, 3, 8, 9, 10)
#: QA_PIXEL bits masked by default: 0 fill, 1 dilated cloud, 2 cirrus, 3 cloud, 4 cloud shadow.
QA_PIXEL_MASKED = (0, 1, 2, 3, 4)
#: Landsat Collection 2 Level-2 surface reflectance scaling: reflectance = DN x scale + offset.
LANDSAT_SCALE, LANDSAT_OFFSET = 2.75e-5, -0.2

#: Sentinel-2 L2A bands with published BRDF coefficients, per output resolution [m] (at 20 m
#: the L2A product has no B08: B8A is its NIR band).
SENTINEL2_BANDS = {10: ("B02", "B03", "B04", "B05", "B06", "B07", "B08", "B8A", "B11", "B12"),
                   20: ("B02", "B03", "B04", "B05", "B06", "B07", "B8A", "B11", "B12")}
#: Landsat sensors by product id prefix: (coefficient sensor key, SR bands, centres [nm]).
#: TM/ETM+ centres: USGS Landsat 7 Data Users Handbook (ETM+) and Landsat 4-5 TM handbook.
LANDSAT_SENSORS = {
    "LC08": ("landsat_oli", {f"SR_B{n}": LANDSAT_OLI_WAVELENGTHS[n] for n in (2, 3, 4, 5, 6, 7)}),
    "LC09": ("landsat_oli", {f"SR_B{n}": LANDSAT_OLI_WAVELENGTHS[n] for n in (2, 3, 4, 5, 6, 7)}),
    "LE07": ("landsat_tm_etm", {"SR_B1": 478.0, "SR_B2": 560.0, "SR_B3": 661.0, "SR_B4": 835.0,
                                "SR_B5": 1650.0, "SR_B7": 2208.0}),
    "LT05": ("landsat_tm_etm", {"SR_B1": 485.0, "SR_B2": 569.0, "SR_B3": 660.0, "SR_B4": 840.0,
                                "SR_B5": 1676.0, "SR_B7": 2223.0}),
    "LT04": ("landsat_tm_etm", {"SR_B1": 485.0, "SR_B2": 569.0, "SR_B3": 660.0, "SR_B4": 840.0,
                                "SR_B5": 1676.0, "SR_B7": 2223.0}),
}


@dataclass(frozen=True)
class ProductFolder(ProductBands):
    """One product folder (:class:`~brdfcorr.io.sensors.bands.ProductBands`: its path, kind
    ``sentinel2_l2a`` or ``landsat_c2_l2``, sensor, bands and their centres), with its scaling,
    quality mask and angle source.

    Attributes
    ----------
    scales, offsets : tuple of float
        Reflectance factor per DN and of DN 0, per band (reflectance = DN x scale + offset).
    resolution : float
        Pixel size of the output grid [m]; ``grid`` is the band file that defines it.
    mask : Path
        The SCL or QA_PIXEL file; ``masked`` the SCL classes or QA_PIXEL bits that become no data.
    angles, angles_kind, angle_options :
        The angle source for :func:`brdfcorr.io.sensors.read_angles`.
    notes : tuple of str
        What was assumed (e.g. the baseline offset), for the output's provenance.
    metadata : Path, optional
        The file the scaling was read from (a SAFE folder's ``MTD_MSIL2A.xml``; Landsat
        Collection 2's scaling is fixed): among :attr:`files`, so that a resumed chain sees an edit.
    """

    scales: tuple[float, ...]
    offsets: tuple[float, ...]
    resolution: float
    grid: Path
    mask: Path
    masked: tuple[int, ...]
    angles: Path
    angles_kind: str
    angle_options: Mapping[str, object] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    metadata: Path | None = None

    @property
    def files(self) -> list[tuple[str, Path]]:
        """Every file read, by role (for the output guard and a resumed chain's fingerprint)."""
        angle_files = find_angle_bands(self.angles) if self.angles_kind == "landsat" else {}
        return [*((("product metadata", self.metadata),) if self.metadata is not None else ()),
                *((f"band {name}", path) for name, path in self.bands.items()),
                ("quality mask", self.mask), ("angle metadata", self.angles),
                *((f"angle band {key}", path) for key, path in angle_files.items()),
                *((("angle coefficient file", self.angle_options["ang"]),) if "ang" in self.angle_options else ())]


def find_product(path: str | Path, *, resolution: int | None = None, bands: Sequence[str] | None = None,
                 masked: Sequence[int] | None = None) -> ProductFolder:
    """The product in folder ``path``: a Sentinel-2 L2A SAFE folder (``MTD_MSIL2A.xml``) or a Landsat
    Collection-2 L2 folder (``*_SR_B<n>.TIF``); see :func:`find_sentinel2_l2a` and
    :func:`find_landsat_c2_l2`.

    Raises
    ------
    SensorInputError
        ``path`` is no folder, holds neither product (the message names what was looked for), or
        holds a Sentinel-2 L1C product or an HLS S30/L30 granule, which is NBAR already
        (:func:`hls_refusal`).
    """
    path = Path(path)
    if not path.is_dir():
        raise SensorInputError(f"product {path} is not a folder (a Sentinel-2 .SAFE or Landsat C2 L2 folder)")
    if os.path.lexists(path / "MTD_MSIL2A.xml"):  # read as a regular file only (a FIFO is refused, not waited on)
        return find_sentinel2_l2a(path, resolution=resolution or 20, bands=bands, masked=masked)
    if any(_SR_BAND.search(p.name) for p in path.iterdir()):
        if resolution not in (None, 30):
            raise SensorInputError(f"{path}: Landsat Collection-2 bands are 30 m; resolution {resolution} m")
        return find_landsat_c2_l2(path, bands=bands, masked=masked)
    if (path / "MTD_MSIL1C.xml").is_file():
        raise SensorInputError(f"{path}: a Sentinel-2 L1C product (top-of-atmosphere); NBAR needs L2A")
    hls = find_hls_granule(path)
    if hls is not None:
        raise SensorInputError(hls_refusal(hls))
    raise SensorInputError(f"{path}: neither a Sentinel-2 L2A SAFE folder (MTD_MSIL2A.xml) nor a Landsat "
                           "Collection-2 L2 folder (*_SR_B<n>.TIF)")


# --- Sentinel-2 L2A ----------------------------------------------------------------------------

def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


#: BOA_QUANTIFICATION_VALUE accepted (ESA: 10000): DN / value is a reflectance factor, so a value
#: outside this range puts a bright pixel's DN of 5000 at 5 or 0.05 (a slip of the metadata).
QUANTIFICATION_RANGE = (1000.0, 100000.0)
#: BOA_ADD_OFFSET accepted, as a reflectance (offset / quantification; ESA from baseline 04.00:
#: -1000 / 10000 = -0.1, before it 0): a larger shift is no radiometric offset.
OFFSET_RANGE = (-0.2, 0.2)


def _product_scaling(path: Path, names: Sequence[str]) -> tuple[float, float, dict[str, float], list[str]]:
    """Processing baseline, quantification value, BOA offsets of the bands ``names``, notes
    (MTD_MSIL2A.xml), each checked against its physical range (:data:`QUANTIFICATION_RANGE`,
    :data:`OFFSET_RANGE`): a product listing offsets lists exactly one for every band read."""
    root = read_xml(path, "the product metadata", SensorInputError)
    elements = {_local(e.tag): e for e in root.iter()}
    baseline = _metadata_number(elements, "PROCESSING_BASELINE", path)
    quantification = _metadata_number(elements, "BOA_QUANTIFICATION_VALUE", path)
    low, high = QUANTIFICATION_RANGE
    if not low <= quantification <= high:
        raise SensorInputError(f"{path}: BOA_QUANTIFICATION_VALUE {quantification:g} is outside {low:g} to {high:g} "
                               "(ESA: 10000, DN per reflectance factor 1)")
    offsets, notes = _boa_offsets(root, path), []
    if not offsets:
        value = -1000.0 if baseline >= 4.0 else 0.0
        if baseline >= 4.0:
            notes.append(f"processing baseline {baseline:05.2f} lists no BOA_ADD_OFFSET: -1000 (ESA, baseline 04.00)")
        return baseline, quantification, dict.fromkeys(names, value), notes
    missing = [name for name in names if name not in offsets]
    if missing:
        raise SensorInputError(f"{path}: no BOA_ADD_OFFSET for band {', '.join(missing)} (band_id "
                               f"{', '.join(str(BAND_NAMES.index(name)) for name in missing)}); the product lists "
                               f"offsets for {', '.join(offsets)}")
    for name in names:
        if not OFFSET_RANGE[0] <= offsets[name] / quantification <= OFFSET_RANGE[1]:
            raise SensorInputError(
                f"{path}: BOA_ADD_OFFSET {offsets[name]:g} of band {name} (band_id {BAND_NAMES.index(name)}) is "
                f"{offsets[name] / quantification:g} in reflectance, outside {OFFSET_RANGE[0]:g} to "
                f"{OFFSET_RANGE[1]:g} (ESA: -1000 of quantification 10000)")
    return baseline, quantification, {name: offsets[name] for name in names}, notes




def _metadata_number(elements: Mapping[str, ET.Element], tag: str, path: Path) -> float:
    """The finite number of a product metadata element, else one error naming it and its text."""
    if tag not in elements:
        raise SensorInputError(f"{path}: no <{tag}> element in the product metadata")
    return _finite(elements[tag].text, f"<{tag}>", path)


def _finite(text: str | None, what: str, path: Path) -> float:
    try:
        value = float(str(text).strip())
    except ValueError:
        value = float("nan")
    if not math.isfinite(value):
        raise SensorInputError(f"{path}: {what} {text!r} is not a finite number")
    return value


def _boa_offsets(root: ET.Element, path: Path) -> dict[str, float]:
    """The ``BOA_ADD_OFFSET`` of each band by name: a band id of 0 to 12, one element per band."""
    offsets: dict[str, float] = {}
    for element in root.iter():
        if _local(element.tag) != "BOA_ADD_OFFSET":
            continue
        band_id = element.get("band_id")
        if band_id is None or not band_id.strip().isdigit() or int(band_id) >= len(BAND_NAMES):
            raise SensorInputError(f"{path}: BOA_ADD_OFFSET band_id {band_id!r} is no Sentinel-2 band id "
                                   f"(0 to {len(BAND_NAMES) - 1})")
        name = BAND_NAMES[int(band_id)]
        if name in offsets:
            raise SensorInputError(f"{path}: BOA_ADD_OFFSET band_id {band_id!r} ({name}) is given twice; a product "
                                   "lists one offset per band")
        offsets[name] = _finite(element.text, f"BOA_ADD_OFFSET of band_id {band_id!r}", path)
    return offsets


def _granule_file(safe: Path, pattern: str, what: str) -> Path:
    found = sorted(safe.glob(f"GRANULE/*/{pattern}"))
    if len(found) != 1:
        raise SensorInputError(f"{safe}: {'no' if not found else 'several'} {what} (GRANULE/*/{pattern})")
    return found[0]


def _band_file(safe: Path, band: str, resolution: int) -> Path:
    """The band's file at ``resolution``, else at the nearest other resolution (resampled later)."""
    for res in sorted((10, 20, 60), key=lambda r: (abs(r - resolution), r)):
        found = sorted(p for p in safe.glob(f"GRANULE/*/IMG_DATA/R{res}m/*_{band}_{res}m.*")
                       if p.suffix.lower() in (".jp2", ".tif", ".tiff"))
        if found:
            return found[0]
    raise SensorInputError(f"{safe}: no image file of band {band} (GRANULE/*/IMG_DATA/R*m/*_{band}_*m.jp2)")


def sentinel2_band_names(source: Path, resolution: int, bands: Sequence[str] | None) -> tuple[str, ...]:
    """The Sentinel-2 bands read at ``resolution`` (10 or 20 m): ``bands`` (checked) or the
    default :data:`SENTINEL2_BANDS` of the resolution; one error naming ``source`` otherwise (a
    band named twice: :func:`~brdfcorr.io.sensors.bands.band_list`)."""
    asked = band_list(source, bands)
    if resolution not in SENTINEL2_BANDS:
        raise SensorInputError(f"{source}: Sentinel-2 resolution must be 10 or 20 m, got {resolution}")
    names = asked if asked is not None else SENTINEL2_BANDS[resolution]
    unknown = [name for name in names if name not in BAND_NAMES]
    if unknown or not names:
        raise SensorInputError(f"{source}: unknown Sentinel-2 band(s) {unknown}; bands are {', '.join(BAND_NAMES)}")
    return names


def find_sentinel2_l2a(path: str | Path, *, resolution: int = 20, bands: Sequence[str] | None = None,
                       masked: Sequence[int] | None = None) -> ProductFolder:
    """A Sentinel-2 L2A SAFE folder at ``resolution`` (10 or 20 m).

    Parameters
    ----------
    path : path-like
        The ``.SAFE`` folder (with ``MTD_MSIL2A.xml`` and one granule).
    resolution : {10, 20}
        Output pixel size [m]; bands of another resolution are resampled onto its grid.
    bands : sequence of str, optional
        Band names in output order, each once (default: :data:`SENTINEL2_BANDS` of the resolution).
    masked : sequence of int, optional
        SCL classes that become no data (default :data:`SCL_MASKED`; ``()``: only DN 0).
    """
    safe = Path(path)
    names = sentinel2_band_names(safe, resolution, bands)
    baseline, quantification, offsets, notes = _product_scaling(safe / "MTD_MSIL2A.xml", names)
    files = {name: _band_file(safe, name, resolution) for name in names}
    grid = next((f for f in files.values() if f.parent.name == f"R{resolution}m"), None)
    if grid is None:
        grid = _band_file(safe, "B02" if resolution == 10 else "B05", resolution)
    return ProductFolder(
        path=safe, kind="sentinel2_l2a", sensor="sentinel2", bands=files,
        wavelengths=tuple(SENTINEL2_WAVELENGTHS[name] for name in names),
        scales=(1.0 / quantification,) * len(names),
        offsets=tuple(offsets[name] / quantification for name in names),
        resolution=float(resolution), grid=grid, mask=_band_file(safe, "SCL", 20),
        masked=tuple(SCL_MASKED if masked is None else masked),
        angles=_granule_file(safe, "MTD_TL.xml", "granule metadata"), angles_kind="sentinel2",
        notes=(f"processing baseline {baseline:05.2f}", *notes), metadata=safe / "MTD_MSIL2A.xml",
    )


# --- Landsat Collection 2 L2 -----------------------------------------------------------------

_SR_BAND = re.compile(r"_SR_B(\d+)\.tiff?$", re.IGNORECASE)


def _one(folder: Path, suffix: str, what: str) -> Path:
    found = sorted(p for p in folder.iterdir() if p.name.upper().endswith(suffix.upper()))
    if len(found) != 1:
        raise SensorInputError(f"{folder}: {'no' if not found else 'several'} {what} (*{suffix})")
    return found[0]


def find_landsat_c2_l2(path: str | Path, *, bands: Sequence[str] | None = None,
                       masked: Sequence[int] | None = None) -> ProductFolder:
    """A Landsat Collection-2 Level-2 folder (Landsat 4/5 TM, 7 ETM+, 8/9 OLI).

    Parameters
    ----------
    path : path-like
        The folder with ``*_SR_B<n>.TIF``, ``*_QA_PIXEL.TIF`` and ``*_ANG.txt``.
    bands : sequence of str, optional
        Band names (``SR_B4``) in output order, each once (default: the six reflective bands with
        published coefficients, in band order).
    masked : sequence of int, optional
        QA_PIXEL bits that make a pixel no data (default :data:`QA_PIXEL_MASKED`; ``()``: fill only).
    """
    folder = Path(path)
    bands = band_list(folder, bands)
    sr_files = {f"SR_B{_SR_BAND.search(p.name)[1]}": p for p in sorted(folder.iterdir()) if _SR_BAND.search(p.name)}
    if not sr_files:
        raise SensorInputError(f"{folder}: no Landsat surface reflectance band (*_SR_B<n>.TIF)")
    product_id = next(iter(sr_files.values())).name[:4].upper()
    if product_id not in LANDSAT_SENSORS:
        raise SensorInputError(f"{folder}: unknown Landsat product {product_id!r}; known: {', '.join(LANDSAT_SENSORS)}")
    sensor, centres = LANDSAT_SENSORS[product_id]
    names = tuple(bands) if bands is not None else tuple(centres)
    missing = [name for name in names if name not in sr_files or name not in centres]
    if missing or not names:
        raise SensorInputError(f"{folder}: no {product_id} reflective band file(s) {missing} (*_<band>.TIF); "
                               f"found {', '.join(sr_files)}")
    return ProductFolder(
        path=folder, kind="landsat_c2_l2", sensor=sensor, bands={name: sr_files[name] for name in names},
        wavelengths=tuple(centres[name] for name in names), scales=(LANDSAT_SCALE,) * len(names),
        offsets=(LANDSAT_OFFSET,) * len(names), resolution=30.0, grid=sr_files[names[0]],
        mask=_one(folder, "_QA_PIXEL.TIF", "QA_PIXEL band"),
        masked=tuple(QA_PIXEL_MASKED if masked is None else masked), angles=folder, angles_kind="landsat",
        angle_options=_landsat_angle_options(folder),
        notes=(f"{product_id} Collection 2 Level-2, scale {LANDSAT_SCALE:g}, offset {LANDSAT_OFFSET:g}",),
    )


def _landsat_angle_options(folder: Path) -> dict:
    """The angle reader's options: none where the four angle bands (``_SZA``, ``_SAA``, ``_VZA``,
    ``_VAA``) are delivered, else the ANG.txt, with view angles from its ephemeris."""
    if set(find_angle_bands(folder)) == {"sza", "saa", "vza", "vaa"}:
        return {}
    return {"ang": _one(folder, "_ANG.txt", "angle coefficient file (or the four angle bands)"),
            "view_from_ang": "ephemeris"}


# --- the stack ---------------------------------------------------------------------------------

def _on_grid(path: Path, grid: rasterio.DatasetReader, chunks: int) -> xr.DataArray:
    """Band 1 of ``path`` (y, x) on the grid of ``grid``, lazily: as it is where the grids agree,
    else through a GDAL warped VRT by nearest neighbour (the quality mask: each value kept). Read by
    its absolute path, as the stack's bands (:func:`_source_xml`): workers started in another
    folder read it."""
    with rasterio.open(path) as source:
        same = (source.crs == grid.crs and source.transform == grid.transform
                and source.shape == (grid.height, grid.width))
        if not same:  # outside the mask every pixel would read as its fill: QA_PIXEL 0 is "clear"
            transformer = None if source.crs == grid.crs else Transformer.from_crs(grid.crs, source.crs, always_xy=True)
            check_covers(source.transform, source.shape, grid.transform, (grid.height, grid.width), transformer,
                         source=f"{path}: the quality mask", margin=0.5)
    absolute = Path(path).absolute()  # what the graph's reads open (messages name the path as given)
    if same:
        band = rioxarray.open_rasterio(absolute, chunks={"y": chunks, "x": chunks}, lock=False)
    else:
        vrt = WarpedVRT(rasterio.open(absolute), crs=grid.crs, transform=grid.transform, width=grid.width,
                        height=grid.height, resampling=Resampling.nearest)
        band = rioxarray.open_rasterio(vrt, chunks={"y": chunks, "x": chunks}, lock=False)
    return band.isel(band=0, drop=True)


def _invalid(product: ProductFolder, mask: xr.DataArray) -> xr.DataArray:
    """Pixels the quality mask makes no data: SCL classes, or any of the QA_PIXEL bits."""
    if product.kind == "sentinel2_l2a":
        return mask.isin(list(product.masked))
    bits = sum(1 << bit for bit in product.masked)
    return (mask & bits) != 0 if bits else xr.zeros_like(mask, dtype=bool)


def _write_mask(product: ProductFolder, grid: rasterio.DatasetReader, target: Path, chunks: int) -> Path:
    """The quality mask on the output grid as a uint8 GeoTIFF: 1 where a pixel is kept, 0 where
    :attr:`ProductFolder.masked` makes it no data (one small pass over the SCL or QA_PIXEL)."""
    kept = (~_invalid(product, _on_grid(product.mask, grid, chunks))).astype("uint8")
    kept = kept.rio.write_crs(grid.crs).rio.write_transform(grid.transform)
    kept.attrs = {}
    # 0 and 1: a few kB per tile. Stored on the local scheduler (io.writer.local_scheduler: dask's
    # default would import dask.distributed to look for a Client).
    kept.rio.to_raster(target, tiled=True, blockxsize=256, blockysize=256, lock=threading.Lock(), driver="GTiff",
                       compress="deflate", compute=False).compute(scheduler=local_scheduler(None))
    return target


def _source_xml(path: Path, grid: rasterio.DatasetReader, element: str = "ComplexSource", *,
                name: Path | None = None) -> str:
    """A VRT source placing band 1 of ``path`` on ``grid`` (same CRS, axis-aligned): its whole
    extent mapped onto the grid's pixels, by nearest neighbour from a coarser grid (each value
    kept) and by averaging, without the no data value 0, from a finer one. The VRT reads the file
    ``name`` (default ``path``: a temporary file is read here under its final name)."""
    with rasterio.open(path) as source:
        transform, shape, crs = source.transform, source.shape, source.crs
    target = grid.transform
    if crs != grid.crs or transform.b or transform.d or target.b or target.d:
        raise SensorInputError(f"{path}: not on the grid of {grid.name} (another CRS, or rotated)")
    column, row = ~target * (transform.c, transform.f)
    width, height = shape[1] * transform.a / target.a, shape[0] * transform.e / target.e
    finer = abs(transform.a) < abs(target.a)
    return (f'<{element} resampling="{"average" if finer else "nearest"}">'
            f'<SourceFilename relativeToVRT="0">{escape(str(Path(name or path).resolve()))}</SourceFilename>'
            f'<SourceBand>1</SourceBand><SrcRect xOff="0" yOff="0" xSize="{shape[1]}" ySize="{shape[0]}"/>'
            f'<DstRect xOff="{column!r}" yOff="{row!r}" xSize="{width!r}" ySize="{height!r}"/>'
            + ("<NODATA>0</NODATA>" if element == "ComplexSource" else "") + f"</{element}>")


def write_stack(product: ProductFolder, target: str | Path, chunks: int = 1024) -> Path:
    """The product's bands on one grid, masked, as one GDAL virtual raster ``target`` (``.vrt``).

    No band is copied: each band of the VRT reads its product file, resampled onto the grid of
    :attr:`ProductFolder.grid` (nearest neighbour from a coarser band, the mean of the valid pixels
    of a finer one) and, where :attr:`ProductFolder.masked` masks anything, multiplied by the
    quality mask (GDAL's ``mul`` pixel function with a 0/1 uint8 GeoTIFF ``<stem>_mask.tif``
    written beside ``target``, :func:`_write_mask`): masked pixels become the product's no data,
    DN 0. The stored DNs are kept (uint16, no data 0); each band carries its GDAL scale and offset
    (reflectance = DN x scale + offset) and its name as description, the raster the
    ``wavelength`` tag (band centres [nm]), so :func:`brdfcorr.io.rasters.open_image` reads
    reflectance factors with their wavelengths.

    Both files pass the output guard first (:func:`brdfcorr.io.paths.check_outputs`: regular
    files or absent, none of the product's files) and are written to temporary names, renamed only
    when both are complete (:func:`brdfcorr.io.files.atomic_path`), the mask before the VRT that
    reads it: a failed or killed write leaves neither file (existing ones untouched). Whether an
    existing file may be replaced is the caller's rule (:func:`brdfcorr.tasks.nbar.nbar_files`:
    only with ``overwrite``).

    Raises
    ------
    InputOverwriteError, OutputError
        ``target`` or its mask is a product file, a directory or another special file; a write
        failed (a full disk, the file size limit, permissions).
    """
    target = Path(target)
    mask_path = target.with_name(f"{target.stem}_mask.tif") if product.masked else None
    check_outputs({f"band stack {target}": target, f"band stack's mask {mask_path}": mask_path}, product.files)
    with rasterio.open(product.grid) as grid, contextlib.ExitStack() as commits:
        temporary = commits.enter_context(atomic_path(target))  # entered first: renamed last
        mask = None
        if mask_path is not None:
            mask_temporary = commits.enter_context(atomic_path(mask_path))
            _write_mask(product, grid, mask_temporary, chunks)
            mask = _source_xml(mask_temporary, grid, "SimpleSource", name=mask_path)
        try:  # named here: inside the mask's commit, atomic_path would name the mask
            temporary.write_text(_stack_xml(product, grid, mask))
        except OSError as error:
            cause = write_cause(error, [temporary])
            raise OutputError(f"cannot write {target}: {cause}; nothing was written") from None
    return target


def open_stack(product: ProductFolder, chunks: int = 1024) -> xr.DataArray:
    """The product's bands on one grid as reflectance factors [1] (band, y, x), lazily, nothing written.

    The same bands, resampling and scaling as :func:`write_stack`'s virtual raster, read from its
    XML text (GDAL opens a VRT document given as text), with the quality mask applied as NaN
    instead of through a mask file. ``band`` holds the band names, ``wavelength`` their centres
    [nm]; masked pixels and the product's no data (DN 0) are NaN.
    """
    with rasterio.open(product.grid) as grid:
        text = _stack_xml(product, grid, None)
        invalid = _invalid(product, _on_grid(product.mask, grid, chunks)) if product.masked else None
    with warnings.catch_warnings():  # per-band offsets: rioxarray applies each band's, and says so
        warnings.filterwarnings("ignore", r"(Scales|Offsets) differ across bands", UserWarning)
        stack = rioxarray.open_rasterio(text, chunks={"band": -1, "y": chunks, "x": chunks}, masked=True,
                                        mask_and_scale=True, lock=False)
    if invalid is not None:
        stack = stack.where(~invalid)
    stack = stack.assign_coords(band=list(product.bands),
                                wavelength=("band", list(product.wavelengths), {"units": "nm"}))
    stack.encoding.pop("source", None)  # the XML text, not a file
    stack.attrs = {"sensor": product.sensor, "product": str(product.path)}
    stack.name = "reflectance"
    return stack


def _stack_xml(product: ProductFolder, grid: rasterio.DatasetReader, mask: str | None) -> str:
    """The VRT document of :func:`write_stack`: one band per product band, multiplied by the mask
    source ``mask`` where there is one."""
    bands = []
    for index, (name, path) in enumerate(product.bands.items()):
        derived = ' subClass="VRTDerivedRasterBand"' if mask else ""
        bands.append(
            f'<VRTRasterBand dataType="UInt16" band="{index + 1}"{derived}><Description>{escape(name)}'
            f"</Description><NoDataValue>0</NoDataValue><Offset>{product.offsets[index]!r}</Offset>"
            f"<Scale>{product.scales[index]!r}</Scale>"
            + ("<PixelFunctionType>mul</PixelFunctionType>" if mask else "")
            + _source_xml(path, grid) + (mask or "") + "</VRTRasterBand>")
    wavelengths = ",".join(f"{w:g}" for w in product.wavelengths)
    return (f'<VRTDataset rasterXSize="{grid.width}" rasterYSize="{grid.height}"><SRS>{escape(grid.crs.to_wkt())}'
            f"</SRS><GeoTransform>{', '.join(repr(v) for v in grid.transform.to_gdal())}</GeoTransform>"
            f'<Metadata><MDI key="wavelength">{wavelengths}</MDI><MDI key="wavelength_units">nm</MDI></Metadata>'
            + "".join(bands) + "</VRTDataset>\n")


def band_stacks(stack: str | Path, directory: str | Path) -> list[Path]:
    """One single-band VRT per band of a stack written by :func:`write_stack`, in ``directory``
    (``<stem>_1.vrt`` ...): the same sources, scaling, description and tags, for corrections
    band by band (``brdfcorr nbar --view-band each``)."""
    stack = Path(stack)
    root = ET.parse(stack).getroot()
    bands = root.findall("VRTRasterBand")
    for band in bands:
        root.remove(band)
    wavelength = root.find("Metadata/MDI[@key='wavelength']")
    centres = wavelength.text.split(",") if wavelength is not None and wavelength.text else []
    paths = []
    for number, band in enumerate(bands, start=1):
        band.set("band", "1")
        if wavelength is not None:
            wavelength.text = centres[number - 1]
        root.append(band)
        paths.append(Path(directory) / f"{stack.stem}_{number}.vrt")
        ET.ElementTree(root).write(paths[-1], encoding="unicode")
        root.remove(band)
    return paths
