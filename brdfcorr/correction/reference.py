"""The reference geometry of a correction, resolved once (:func:`resolve_reference`), and how
the factor limits are written in tags."""

from __future__ import annotations

import dask.array as da
import numpy as np
from pyproj import Transformer

from brdfcorr.errors import InputError
from brdfcorr.io.grid import describe_layer, refuse_gcps
from brdfcorr.params import ParameterTable, ReferenceGeometry

__all__ = ["resolve_reference", "describe_limits", "scene_mean_sza", "with_mean_sza", "fixed_sza", "hls_sza",
           "centre_latitude", "with_hls_sza"]


def resolve_reference(reference, params: ParameterTable) -> ReferenceGeometry:
    """The reference geometry to use: the given one (a dict is validated), else the table's, else
    the default (observed sun zenith, nadir view)."""
    if reference is None:
        return params.reference or ReferenceGeometry()
    if isinstance(reference, ReferenceGeometry):
        return reference
    validated = ParameterTable.from_dict({"reference": dict(reference)}, source="reference geometry").reference
    return validated if validated is not None else ReferenceGeometry()


def scene_mean_sza(sza, xp):
    """Mean of the valid solar zeniths (finite, in [0, 90)) [deg]; lazy for dask."""
    valid = (sza >= 0) & (sza < 90)
    return xp.nanmean(xp.where(valid, sza.astype(np.float64), np.nan))


def with_mean_sza(reference: ReferenceGeometry, sza) -> ReferenceGeometry:
    """``reference`` with a ``"mean"`` sun zenith resolved now to the mean of the pixels' ``sza``
    [deg] (:func:`scene_mean_sza`, computed for dask), for the methods that evaluate the factor
    at a subset of points (the angle grid's nodes, a subgrid): each evaluation's own mean is that
    of its points (6 % off in a test); any other reference as it is."""
    if reference.sza != "mean":
        return reference
    values = getattr(sza, "data", sza)
    mean = scene_mean_sza(values, da if isinstance(values, da.Array) else np)
    return reference.model_copy(update={"sza": float(mean.compute() if isinstance(mean, da.Array) else mean)})


def fixed_sza(reference: ReferenceGeometry) -> float:
    # "observed" takes the per-pixel sza inside the block; the scalar is then unused.
    return float(reference.sza) if not isinstance(reference.sza, str) else np.nan


def describe_limits(limits) -> str:
    return "none" if limits is None else f"{limits[0]:g},{limits[1]:g}"


#: HLS v1.4's NBAR sun zenith [deg] as a 6th-order polynomial in latitude [deg], lowest power first
#: (NASA HLS v1.4 User Guide, Claverie et al. 2018, section on the BRDF normalization, p. 13).
HLS_SZA_POLYNOMIAL = (31.0076, -0.1272, 0.01187, 2.40e-05, -9.48e-07, -1.95e-09, 6.15e-11)


def hls_sza(latitude: float) -> float:
    """The reference sun zenith [deg] HLS v1.4 normalizes to at ``latitude`` [deg, north
    positive]: a fit to the sun zeniths of Landsat and Sentinel-2 overpasses over the year
    (31.0 deg at the equator, 47.8 deg at 45 N; :data:`HLS_SZA_POLYNOMIAL`). HLS v2.0 computes
    it per granule and day instead (its ``NBAR_SOLAR_ZENITH`` tag)."""
    if not -90.0 <= latitude <= 90.0:
        raise ValueError(f"latitude {latitude:g} deg is outside [-90, 90]")
    return float(np.polynomial.polynomial.polyval(latitude, HLS_SZA_POLYNOMIAL))


def centre_latitude(image) -> float:
    """The latitude [deg] of the centre of a georeferenced (rioxarray) image."""
    crs, transform = image.rio.crs, image.rio.transform()
    if crs is None:
        raise InputError("the reference sun zenith 'hls' needs a georeferenced image (a CRS) for its latitude")
    refuse_gcps(image, describe_layer("the image", image), "the reference sun zenith 'hls' (the latitude of its "
                "centre)", "give the reference sun zenith in degrees")
    x, y = transform * (image.sizes["x"] / 2.0, image.sizes["y"] / 2.0)
    _, latitude = Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(x, y)
    return float(latitude)


def with_hls_sza(reference: ReferenceGeometry, image) -> ReferenceGeometry:
    """``reference`` with a sun zenith ``"hls"`` replaced by :func:`hls_sza` at the image's centre."""
    if reference.sza != "hls":
        return reference
    return reference.model_copy(update={"sza": hls_sza(centre_latitude(image))})
