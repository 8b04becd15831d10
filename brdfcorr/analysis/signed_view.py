"""The signed view zenith of each pixel (:func:`signed_view_zenith`): the view zenith [deg] with a
sign for its side of nadir, by the sun (forward or backward scattering) or by the flight direction
(right or left of the track); the axis along which :mod:`brdfcorr.analysis.view_angles` measures
the view-angle signal left in a scene.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from brdfcorr._arrays import cosd, sind
from brdfcorr.defaults import SIGN_CONVENTIONS
from brdfcorr.errors import InputError
from brdfcorr.io.angles import RELATIVE_ONLY

__all__ = ["SIGN_CONVENTIONS", "signed_view_zenith", "check_signing"]


# SIGN_CONVENTIONS, how the sign of the view zenith is chosen (:func:`signed_view_zenith`), is
# brdfcorr.defaults' (the command line's words too).
_SIGN_WORDS = {
    "sun": ("forward scattering: relative azimuth > 90 deg, the sensor opposite the sun",
            "backscattering: relative azimuth < 90 deg, the sensor on the sun's side"),
    "track": ("right of the flight direction (east of a line flown north)",
              "left of the flight direction (west of a line flown north)"),
}


def signed_view_zenith(vza, vaa, saa=None, *, by: Literal["sun", "track"] = "sun", heading: float | None = None):
    """The view zenith with a sign for the side of nadir the pixel is seen from.

    Parameters
    ----------
    vza : array-like
        View zenith [deg].
    vaa : array-like
        Azimuth of the direction from the pixel towards the sensor [deg], clockwise from north
        (``docs/conventions.md``).
    saa : array-like, optional
        Azimuth of the direction from the pixel towards the sun [deg]; needed for ``by="sun"``.
    by : {"sun", "track"}, default "sun"
        ``"sun"``: positive in the forward-scattering half (relative azimuth φ > 90°, the sensor
        opposite the sun: the side of the specular peak), negative in the backscattering half
        (φ < 90°: the side of the hot spot). ``"track"``: positive to the right of the flight
        direction ``heading`` (east of a line flown north), negative to its left.
    heading : float, optional
        Flight direction [deg], clockwise from north; needed for ``by="track"``.

    Returns
    -------
    array-like
        Signed view zenith [deg] in (-90, 90), of the kind of the inputs (numpy, dask or xarray).
        Pixels seen exactly perpendicular to the sun (φ = 90°) or to the track get 0.

    Notes
    -----
    ``"sun"``: θ_signed = θ_r · sign(−cos(saa − vaa)), since cos φ = cos(saa − vaa) < 0 exactly
    when φ > 90°. ``"track"``: θ_signed = θ_r · sign(sin(heading − vaa)); a pixel right of a
    northbound track sees the sensor to its west (vaa = 270°), sin(0° − 270°) = 1.
    """
    if by == "sun":
        if saa is None:
            raise InputError("the signed view zenith by the sun needs the solar azimuth (saa)")
        side = -cosd(saa - vaa)
    elif by == "track":
        if heading is None or not math.isfinite(heading):
            raise InputError("the signed view zenith by the track needs the flight direction (heading) in degrees")
        side = sind(heading - vaa)
    else:
        raise InputError(f"sign convention {by!r} is not one of {', '.join(SIGN_CONVENTIONS)}")
    return vza * np.sign(side)


def check_signing(by: str, *azimuths) -> None:
    """Refuse signing by the flight track (``by="track"``) with azimuth layers (``saa``, ``vaa``:
    DataArrays) of a source that gives the relative azimuth only (their attribute
    :data:`brdfcorr.io.angles.RELATIVE_ONLY`; MODIS, VIIRS): their ``vaa`` is the relative
    azimuth, so sin(heading - vaa) says nothing of a side of the track. Signing by the sun needs
    only the relative azimuth."""
    if by == "track" and any(getattr(layer, "attrs", {}).get(RELATIVE_ONLY) for layer in azimuths):
        raise InputError("signing by the track needs the sensor's azimuth; the angle source gives only the "
                         "relative azimuth (raa): sign by the sun")
