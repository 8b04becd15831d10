"""An HLS v2.0 granule's NBAR moved to another sun zenith (``brdfcorr nbar GRANULE --ref-sza DEG``).

An HLS granule is NBAR already (:mod:`brdfcorr.io.sensors.hls`): nadir view at the granule's sun
zenith θ (``NBAR_SOLAR_ZENITH``), made with the c-factor and the coefficients of Roy et al.
(2016, 2017). Moving it to a sun zenith θ′ with the same coefficients is exact, one factor per band
for the whole granule:

    NBAR(θ′) = NBAR(θ) · f(θ′, 0, 0) / f(θ, 0, 0)        (Roy et al. 2016, eq. 7, view at nadir)

so HLS granules and brdfcorr's Sentinel-2 and Landsat NBAR can be brought to one sun zenith.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Literal

import numpy as np
import rioxarray
import xarray as xr

from brdfcorr.correction import QA, qa_attrs
from brdfcorr.correction.reference import resolve_reference, with_hls_sza
from brdfcorr.errors import SensorInputError
from brdfcorr.io.grid import grid_difference
from brdfcorr.io.scale_check import check_reflectance_scale
from brdfcorr.io.sensors.hls import HLS_FMASK_MASKED, HlsGranule
from brdfcorr.io.writer import wavelength_tags
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.params import ParameterTable
from brdfcorr.tasks.request import Engine

__all__ = ["hls_sun_zenith_layers", "hls_factors", "band_scale", "HLS_SCALE"]

#: HLS v2.0 stores reflectance x 10 000 (int16) where a band file gives no scale of its own.
HLS_SCALE = 1e-4
#: The value of an Fmask pixel outside the granule's data.
FMASK_FILL = 255


def hls_factors(granule: HlsGranule, coefficients: str, sza: float) -> np.ndarray:
    """Per band, f(sza, 0, 0) / f(nbar_sza, 0, 0) with the bands' coefficients [-] (module docstring)."""
    library = load_coefficients(coefficients)
    spectral = [library.sensor_band(granule.sensor, band) for band in granule.coefficient_bands]
    return np.array([float(library.brdf(sza, 0.0, 0.0, name) / library.brdf(own, 0.0, 0.0, name))
                     for name, own in zip(spectral, granule.nbar_sza, strict=True)])


def band_scale(band: xr.DataArray) -> float:
    """Reflectance per stored value of a band file: its own scale where it gives one, else
    :data:`HLS_SCALE` for integers (HLS v2.0) and 1 for floats (reflectance already, as a
    reprocessed granule holds it)."""
    scale = float(band.attrs.get("scale_factor", 1.0))
    if scale != 1.0:
        return scale
    stored = np.dtype(band.encoding.get("rasterio_dtype", band.encoding.get("dtype", band.dtype)))
    return HLS_SCALE if np.issubdtype(stored, np.integer) else 1.0


def _reflectance(granule: HlsGranule, chunks: int) -> xr.DataArray:
    """The bands (band, y, x) as reflectance factors [1], no data as NaN (lazy)."""
    layers = []
    for name, path in granule.bands.items():
        band = rioxarray.open_rasterio(path, chunks={"y": chunks, "x": chunks}, masked=True, lock=False)
        layer = band.isel(band=0, drop=True)
        difference = grid_difference(layer, layers[0]) if layers else None  # the one grid check (io.grid)
        if difference is not None:
            first, where = next(iter(granule.bands.items()))
            raise SensorInputError(f"{path}: band {name} is not on the grid of band {first} {where}: {difference}")
        layers.append(layer * band_scale(band))
    stack = xr.concat(layers, dim="band").assign_coords(band=np.arange(1, len(layers) + 1))
    return stack.assign_coords(wavelength=("band", list(granule.wavelengths))).astype(np.float32)


def _masked(granule: HlsGranule, like: xr.DataArray, bits: Sequence[int], chunks: int) -> xr.DataArray:
    """Pixels the Fmask makes no data (any of ``bits``, or its fill); none without an Fmask."""
    if granule.fmask is None:
        return xr.zeros_like(like.isel(band=0, drop=True), dtype=bool)
    fmask = rioxarray.open_rasterio(granule.fmask, chunks={"y": chunks, "x": chunks}, lock=False)
    fmask = fmask.isel(band=0, drop=True)
    difference = grid_difference(fmask, like.isel(band=0, drop=True))  # the one grid check (io.grid)
    if difference is not None:
        raise SensorInputError(f"{granule.fmask}: the Fmask is not on the grid of band {next(iter(granule.bands))} "
                               f"{next(iter(granule.bands.values()))}: {difference}")
    flags = sum(1 << bit for bit in bits)
    return ((fmask & flags) != 0) | (fmask == FMASK_FILL)


def hls_sun_zenith_layers(granule: HlsGranule, *, coefficients: str, reference_sza: float | Literal["hls"],
                          masked: Sequence[int] | None = None, engine: Engine = Engine()):
    """``granule``'s NBAR moved to sun zenith ``reference_sza`` [deg], or ``"hls"``: HLS v1.4's for
    the granule centre's latitude (module docstring), lazily. (``"mean"`` and ``"observed"`` leave
    a granule as it is: :func:`brdfcorr.tasks.nbar.nbar_files` refuses them with
    :func:`brdfcorr.io.sensors.hls.hls_refusal`.)

    Returns
    -------
    tuple
        The corrected bands (band, y, x), float32 reflectance factors, NaN where masked; their QA
        flags (y, x; ``nodata``); the output's tags; the reference (:class:`ReferenceGeometry`).
    """
    chunks = engine.chunks or 512
    reflectance = _reflectance(granule, chunks)
    check_reflectance_scale(reflectance, str(granule.path), scheduler=engine.scheduler,
                            num_workers=engine.num_workers)
    invalid = _masked(granule, reflectance, HLS_FMASK_MASKED if masked is None else masked, chunks)
    # Validated as every reference geometry is (a finite sun zenith in [0, 90), one line naming it).
    reference = with_hls_sza(resolve_reference({"sza": reference_sza, "vza": 0.0, "raa": 0.0}, ParameterTable()),
                             reflectance)
    sza = float(reference.sza)
    factors = xr.DataArray(hls_factors(granule, coefficients, sza).astype(np.float32), dims="band")
    corrected = (reflectance * factors).where(~invalid)
    nodata = (~np.isfinite(corrected)).any("band") | invalid
    qa = xr.where(nodata, np.uint8(QA.NODATA), np.uint8(0)).astype(np.uint8).assign_attrs(qa_attrs("QA flags"))
    tags = {**wavelength_tags(granule.wavelengths), "brdf_reference": reference.describe(),
            "brdf_hls_nbar_solar_zenith": ",".join(dict.fromkeys(f"{value:g}" for value in granule.nbar_sza))
            if len(set(granule.nbar_sza)) == 1 else ",".join(f"{value:g}" for value in granule.nbar_sza),
            "brdf_coefficients": json.dumps({"set": coefficients, "bands": list(granule.coefficient_bands)}),
            "brdf_method": "HLS NBAR x f(ref sza, 0, 0) / f(NBAR_SOLAR_ZENITH, 0, 0) per band (Roy et al. 2016)"}
    return corrected, qa, tags, reference
