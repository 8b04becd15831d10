"""Sun and view angle rasters: reading a 4-band raster or four files (:func:`open_angles`,
bands found by their descriptions) and the one physical check of their values
(:func:`check_angles`: degrees, a zenith in [0, 90) somewhere), which also gives the scene means."""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Mapping
from typing import NamedTuple

import dask
import dask.array
import dask.local
import numpy as np
import xarray as xr

from brdfcorr._entry import option
from brdfcorr.errors import BrdfcorrWarning, InputError
from brdfcorr.io.grid import describe_layer
from brdfcorr.io.opening import chunk_spec, open_raster, reading
from brdfcorr.io.sensors.grids import GRID_STATISTICS, grid_window
from brdfcorr.io.writer import local_scheduler

__all__ = ["ANGLE_NAMES", "ANGLE_BAND_NAMES", "RELATIVE_ANGLE_NAMES", "RELATIVE_ONLY", "POSITIONAL",
           "angle_band_name", "open_angles", "from_relative_azimuth", "AngleStatistics", "check_angles",
           "check_angle_values", "window_values"]

ANGLE_NAMES = ("sza", "saa", "vza", "vaa")

#: Band descriptions that name an angle in a 4-band angle raster (:func:`open_angles`), after
#: lower-casing, spaces and hyphens turned into ``_`` and an ``_angle`` suffix dropped.
ANGLE_BAND_NAMES = {
    "sza": ("sza", "solar_zenith", "sun_zenith"),
    "saa": ("saa", "solar_azimuth", "sun_azimuth"),
    "vza": ("vza", "view_zenith", "viewing_zenith", "sensor_zenith"),
    "vaa": ("vaa", "view_azimuth", "viewing_azimuth", "sensor_azimuth"),
    "raa": ("raa", "relative_azimuth", "relative_view_azimuth", "sun_sensor_relative_azimuth"),
}
#: The layers of a 3-band angle raster of products that give the relative azimuth only (MODIS,
#: VIIRS): solar zenith, view zenith and the relative azimuth raa = vaa - saa [deg].
RELATIVE_ANGLE_NAMES = ("sza", "vza", "raa")
#: Attribute of the ``saa`` layer made up for such a source (0 deg, with ``vaa`` = raa): the
#: correction needs only the relative azimuth, a tilted surface or a heading the true ones.
RELATIVE_ONLY = "relative_azimuth_only"
#: Attribute of a layer taken from an angle raster by its band's position (no band description
#: names the angles): its 1-based band. :func:`check_angles` then checks that the values fit that
#: order (:func:`_check_order`), since nothing else says which band is which.
POSITIONAL = "brdf_positional_band"
#: Statistics per layer of :func:`_angle_statistics`: min, max, finite count, count in [0, 90),
#: sum in [0, 90), min and max of the values mod 360 and of the values turned by 180 deg (mod 360):
#: an azimuth's spread, whatever its convention ([0, 360), (-180, 180]) and across north.
N_STATISTICS = 9


def angle_band_name(description: str | None) -> str | None:
    """The angle (``"sza"``, ``"saa"``, ``"vza"``, ``"vaa"``) a band description names, or None.

    Case and spaces/hyphens are ignored (``"Solar Zenith"`` is ``solar_zenith``), and a suffix
    ``_angle`` is allowed (CF standard names: ``solar_zenith_angle``, ``sensor_azimuth_angle``);
    the names are those of :data:`ANGLE_BAND_NAMES`.
    """
    if not description:
        return None
    key = re.sub(r"[\s\-]+", "_", description.strip().lower())
    key = key.removesuffix("_angle")
    return next((angle for angle, names in ANGLE_BAND_NAMES.items() if key in names), None)


def _angle_band_order(path, descriptions, names: tuple[str, ...] = ANGLE_NAMES) -> dict[str, int] | None:
    """Band index of each angle of an angle raster of the layers ``names`` by band descriptions
    that name the angles; None where none do (the documented order of ``names`` applies)."""
    if isinstance(descriptions, str):  # rioxarray keeps one description as a string
        descriptions = (descriptions,)
    descriptions = tuple(descriptions or ())
    named = [angle_band_name(text) for text in descriptions]
    # No descriptions, none naming an angle ("Band 1"), or one on every band (rioxarray describes
    # every band by the array's name: a stack of layers named "sza" says "sza" four times): positional.
    if not any(named) or len(set(descriptions)) == 1:
        return None
    if len(named) != len(names) or sorted(map(str, named)) != sorted(names):
        shown = ", ".join(repr(text) if text else "(none)" for text in descriptions)
        listed = ", ".join(names)
        raise InputError(
            f"angle file {path}: band descriptions {shown} do not name each of {listed} once; "
            f"describe every band ({listed}, or solar_zenith, ...) or none (then the order is {listed})"
        )
    return {name: index for index, name in enumerate(named)}


def from_relative_azimuth(sza: xr.DataArray, vza: xr.DataArray, raa: xr.DataArray) -> dict[str, xr.DataArray]:
    """The four layers of a source that gives the relative azimuth only: ``saa`` = 0 deg and
    ``vaa`` = ``raa`` (both flagged with the attribute :data:`RELATIVE_ONLY`), so that |saa - vaa|
    is |raa| (brdfcorr's convention, ``docs/conventions.md``: raa = vaa - saa, 0 deg at the hotspot)."""
    saa = xr.zeros_like(sza).rename("saa").assign_attrs({RELATIVE_ONLY: 1, "units": "degree"})
    return {"sza": sza, "saa": saa, "vza": vza, "vaa": raa.rename("vaa").assign_attrs({RELATIVE_ONLY: 1})}


def open_angles(path=None, *, sza=None, saa=None, vza=None, vaa=None, raa=None,
                chunks=None) -> dict[str, xr.DataArray]:
    """Open the sun/view angles [deg] as four (y, x) arrays, nodata as NaN, the values scaled by
    the file's own scale and offset (int16 hundredths of a degree with a scale of 0.01 read as degrees).

    Either ``path``, a 4-band raster (sza, saa, vza, vaa) or a 3-band raster of products that give
    the relative azimuth only (sza, vza, raa: MODIS, VIIRS; :func:`from_relative_azimuth`), or
    single-band files: ``sza``, ``saa``, ``vza``, ``vaa``, or ``sza``, ``vza``, ``raa``. The bands
    of a raster are picked by their band descriptions where these name the angles
    (:data:`ANGLE_BAND_NAMES`: ``sza`` or ``solar_zenith``, ..., ``raa`` or ``relative_azimuth``,
    any case), else (no descriptions, none naming an angle, or the same one on every band) taken in
    the order sza, saa, vza, vaa (sza, vza, raa for 3 bands).

    Raises
    ------
    InputError
        A missing or unreadable file, a wrong band count, or band descriptions that name some
        angles but not each once (one line naming the file and its descriptions).
    """
    separate = {"sza": sza, "saa": saa, "vza": vza, "vaa": vaa, "raa": raa}
    given = [name for name, value in separate.items() if value is not None]
    if path is not None and given:
        raise InputError("give either one angle file or the separate sza/saa/vza/vaa (or sza/vza/raa) files, not both")
    if path is not None:
        stack = open_raster(path, "angle", chunk_spec(chunks), masked=True, mask_and_scale=True)
        count = stack.sizes[stack.dims[0]]
        if count not in (3, 4):
            raise InputError(f"angle file {path} has {count} bands; it needs 4 (sza, saa, vza, vaa) or 3 "
                             f"(sza, vza, raa){_sensor_hint(stack)}")
        names = ANGLE_NAMES if count == 4 else RELATIVE_ANGLE_NAMES
        order = _angle_band_order(path, stack.attrs.get("long_name"), names)
        positional = order is None
        order = order or {name: index for index, name in enumerate(names)}
        layers = {name: stack.isel({stack.dims[0]: order[name]}, drop=True).rename(name) for name in names}
        if positional:
            layers = {name: layer.assign_attrs({POSITIONAL: order[name] + 1}) for name, layer in layers.items()}
        return layers if count == 4 else from_relative_azimuth(**layers)
    names = RELATIVE_ANGLE_NAMES if raa is not None else ANGLE_NAMES
    missing = [name for name in names if separate[name] is None]
    extra = [name for name in given if name not in names]
    if extra:
        raise InputError(f"angle file(s) of {', '.join(extra)} do not go with raa: give sza, vza, raa or sza, saa, "
                         "vza, vaa")
    if missing:
        raise InputError(f"missing angle file(s): {', '.join(missing)} (or give one angle file)")
    angles = {}
    for name in names:
        layer = open_raster(separate[name], f"{name} angle", chunk_spec(chunks), masked=True, mask_and_scale=True)
        if layer.sizes[layer.dims[0]] != 1:
            raise InputError(f"{name} angle file {separate[name]} has {layer.sizes[layer.dims[0]]} bands; it needs 1")
        angles[name] = layer.isel({layer.dims[0]: 0}, drop=True).rename(name)
    return angles if raa is None else from_relative_azimuth(**angles)


def _sensor_hint(stack: xr.DataArray) -> str:
    """For an angle raster with the wrong band count: the angle kind that reads it, where its band
    descriptions or count say it is a sensor product (an ENVI obs/obs_ort file: 10 or 11 bands,
    "path length", "to-sensor azimuth", ...)."""
    descriptions = stack.attrs.get("long_name") or ()
    text = " ".join([descriptions] if isinstance(descriptions, str) else descriptions).lower()
    if "to-sensor" in text or "path length" in text or stack.sizes[stack.dims[0]] in (10, 11):
        return f"; an ENVI obs/obs_ort file? Read it with {option('angles_kind_envi')}"
    return ""


class AngleStatistics(NamedTuple):
    """What one pass over the angle layers found (:func:`check_angles`)."""

    ranges: dict[str, tuple[float, float]]
    """(min, max) of the finite values of each layer [deg]."""
    means: dict[str, float]
    """Mean of each layer's values in [0, 90) [deg] (NaN where there is none); ``means["sza"]`` is
    the scene-mean sun zenith of a ``"mean"`` reference geometry."""


def check_angles(layers: Mapping[str, xr.DataArray], source: str | None = None, *, scheduler: str | None = None,
                 num_workers: int | None = None) -> AngleStatistics:
    """Check that sun/view angle layers hold degrees; return their ranges and means [deg].

    One pass over the (lazy) layers, which also gives the scene-mean sun zenith; a layer
    interpolated from a coarse grid that recorded its statistics
    (:data:`~brdfcorr.io.sensors.grids.GRID_STATISTICS`: exact for zeniths interpolated linearly,
    from the coarse cells' corner pixels for azimuths and for a view vector's zenith) needs none. Pixels with a
    zenith outside [0, 90) are not an error here: :func:`brdfcorr.correction.normalize` flags them
    (QA ``invalid_geometry``) and writes nodata. A layer set that cannot be degrees is an error:
    every zenith below 1.6 with every azimuth below 6.3 (radians: pi/2 and 2 pi), or no zenith of a
    layer in [0, 90) at all (scaled or other units); so is a layer without a single finite value
    (all NaN or inf: nothing could be corrected).

    Parameters
    ----------
    layers : mapping of str to DataArray
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] (as from :func:`open_angles`).
    source : str, optional
        Name of the angle source for messages (default: the layers' files).
    scheduler, num_workers : optional
        dask scheduler of the pass and its number of workers (as for :func:`dask.compute`;
        default: dask's).

    Raises
    ------
    InputError
        Naming the angle file (or layer) and the range found; a file that cannot be read to the end
        (truncated, damaged), naming it and GDAL's reason.
    """
    names = [name for name in ANGLE_NAMES if name in layers]
    known = {name: _grid_statistics(layers[name]) for name in names}
    passed = [name for name in names if known[name] is None]  # the layers that need a pass
    measured = (_pixel_statistics(layers, passed, source, scheduler, num_workers) if passed
                else np.empty((1, 0, N_STATISTICS)))
    # A recorded layer is one block among the measured ones: its values, then no values (NaN range, 0 counts).
    per_block = np.zeros((measured.shape[0], len(names), N_STATISTICS))
    per_block[1:, :, :2] = per_block[:, :, 5:] = np.nan  # a recorded layer has no azimuth spread
    for index, name in enumerate(names):
        if known[name] is None:
            per_block[:, index] = measured[:, passed.index(name)]
        else:
            per_block[0, index, :5] = known[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN layers: NaN range
        low, high = np.nanmin(per_block[..., [0, 5, 7]], axis=0), np.nanmax(per_block[..., [1, 6, 8]], axis=0)
    totals = per_block[..., 2:5].sum(axis=0)
    ranges = {name: (float(low[i, 0]), float(high[i, 0])) for i, name in enumerate(names)}
    counts = {name: (int(totals[i, 0]), int(totals[i, 1])) for i, name in enumerate(names)}
    means = {name: totals[i, 2] / totals[i, 1] if totals[i, 1] else math.nan for i, name in enumerate(names)}
    def where(name: str) -> str:
        return source or describe_layer(name, layers[name])

    positional = {name: layers[name].attrs.get(POSITIONAL) for name in names}
    relative = "saa" in layers and bool(layers["saa"].attrs.get(RELATIVE_ONLY))
    check_angle_values(ranges, counts, where, positional, relative=relative)
    if all(positional.values()) and len(names) == len(ANGLE_NAMES):
        _check_order(ranges, _spreads(names, low, high), where)
    return AngleStatistics(ranges, means)


def _spreads(names: list[str], low: np.ndarray, high: np.ndarray) -> dict[str, float]:
    """Each layer's spread [deg]: a zenith's range; an azimuth's the range of its values mod 360,
    or of them turned by 180 deg where that is smaller (values across north). ``low``/``high``:
    (layers, 3) minima and maxima of the values, mod 360, turned (:func:`_angle_statistics`)."""
    width = high - low
    return {name: float(width[i, 0] if name not in ("saa", "vaa") else np.fmin(width[i, 1], width[i, 2]))
            for i, name in enumerate(names)}


def _grid_statistics(layer: xr.DataArray) -> np.ndarray | None:
    """The statistics a coarse-grid reader recorded for ``layer`` (:data:`~brdfcorr.io.sensors.grids.GRID_STATISTICS`,
    :func:`brdfcorr.io.sensors.grids.grid_statistics`) as one block's row, or None (also when the
    layer no longer has the shape they were made for)."""
    recorded = layer.encoding.get(GRID_STATISTICS)
    if recorded is None or tuple(recorded[:2]) != (layer.sizes.get("y"), layer.sizes.get("x")):
        return None
    return np.asarray(recorded[2:], dtype=np.float64)


def _pixel_statistics(layers: Mapping[str, xr.DataArray], names: list[str], source, scheduler,
                      num_workers) -> np.ndarray:
    """(blocks, layers, 5): :func:`_angle_statistics` of every block of the layers ``names``, in one
    pass (one small task per chunk for all layers, not one graph per statistic and layer)."""
    arrays = [layers[name].data for name in names]
    if not any(isinstance(a, dask.array.Array) for a in arrays):
        return _angle_statistics(*(np.asarray(a) for a in arrays)).reshape(-1, len(names), N_STATISTICS)
    first = next(a for a in arrays if isinstance(a, dask.array.Array))
    arrays = [dask.array.asarray(a).rechunk(first.chunks) for a in arrays]
    files = [str(file) for file in dict.fromkeys(layers[n].encoding.get("source") for n in names) if file]
    what = source or (f"angle file{'s' * (len(files) > 1)} {', '.join(files)}" if files else "angles")
    with reading(what):  # a truncated file fails here, in its first pass
        per_block = dask.array.map_blocks(
            _angle_statistics, *arrays, new_axis=[2, 3], chunks=(1, 1, len(names), N_STATISTICS), dtype=np.float64,
        ).compute(scheduler=local_scheduler(scheduler), num_workers=num_workers)
    return per_block.reshape(-1, len(names), N_STATISTICS)


#: Fewest finite values of each layer from which :func:`looks_like_radians` judges the units: a few
#: pixels (one geometry of a test, a goniometer's) may be any angles in degrees.
MIN_VALUES_FOR_UNITS = 16


def looks_like_radians(ranges: Mapping[str, tuple[float, float]], counts: Mapping[str, int]) -> bool:
    """Whether angle layers' (min, max) [deg] can only be radians: every zenith below 1.6 (pi/2) and
    every azimuth below 6.3 (2 pi), with at least one zenith and one azimuth, each of at least
    :data:`MIN_VALUES_FOR_UNITS` finite values (``counts``; NaN ranges: False)."""
    zeniths = [name for name in ("sza", "vza") if name in ranges]
    azimuths = [name for name in ("saa", "vaa") if name in ranges]
    enough = all(counts[n] >= MIN_VALUES_FOR_UNITS for n in zeniths + azimuths)
    return bool(zeniths and azimuths and enough and all(ranges[n][1] < 1.6 for n in zeniths)
                and all(ranges[n][1] < 6.3 for n in azimuths))


def _order_hint(positional: Mapping[str, int | None]) -> str:
    """For layers taken by band position: the order assumed, and how to say another."""
    if not positional or not all(positional.values()):
        return ""
    order = ", ".join(sorted(positional, key=lambda name: positional[name] or 0))
    return (f"; the bands have no descriptions, so they were taken as {order}: if they are in another order, "
            f"describe them ({order}, or solar_zenith, ...)")


def _check_order(ranges: dict, spreads: dict, where) -> None:
    """Refuse a 4-band raster read by position whose sun layers vary far more than its view layers.

    Within one scene the sun's zenith and azimuth change by about 1 deg per 100 km, the view's by
    far more (a swath seen from a few hundred km, or an aircraft's field of view, whose azimuth
    jumps by 180 deg at nadir). Bands 1-2 that vary more than twice as much as bands 3-4 in both
    the zenith and the azimuth (and by more than 1 deg) are the view angles: the order is not
    sza, saa, vza, vaa (e.g. vza, vaa, sza, saa, which the reciprocal models would take silently).
    """
    def wider(sun: str, view: str) -> bool:
        return spreads[sun] > max(2.0 * spreads[view], 1.0)

    if wider("sza", "vza") and wider("saa", "vaa"):
        found = ", ".join(f"{n} {ranges[n][0]:.4g}..{ranges[n][1]:.4g}" for n in ANGLE_NAMES)
        raise InputError(
            f"{where('sza')}: the bands have no descriptions, so they were taken as sza, saa, vza, vaa, but "
            f"bands 1-2 vary far more than bands 3-4 ({found}), as view angles do and the sun's within one "
            "scene do not: is the order vza, vaa, sza, saa? Describe the bands (sza, saa, vza, vaa, or "
            "solar_zenith, ...) or write them in the order sza, saa, vza, vaa"
        )


def check_angle_values(ranges: dict, counts: dict, where, positional: Mapping[str, int | None] | None = None, *,
                  relative: bool = False, whole: bool = True) -> None:
    """The unit checks of :func:`check_angles` on the layers' ranges and (finite, in [0, 90))
    counts; ``where(name)`` names a layer in messages; ``positional`` the band of each layer taken
    by position (:data:`POSITIONAL`), for a hint at the band order. With ``relative`` (a source of
    the relative azimuth only, :func:`from_relative_azimuth`: ``vaa`` is the raa) a raa within
    +-6.3 that is not all 0 is radians (+-2 pi): degrees would put every pixel within 6.3 deg of
    the hotspot. With ``whole`` (the ranges are those of whole layers, not of one chunk), a sun
    zenith below pi/2 everywhere that is not all 0 is a :class:`~brdfcorr.errors.BrdfcorrWarning`:
    the sun within 1.6 deg of the zenith over a whole scene is rare, a sun zenith in radians beside
    azimuths in degrees (which the radians rule takes for degrees) is not."""
    empty = [name for name in counts if counts[name][0] == 0]
    if empty:  # every pixel would be nodata (a NaN sun zenith of a product, a layer of inf)
        raise InputError(f"{where(empty[0])}: no finite {empty[0]} value (all NaN, inf or nodata): "
                         "nothing could be corrected")
    zeniths = [name for name in ("sza", "vza") if name in ranges]
    if looks_like_radians(ranges, {name: count[0] for name, count in counts.items()}):
        raise InputError(radians_message(ranges, where(zeniths[0])))
    if relative and "vaa" in ranges and 0.0 < max(map(abs, ranges["vaa"])) < 6.3:
        low, high = ranges["vaa"]
        raise InputError(f"{where('vaa')}: the relative azimuth (raa) {low:.3g}..{high:.3g} looks like radians; "
                         "brdfcorr needs degrees")
    if whole and "sza" in ranges and 0.0 < ranges["sza"][1] < math.pi / 2:
        low, high = ranges["sza"]
        warnings.warn(BrdfcorrWarning(
            f"{where('sza')}: the sun zenith lies in {low:.3g}..{high:.3g} deg over the whole scene: the sun within "
            f"{high:.2g} deg of the zenith, or radians? brdfcorr needs degrees{option('degrees')}"), stacklevel=2)
    for name in zeniths:
        if counts[name][1] == 0:
            lowest, highest = ranges[name]
            raise InputError(
                f"{where(name)}: no {name} value in [0, 90) deg (found {lowest:.6g}..{highest:.6g}); "
                f"are the angles scaled or in other units?{_order_hint(positional or {})}"
            )


def radians_message(ranges: Mapping[str, tuple[float, float]], where: str) -> str:
    """The one line refusing angle layers that look like radians (:func:`looks_like_radians`)."""
    found = ", ".join(f"{n} {ranges[n][0]:.3g}..{ranges[n][1]:.3g}" for n in ANGLE_NAMES if n in ranges)
    return f"{where}: the angles look like radians ({found}); brdfcorr needs degrees{option('degrees')}"


def _angle_statistics(*blocks: np.ndarray) -> np.ndarray:
    """(1, 1, n_layers, 9): min, max, finite count, count in [0, 90), the sum of the values in
    [0, 90), min and max of the values mod 360 and of the values turned by 180 deg (mod 360) of
    each (y, x) block."""
    result = np.empty((1, 1, len(blocks), N_STATISTICS))
    for index, block in enumerate(blocks):
        values = block[np.isfinite(block)]
        in_domain = values[(values >= 0) & (values < 90)]
        result[0, 0, index, 2:5] = values.size, in_domain.size, in_domain.sum(dtype=np.float64)
        result[0, 0, index, [0, 1, 5, 6, 7, 8]] = np.nan
        if values.size:
            circular = np.mod(values.astype(np.float64), 360.0)
            turned = np.mod(circular + 180.0, 360.0)
            result[0, 0, index, [0, 1, 5, 6, 7, 8]] = (values.min(), values.max(), circular.min(), circular.max(),
                                                       turned.min(), turned.max())
    return result


def window_values(layer: xr.DataArray, rows: slice, cols: slice) -> np.ndarray:
    """The (y, x) window ``rows`` x ``cols`` (slices with start and stop) of an angle layer as float64
    [deg]: from a coarse grid's record where a reader made one
    (:func:`brdfcorr.io.sensors.grids.grid_window`: a few pixels interpolated instead of a whole
    chunk), else read from the layer."""
    window = grid_window(layer, rows, cols)
    if window is None:
        # A few pixels: in this thread (dask's default would import dask.distributed to look for a Client).
        window = layer.isel(y=rows, x=cols).transpose("y", "x").compute(scheduler=dask.local.get_sync)
        window = window.values.astype(np.float64)
    return window
