"""Band names as sensors write them, and their centre wavelengths: Sentinel-2 MSI (``B02``,
``B8A``) and Landsat 8/9 OLI (``SR_B4``); the bands of a product on disk (:class:`ProductBands`)."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from brdfcorr._entry import option
from brdfcorr.errors import SensorInputError

__all__ = ["SENTINEL2_WAVELENGTHS", "LANDSAT_OLI_WAVELENGTHS", "MICROMETRES_BELOW", "UNITS_TO_NM",
           "named_band_wavelengths", "ProductBands", "band_list"]

#: Band centres without a unit below this are micrometres [nm]: no optical band is centred below
#: 100 nm (an ENVI header's ``wavelength`` items, an array's ``wavelength`` coordinate).
MICROMETRES_BELOW = 100.0

#: Nanometres per wavelength unit, by the unit's lower-case spellings (ENVI's ``wavelength units``,
#: a coordinate's ``units``, a band description); ``""`` is nanometres.
UNITS_TO_NM = {
    "": 1.0, "nm": 1.0, "nanometer": 1.0, "nanometers": 1.0, "nanometre": 1.0, "nanometres": 1.0,
    "um": 1e3, "µm": 1e3, "μm": 1e3, "micron": 1e3, "microns": 1e3, "micrometer": 1e3,
    "micrometers": 1e3, "micrometre": 1e3, "micrometres": 1e3,
}

#: Central wavelengths [nm] of the Sentinel-2A MSI bands (ESA, Sentinel-2 spectral response
#: functions, COPE-GSEG-EOPG-TN-15-0007). Sentinel-2B's centres differ by 3 nm or less in B01 to
#: B8A (by up to 17 nm in B12): the S2A values serve both.
SENTINEL2_WAVELENGTHS = {
    "B01": 442.7, "B02": 492.4, "B03": 559.8, "B04": 664.6, "B05": 704.1, "B06": 740.5, "B07": 782.8,
    "B08": 832.8, "B8A": 864.7, "B09": 945.1, "B10": 1373.5, "B11": 1613.7, "B12": 2202.4,
}

#: Central wavelengths [nm] of the Landsat 8/9 OLI reflective bands 1-7 (USGS, Landsat 8 Data
#: Users Handbook, Table 2-1), used only for images whose tags state the sensor
#: (:func:`brdfcorr.io.wavelengths.band_wavelengths`).
LANDSAT_OLI_WAVELENGTHS = {1: 443.0, 2: 482.0, 3: 562.0, 4: 655.0, 5: 865.0, 6: 1609.0, 7: 2201.0}

#: Dataset tags that may state the sensor of an image (Landsat MTL's ``SENSOR_ID``: ``OLI_TIRS``).
_SENSOR_TAGS = ("sensor", "SENSOR", "SENSOR_ID")


def sentinel2_band(text: str | None) -> str | None:
    """``"B02"`` for a description ``"B02"``, ``"b2"`` or ``"B2"``; ``"B8A"`` for ``"B8A"``; else None."""
    match = re.fullmatch(r"B(0?[1-9]|1[0-2]|8A)", (text or "").strip(), re.I)
    if match is None:
        return None
    number = match[1].upper()
    return "B8A" if number == "8A" else f"B{int(number):02d}"


def landsat_oli_band(text: str | None) -> int | None:
    """Band number of a Landsat OLI band name (``"SR_B4"``, ``"B4"``, ``"B04"``) of bands 1-7, or None."""
    match = re.fullmatch(r"(?:SR_)?B0?([1-7])", (text or "").strip(), re.I)
    return int(match[1]) if match else None


def band_list(source: str | os.PathLike, bands: Sequence[str] | None) -> tuple[str, ...] | None:
    """The band names asked of a product reader (``bands``, in output order) as a tuple, or None
    where none were asked; a band named more than once is one :class:`SensorInputError` naming it
    and ``source`` (the readers key their files by band name, so a repeated band would be read once
    while its wavelengths and sun zeniths were counted twice)."""
    if bands is None:
        return None
    names = tuple(bands)
    repeated = [name for index, name in enumerate(names) if name in names[:index]]
    if repeated:
        twice = ", ".join(dict.fromkeys(repeated))
        raise SensorInputError(f"{source}: band {twice} is named more than once in {option('bands')} "
                               f"({', '.join(names)}); name each band once")
    return names


def named_band_wavelengths(descriptions, tags) -> tuple[list[float] | None, str]:
    """Wavelengths [nm] from band names, and their origin: Landsat OLI names where a tag states the
    sensor (``sensor``/``SENSOR_ID`` holding ``OLI``), else Sentinel-2 names when every description
    is one. Anything else (a mix, ``SR_B4`` without the sensor): None, no guess."""
    if not descriptions:
        return None, ""
    sensor = next((str(tags[key]) for key in _SENSOR_TAGS if key in tags), "")
    if "OLI" in sensor.upper():
        bands = [landsat_oli_band(text) for text in descriptions]
        if all(band is not None for band in bands):
            return [LANDSAT_OLI_WAVELENGTHS[band] for band in bands], f"Landsat OLI band names (sensor {sensor})"
        return None, ""
    names = [sentinel2_band(text) for text in descriptions]
    if all(name is not None for name in names):
        return [SENTINEL2_WAVELENGTHS[name] for name in names], "Sentinel-2 band names"
    return None, ""


@dataclass(frozen=True)
class ProductBands:
    """The bands of a product on disk: the product's folder ``path``, its ``kind``
    (``sentinel2_l2a``, ``landsat_c2_l2``, ``hls_s30``, ``hls_l30``), the coefficient library's
    ``sensor`` key (:mod:`brdfcorr.models.coefficients`), the ``bands`` (band name -> file, in band
    order) and their nominal centres [nm] (``wavelengths``)."""

    path: Path
    kind: str
    sensor: str
    bands: dict[str, Path]
    wavelengths: tuple[float, ...]
