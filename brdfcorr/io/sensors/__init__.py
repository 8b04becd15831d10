"""Sun and view angles (and imaging-spectrometer cubes) as sensor products deliver them.

Every reader returns the same thing: an :class:`xarray.Dataset` with ``sza``, ``saa``, ``vza``,
``vaa`` in degrees on the image grid (dims ``y``, ``x``; CRS and transform where the product has
them), dask-backed, azimuths clockwise from north of the directions from the pixel *towards* the sun
and *towards* the sensor (``docs/conventions.md``). Each product's own convention is stated in its module and
converted explicitly (``view_azimuth="to_sensor"|"from_sensor"``), never guessed.

=============  ==========================================================  =====================
kind           product                                                     reader
=============  ==========================================================  =====================
``envi_obs``   AVIRIS-NG / AVIRIS-3 (and alike) ``obs``/``obs_ort`` file   :func:`read_envi_obs`
``sentinel2``  Sentinel-2 L1C/L2A granule ``MTD_TL.xml``                   :func:`read_sentinel2_angles`
``landsat``    Landsat Collection 2 angle bands (+ ANG.txt)                :func:`read_landsat_angles`
``solar``      none: solar angles from time and pixel coordinates, plus   :func:`read_solar_angles`
               an explicitly given constant view geometry
``neon``       NEON AOP reflectance HDF5 (to-sensor rasters, logged sun)  :func:`read_neon_angles`
``emit``       EMIT L1B OBS NetCDF, orthorectified by its GLT             :func:`read_emit_obs`
=============  ==========================================================  =====================

The NEON and EMIT reflectance cubes themselves are images (:func:`read_neon_image`,
:func:`read_emit_image`), which :func:`brdfcorr.io.rasters.open_image` opens by content.

The one call for the correction and chain configs is ``read_angles(kind, path, like=image)``.

Whole product folders (a Sentinel-2 L2A ``.SAFE``, a Landsat Collection-2 L2 folder: bands,
scaling, cloud mask, angle source) are found by :func:`find_product` and stacked by
:func:`write_stack` (:mod:`brdfcorr.io.sensors.folders`; ``brdfcorr nbar``).
"""

from __future__ import annotations

import importlib
import inspect
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from brdfcorr.errors import SensorInputError

if TYPE_CHECKING:  # xarray is imported by the readers: the command line's start needs this module only
    import xarray as xr

#: Where each public name lives. The readers are imported at first use (PEP 562): they pull in
#: pandas, pvlib, h5py and rasterio, which the command line's start and argument errors need not.
_MODULES = {
    "apply_glt": "emit", "read_emit_image": "emit", "read_emit_obs": "emit",
    "acquisition_time": "envi", "envi_wavelengths": "envi", "read_envi_image": "envi", "read_envi_obs": "envi",
    "find_product": "folders", "write_stack": "folders",
    "grid_template": "grids", "to_grid": "grids",
    "parse_ang_txt": "landsat", "read_landsat_angles": "landsat",
    "read_neon_angles": "neon", "read_neon_image": "neon",
    "parse_mtd_tl": "sentinel2", "read_sentinel2_angles": "sentinel2",
    "solar_angles": "solar", "solar_position": "solar",
}


def __getattr__(name: str):
    if name not in _MODULES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_MODULES[name]}"), name)
    globals()[name] = value
    return value


def _reader(name: str) -> Callable[..., xr.Dataset]:
    """The reader ``name``, imported when it is called."""

    def read(*args, **options) -> xr.Dataset:
        return __getattr__(name)(*args, **options)

    read.__name__ = read.__qualname__ = name
    return read

__all__ = [
    "ANGLE_KINDS",
    "flip_refusal",
    "acquisition_time",
    "apply_glt",
    "envi_wavelengths",
    "find_product",
    "grid_template",
    "parse_ang_txt",
    "parse_mtd_tl",
    "read_angles",
    "read_emit_image",
    "read_emit_obs",
    "read_envi_image",
    "read_envi_obs",
    "read_landsat_angles",
    "read_neon_angles",
    "read_neon_image",
    "read_sentinel2_angles",
    "read_solar_angles",
    "solar_angles",
    "solar_position",
    "to_grid",
    "write_stack",
]


def read_solar_angles(time, like: xr.DataArray, *, view_zenith: float | None = None,
                      view_azimuth: float | None = None, **options) -> xr.Dataset:
    """Solar angles from ``time`` and the pixel coordinates of ``like`` (pvlib SPA), with a
    constant view geometry that the caller states (e.g. ``view_zenith=0`` for a nadir view).

    Parameters
    ----------
    time : str, datetime or pandas.Timestamp
        Acquisition time, timezone-aware.
    like : xarray.DataArray
        Georeferenced image.
    view_zenith, view_azimuth : float
        View zenith [deg] and azimuth towards the sensor [deg], applied to every pixel.
    **options :
        Passed to :func:`brdfcorr.io.sensors.solar.solar_angles`.

    Raises
    ------
    SensorInputError
        ``view_zenith`` or ``view_azimuth`` not given: the view geometry is never assumed.
    """
    if view_zenith is None or view_azimuth is None:
        raise SensorInputError(
            "angle source kind 'solar' gives only sun angles: set view_zenith and view_azimuth "
            "(degrees; e.g. view_zenith=0 for a nadir view) explicitly"
        )
    import xarray as xr

    from brdfcorr.io.sensors.solar import solar_angles  # pvlib: only for this kind

    angles = solar_angles(time, like, **options)
    for key, value, long_name in (
        ("vza", view_zenith, "view zenith angle"),
        ("vaa", view_azimuth % 360.0, "view azimuth angle (pixel to sensor, clockwise from north)"),
    ):
        angles[key] = xr.full_like(angles["sza"], float(value)).assign_attrs(
            units="degree", long_name=long_name, source="constant given by the user")
    return angles


#: Source kinds accepted by :func:`read_angles` and their readers.
ANGLE_KINDS: dict[str, Callable[..., xr.Dataset]] = {
    "envi_obs": _reader("read_envi_obs"),
    "sentinel2": _reader("read_sentinel2_angles"),
    "landsat": _reader("read_landsat_angles"),
    "solar": read_solar_angles,
    "neon": _reader("read_neon_angles"),
    "emit": _reader("read_emit_obs"),
}


def flip_refusal(angles_kind: str, flip_view_azimuth: bool, setting: str) -> str | None:
    """Why a 180 deg flip of the view azimuths (``setting``, as the caller names it) is refused
    for angles of ``angles_kind``, or None: every reader of :data:`ANGLE_KINDS` but ``solar`` (whose
    view azimuth is the one given, a number) applies its product's own
    convention (``docs/sensors.md``), so the flip turned its azimuths the wrong way (2.4 % on a
    real AVIRIS-NG line) or undid a reader's ``view_azimuth=from_sensor``, without a word."""
    if flip_view_azimuth is not True or angles_kind in ("geotiff", "solar"):  # solar: the view azimuth typed in
        return None
    return (f"{setting} is for angle rasters stored another way (angles kind geotiff): the {angles_kind} reader "
            "gives view azimuths from the pixel towards the sensor already; leave it out (docs/sensors.md)")


def read_angles(kind: str, source, like: xr.DataArray | None = None, **options) -> xr.Dataset:
    """Read or compute ``sza``, ``saa``, ``vza``, ``vaa`` [deg] on the image grid.

    Parameters
    ----------
    kind : {"envi_obs", "sentinel2", "landsat", "solar", "neon", "emit"}
        The source kind (see the module table).
    source :
        The obs file, the ``MTD_TL.xml``, the Landsat product directory or file, the NEON
        reflectance HDF5, the EMIT L1B OBS NetCDF, or for ``"solar"`` the acquisition time. A
        path is made absolute here, so that the lazy reads of every kind (and of the files found
        beside it: a Landsat product's angle bands) run on dask.distributed workers started in
        another folder; the readers' messages name it so.
    like : xarray.DataArray, optional
        The image the angles are for (required for ``"solar"``).
    **options :
        Passed to the kind's reader (e.g. ``band="B04"``, ``ang=...``, ``view_azimuth=...``).

    Raises
    ------
    SensorInputError
        Unknown kind, or any problem of the source (the message names file and item).
    """
    try:
        reader = ANGLE_KINDS[kind]
    except KeyError:
        raise SensorInputError(
            f"unknown angle source kind {kind!r}; choose one of {', '.join(ANGLE_KINDS)}"
        ) from None
    if kind == "solar" and like is None:
        raise SensorInputError("angle source kind 'solar' needs the image grid (like=image)")
    if kind != "solar" and isinstance(source, (str, os.PathLike)):  # (solar: a time)
        # An absolute path, as brdfcorr.io.opening.open_raster opens rasters: the graph's reads may
        # run on dask.distributed workers started elsewhere.
        source = Path(source).absolute()
    _check_options(kind, reader, options)
    return reader(source, like, **options)


def _check_options(kind: str, reader, options) -> None:
    """Refuse an option the kind's reader does not take (a misspelt key, or ``like``, which is the
    image), naming those it takes: passed on, it was a TypeError, an internal error."""
    function = __getattr__(reader.__name__) if reader.__name__ in _MODULES else reader
    parameters = list(inspect.signature(function).parameters.values())[2:]  # after the source and like
    if any(parameter.kind == parameter.VAR_KEYWORD for parameter in parameters):
        return
    taken = [parameter.name for parameter in parameters]
    unknown = sorted(set(options) - set(taken))
    if unknown:
        raise SensorInputError(f"angle option {unknown[0]!r} is no option of angle kind {kind!r}; its options: "
                               f"{', '.join(taken) or 'none'}")
