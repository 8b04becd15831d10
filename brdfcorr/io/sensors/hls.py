"""HLS v2.0 S30/L30 granules: found, and their NBAR sun zenith read (:func:`find_hls_granule`).

The surface reflectance of a Harmonized Landsat Sentinel-2 granule (NASA HLS v2.0 User Guide;
hls.gsfc.nasa.gov/algorithms/brdf-adjustment) is NBAR already: the c-factor with the global
coefficients of Roy et al. (2016, 2017), nadir view, one modelled sun zenith per granule (the
mean of the sun zeniths predicted for the Landsat and Sentinel-2 overpasses at the tile centre's
latitude on that day), stored in each band file's ``NBAR_SOLAR_ZENITH`` tag. Normalizing it again
would apply the view correction twice; moving it to another sun zenith is exact
(:func:`brdfcorr.tasks.nbar.nbar_files` with a fixed reference sun zenith).

Files: one COG per band, ``HLS.S30.T33UUP.2023166T101559.v2.0.B04.tif``, int16 reflectance x 10 000
(no data -9999), and ``...Fmask.tif`` (bits 1 cloud, 2 adjacent to cloud or shadow, 3 cloud shadow,
4 snow/ice, 5 water, 6-7 aerosol level).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import rasterio

from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors.bands import LANDSAT_OLI_WAVELENGTHS, SENTINEL2_WAVELENGTHS, ProductBands, band_list

__all__ = ["HlsGranule", "find_hls_granule", "hls_refusal", "HLS_FMASK_MASKED"]

#: An HLS v2.0 file name: the granule id (``HLS.S30.T33UUP.2023166T101559.v2.0``), its product, the band.
_HLS_FILE = re.compile(r"^(HLS\.(S30|L30)\..*)\.(B\w+|Fmask)\.tiff?$", re.IGNORECASE)
#: Fmask bits that make a pixel no data by default: cloud, adjacent to cloud or shadow, cloud shadow.
HLS_FMASK_MASKED = (1, 2, 3)
#: Per product: the coefficient library's sensor key and, per HLS band with published coefficients
#: (Roy et al. 2016, 2017), its name there and its centre [nm].
_BANDS = {
    "S30": ("sentinel2", {name: (name, SENTINEL2_WAVELENGTHS[name])
                          for name in ("B02", "B03", "B04", "B05", "B06", "B07", "B08", "B8A", "B11", "B12")}),
    "L30": ("landsat_oli", {f"B0{n}": (f"SR_B{n}", LANDSAT_OLI_WAVELENGTHS[n]) for n in (2, 3, 4, 5, 6, 7)}),
}


@dataclass(frozen=True)
class HlsGranule(ProductBands):
    """An HLS v2.0 granule folder (:class:`~brdfcorr.io.sensors.bands.ProductBands`: kind
    ``hls_s30``, Sentinel-2 based, or ``hls_l30``, Landsat based; the coefficient library's sensor
    ``sentinel2`` or ``landsat_oli``), with each band's name in the library
    (``coefficient_bands``: ``B04``, ``SR_B4``), the sun zenith of the granule's NBAR ``nbar_sza``
    [deg] (``NBAR_SOLAR_ZENITH``, each band's own) and its Fmask file ``fmask`` (None where there is
    none)."""

    coefficient_bands: tuple[str, ...]
    nbar_sza: tuple[float, ...]
    fmask: Path | None

    def describe_sza(self) -> str:
        """The bands' NBAR sun zenith [deg] in words: one value, or each band's."""
        if len(set(self.nbar_sza)) == 1:
            return f"{self.nbar_sza[0]:.2f}"
        return ", ".join(f"{name} {sza:.2f}" for name, sza in zip(self.bands, self.nbar_sza, strict=True))

    @property
    def resolution(self) -> float:
        """Pixel size [m]: HLS v2.0 is 30 m."""
        return 30.0

    @property
    def files(self) -> list[tuple[str, Path]]:
        """Every file read, by role (for the output guard)."""
        return [*((f"band {name}", path) for name, path in self.bands.items()),
                *((("Fmask", self.fmask),) if self.fmask is not None else ())]


def _hls_files(path: Path) -> list[Path]:
    """The HLS files in folder ``path``, all of one granule: a folder of several (earthaccess
    downloads a search's granules into one) is one :class:`SensorInputError` naming their ids,
    as the bands of one date with the Fmask of another, or an S30 B05 (red edge) read as an
    L30 B05 (NIR), would be silently wrong."""
    files = sorted(p for p in path.iterdir() if _HLS_FILE.match(p.name)) if path.is_dir() else []
    granules = list(dict.fromkeys(_HLS_FILE.match(file.name)[1] for file in files))
    if len(granules) > 1:
        raise SensorInputError(f"{path}: {len(granules)} HLS granules in one folder ({', '.join(granules)}); "
                               "brdfcorr reads one granule per folder: move each into a folder of its own")
    return files


def _nbar_sza(path: Path) -> float | None:
    try:
        with rasterio.open(path) as dataset:
            value = dataset.tags().get("NBAR_SOLAR_ZENITH")
    except rasterio.errors.RasterioIOError:
        return None
    try:
        return float(value) if value is not None else None
    except ValueError:
        return None


def _band_sza(path: Path) -> float:
    """A band file's ``NBAR_SOLAR_ZENITH`` [deg, in [0, 90)]."""
    sza = _nbar_sza(path)
    if sza is None or not 0.0 <= sza < 90.0:
        raise SensorInputError(f"{path}: no valid NBAR_SOLAR_ZENITH tag (the granule's NBAR sun zenith [deg]); is "
                               "this an HLS v2.0 file?")
    return sza


def hls_refusal(granule: HlsGranule) -> str:
    """Why a granule is not normalized again: its reflectance is NBAR already (module docstring)."""
    kind = "S30 (Sentinel-2)" if granule.kind == "hls_s30" else "L30 (Landsat)"
    return (f"{granule.path}: an HLS v2.0 {kind} granule is already NBAR (c-factor with the Roy et al. "
            f"coefficients: nadir view, sun zenith {granule.describe_sza()} deg); brdfcorr nbar does not normalize "
            "it again, but moves it to another sun zenith with --ref-sza DEG")


def find_hls_granule(path: str | Path, bands: Sequence[str] | None = None) -> HlsGranule | None:
    """The HLS granule in folder ``path``, or None where it holds no HLS file; its band and Fmask
    files by absolute path.

    Raises
    ------
    SensorInputError
        The folder holds files of more than one granule; a band asked for is named twice, is
        missing or has no published coefficients; the band files carry no readable
        ``NBAR_SOLAR_ZENITH`` tag.
    """
    path = Path(path)
    bands = band_list(path, bands)
    files = _hls_files(path)
    if not files:
        return None
    product = "S30" if ".S30." in files[0].name.upper() else "L30"
    sensor, known = _BANDS[product]
    found = {name: file for name in known for file in files if file.name.upper().endswith(f".{name}.TIF")
             or file.name.upper().endswith(f".{name}.TIFF")}
    names = list(bands) if bands is not None else list(found)
    missing = [name for name in names if name not in found]
    if missing or not names:
        what = ", ".join(missing) if missing else "no band with coefficients"
        raise SensorInputError(f"{path}: HLS {product} granule: {what} (bands with published coefficients: "
                               f"{', '.join(known)})")
    sza = tuple(_band_sza(found[name]) for name in names)  # each band's own: they may differ
    fmask = next((file for file in files if file.name.upper().endswith((".FMASK.TIF", ".FMASK.TIFF"))), None)
    # The files by absolute path (the granule's own path as given, which messages name), as
    # brdfcorr.io.opening.open_raster opens rasters: their lazy reads may run on dask.distributed
    # workers started elsewhere.
    return HlsGranule(path, f"hls_{product.lower()}", sensor, {name: found[name].absolute() for name in names},
                      tuple(known[name][1] for name in names), tuple(known[name][0] for name in names), sza,
                      None if fmask is None else fmask.absolute())
