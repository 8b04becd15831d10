"""What every figure shares: class names as people read them, the nodata colour, bands chosen by
wavelength, and where east and west are."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

import numpy as np

#: Nodata in images: a colour no reflectance stretch produces (grey images) and rarely seen in
#: true-colour scenes, said in the figure's notes.
NODATA_COLOUR = (0.85, 0.25, 0.85)
NODATA_NAME = "magenta"

#: Band centres [nm] of a true-colour picture (red, green, blue: Sentinel-2 B4, B3, B2).
TRUE_COLOUR = (665.0, 560.0, 490.0)

#: Band centres [nm] shown when a figure has room for a few bands: blue, green, red, NIR, SWIR 1, SWIR 2.
REPRESENTATIVE = (490.0, 560.0, 665.0, 865.0, 1610.0, 2200.0)


#: An NDVI stratum's name as ``brdfcorr classes ndvi`` writes it: ``ndvi_-inf_0.10``, ``ndvi_0.10_0.30``.
_STRATUM = re.compile(r"ndvi_(-inf|-?[0-9.]+)_(inf|-?[0-9.]+)")


def display_name(name: str) -> str:
    """A class name as a legend shows it: ``roof_tile`` -> ``roof tile``, ``class_2`` -> ``class 2``,
    an NDVI stratum ``ndvi_0.10_0.30`` -> ``NDVI 0.10–0.30`` (``ndvi_-inf_0.10`` -> ``NDVI < 0.10``,
    ``ndvi_0.70_inf`` -> ``NDVI ≥ 0.70``)."""
    stratum = _STRATUM.fullmatch(str(name))
    if stratum is None:
        return str(name).replace("_", " ")
    low, high = stratum.groups()
    if low == "-inf":
        return f"NDVI < {high}"
    return f"NDVI ≥ {low}" if high == "inf" else f"NDVI {low}–{high}"


def nearest_bands(wavelengths: Sequence[float] | None, targets: Sequence[float], tolerance: float = 60.0) -> list[int]:
    """0-based indices of the bands nearest to each target [nm] that lie within ``tolerance`` [nm]
    of it, in the targets' order without repeats; [] without wavelengths."""
    if wavelengths is None or len(wavelengths) == 0:
        return []
    centres = np.asarray(wavelengths, dtype=float)
    chosen: list[int] = []
    for target in targets:
        index = int(np.argmin(np.abs(centres - target)))
        if abs(centres[index] - target) <= tolerance and index not in chosen:
            chosen.append(index)
    return chosen


def true_colour_bands(wavelengths: Sequence[float] | None, n_bands: int) -> list[int]:
    """1-based bands for red, green, blue: the bands nearest 665, 560 and 490 nm where the image
    has all three within 60 nm; else bands 3, 2, 1 of an image with at least three bands; else band 1."""
    chosen = nearest_bands(wavelengths, TRUE_COLOUR)
    if len(chosen) == 3:
        return [index + 1 for index in chosen]
    return [3, 2, 1] if n_bands >= 3 else [1]


def representative_bands(wavelengths: Sequence[float] | None, n_bands: int, most: int) -> list[int]:
    """Up to ``most`` 0-based bands for a figure with one panel per band: those nearest to
    :data:`REPRESENTATIVE` centres where wavelengths are known (ascending), else bands evenly spread."""
    chosen = sorted(nearest_bands(wavelengths, REPRESENTATIVE))
    if chosen:
        keep = np.unique(np.linspace(0, len(chosen) - 1, min(most, len(chosen))).round().astype(int))
        return [chosen[i] for i in keep]
    return np.unique(np.linspace(0, n_bands - 1, min(most, n_bands)).round().astype(int)).tolist()


def is_north_up(transform: Sequence[float] | None) -> bool:
    """Whether columns run west to east and rows north to south (an affine transform
    ``(a, b, c, d, e, f)`` with no rotation, a > 0 and e < 0)."""
    if transform is None:
        return False
    a, b, _, d, e, _ = tuple(transform)[:6]
    return b == 0 and d == 0 and a > 0 and e < 0


def scene_sun_azimuth(tags: Mapping[str, str]) -> float | None:
    """The sun azimuth [deg] a corrected image records (its ``brdf_scene_sun`` tag), or None."""
    match = re.search(r"azimuth (-?[0-9.]+)", tags.get("brdf_scene_sun", ""))
    return float(match[1]) if match else None


def sun_side(azimuth: float) -> str:
    """The image side (of a north-up image: ``"east"`` or ``"west"``) the sun shines from, by
    the east component of the direction towards the sun (azimuth clockwise from north [deg])."""
    return "east" if np.sin(np.radians(azimuth)) >= 0 else "west"
