"""Sentinel-2 sun and view angles from the granule metadata (``MTD_TL.xml``).

A Sentinel-2 L1C/L2A granule (a 109.8 km tile) carries its geometry as grids of 23 x 23 nodes at
5 km: one for the sun, and one per band *and detector* for the view direction, NaN where that
detector does not see the node. This module parses them (``xml.etree``) and interpolates them
lazily onto the 10, 20 or 60 m image grid, or any georeferenced grid, with
:func:`brdfcorr.io.sensors.grids.to_grid`: the sun zenith linearly, the sun azimuth through its sine
and cosine.

The view direction is handled as one vector throughout, the ground-projected view vector
(tan θv sin φv, tan θv cos φv) (:func:`brdfcorr.io.sensors.grids.view_vector`): the detectors of
a band are combined on it (its mean where detectors overlap; remaining gaps, nodes outside every
detector, filled from the nearest node that has a value), the bands are averaged on it, and its two
components are interpolated to the pixels as ordinary grids, the view zenith and azimuth of each
pixel being those of its interpolated vector. The satellite's nadir line crosses most tiles: there
the view azimuth turns by 180 deg between neighbouring nodes and the view zenith has its minimum
near 0, while the vector's components vary nearly linearly across track (for a sensor at height H
above a flat ground they are the offset from the pixel to the sensor over H). Interpolated apart,
zenith and azimuth were off there (a closed-form nadir line: the zenith by 0.16 deg, the azimuth by
up to 99 deg, where it matters little, the view being near vertical).

Node ``(i, j)`` of an angle grid lies at ``(ULX + j * COL_STEP, ULY - i * ROW_STEP)``, the tile's
upper-left corner being node (0, 0) (ESA S2 MSI product specification, Tile_Angles); as a raster
the nodes are pixel centres of a grid whose corner is half a step up and left of the tile corner.

Conventions (``docs/conventions.md``): the sun azimuth in the metadata is the azimuth of the direction towards
the sun; the viewing incidence azimuth is the azimuth of the direction from the pixel towards the
satellite (the view zenith of the real tile in ``shared/realdata`` decreases towards the stored view
azimuth, that is towards the satellite ground track; tests check both against the product's own
geometry). No flip is needed; ``view_azimuth="from_sensor"`` flips explicitly for a product that
differs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr
from affine import Affine
from rasterio.crs import CRS
from rasterio.errors import CRSError
from scipy import ndimage

from brdfcorr.errors import SensorInputError
from brdfcorr.io.files import read_xml
from brdfcorr.io.sensors.grids import Kind, grid_template, to_grid, view_angles, view_vector, wrap_azimuth

__all__ = [
    "BAND_NAMES",
    "TileAngles",
    "combine_detectors",
    "combined_view_vector",
    "fill_gaps",
    "parse_mtd_tl",
    "read_sentinel2_angles",
]

#: Band names in the order of the metadata's ``bandId`` (0 to 12).
BAND_NAMES = ("B01", "B02", "B03", "B04", "B05", "B06", "B07", "B08", "B8A", "B09", "B10", "B11", "B12")


@dataclass
class TileAngles:
    """The angle content of one ``MTD_TL.xml``; grids are (row, column) numpy arrays [deg]."""

    path: Path
    crs: str
    sensing_time: pd.Timestamp
    sizes: dict[int, tuple[int, int]]  # resolution [m] -> (rows, columns)
    geopositions: dict[int, Affine]  # resolution [m] -> pixel-corner transform of the image
    node_transform: Affine  # the angle nodes as pixel centres
    sun_zenith: np.ndarray
    sun_azimuth: np.ndarray
    view_zenith: dict[str, dict[int, np.ndarray]] = field(default_factory=dict)  # band -> detector
    view_azimuth: dict[str, dict[int, np.ndarray]] = field(default_factory=dict)


def _find(element, path: str, source: Path):
    found = element.find(path)
    if found is None:
        raise SensorInputError(f"{source}: no <{path}> element in the granule metadata")
    return found


def _text(element, tag: str, source: Path) -> str:
    """The stripped text of ``tag`` under ``element``; an empty one is an error naming the tag."""
    text = (_find(element, tag, source).text or "").strip()
    if not text:
        raise SensorInputError(f"{source}: <{tag}> is empty in the granule metadata")
    return text


def _number(text: str | None, what: str, source: Path, kind: type = float):
    """``text`` as a finite number of ``kind`` (float or int), else an error naming ``what``."""
    if text is None:
        raise SensorInputError(f"{source}: no {what} in the granule metadata")
    try:
        value = kind(str(text).strip())
    except ValueError:
        raise SensorInputError(f"{source}: {what} {text!r} is not {'an integer' if kind is int else 'a number'}"
                               ) from None
    if not np.isfinite(value):
        raise SensorInputError(f"{source}: {what} {text!r} is not a finite number")
    return value


def _crs(text: str, source: Path) -> str:
    """The tile's ``HORIZONTAL_CS_CODE`` as given, once rasterio knows it (``EPSG:32632``)."""
    try:
        CRS.from_user_input(text)
    except CRSError:
        raise SensorInputError(f"{source}: <HORIZONTAL_CS_CODE> {text!r} is not a known CRS") from None
    return text


def _band_name(value: str | None, source: Path) -> str:
    """The band of a view grid's ``bandId`` (0 to 12 in the order of :data:`BAND_NAMES`)."""
    index = _number(value, "Viewing_Incidence_Angles_Grids bandId", source, int)
    if not 0 <= index < len(BAND_NAMES):
        raise SensorInputError(f"{source}: Viewing_Incidence_Angles_Grids bandId {value!r} is no Sentinel-2 "
                               f"band id (0 to {len(BAND_NAMES) - 1})")
    return BAND_NAMES[index]


def _sensing_time(root, source: Path) -> pd.Timestamp:
    text = _text(root, ".//SENSING_TIME", source)
    try:
        time = pd.Timestamp(text)
    except ValueError:
        time = pd.NaT
    if pd.isna(time):
        raise SensorInputError(f"{source}: <SENSING_TIME> {text!r} is not a date and time")
    return time


def _values_list(element, source: Path, what: str) -> tuple[np.ndarray, float, float]:
    """A ``Values_List`` grid (NaN kept) and its column and row steps [m], both > 0."""
    try:
        rows = [[float(value) for value in (row.text or "").split()] for row in element.iter("VALUES")]
        grid = np.array(rows, dtype="float64")
    except ValueError as error:
        raise SensorInputError(f"{source}: malformed {what} grid ({error})") from error
    if grid.ndim != 2 or grid.size == 0:
        raise SensorInputError(f"{source}: {what} grid rows have unequal lengths or are empty")
    steps = []
    for tag in ("COL_STEP", "ROW_STEP"):
        step = _number(_text(element, tag, source), f"{what} <{tag}>", source)
        if step <= 0:
            raise SensorInputError(f"{source}: {what} <{tag}> {step:g} must be > 0 (metres between nodes)")
        steps.append(step)
    return grid, steps[0], steps[1]


def _geocoding(root, path: Path) -> tuple[str, dict[int, tuple[int, int]], dict[int, Affine]]:
    """The tile's CRS, image sizes and pixel-corner transforms by resolution [m] (``Tile_Geocoding``)."""
    geocoding = _find(root, ".//Tile_Geocoding", path)
    crs = _crs(_text(geocoding, "HORIZONTAL_CS_CODE", path), path)
    sizes, geopositions = {}, {}
    for size in geocoding.findall("Size"):
        resolution = _number(size.get("resolution"), "Size resolution", path, int)
        shape = tuple(_number(_text(size, tag, path), f"<{tag}> of resolution {resolution}", path, int)
                      for tag in ("NROWS", "NCOLS"))
        if min(shape) < 1:
            raise SensorInputError(f"{path}: <Size> of resolution {resolution} has {shape[0]} x {shape[1]} pixels")
        sizes[resolution] = shape
    for position in geocoding.findall("Geoposition"):
        resolution = _number(position.get("resolution"), "Geoposition resolution", path, int)
        ulx, uly, xdim, ydim = (_number(_text(position, tag, path), f"<{tag}> of resolution {resolution}", path)
                                for tag in ("ULX", "ULY", "XDIM", "YDIM"))
        if xdim <= 0 or ydim >= 0:
            raise SensorInputError(f"{path}: <XDIM> {xdim:g} and <YDIM> {ydim:g} of resolution {resolution} must "
                                   "be > 0 and < 0 (north-up pixels)")
        geopositions[resolution] = Affine(xdim, 0.0, ulx, 0.0, ydim, uly)
    if not geopositions:
        raise SensorInputError(f"{path}: no <Geoposition> element in the granule metadata")
    return crs, sizes, geopositions


def _view_grids(angles, tile: TileAngles) -> None:
    """Add the per-band, per-detector view grids of ``Tile_Angles`` to ``tile``; each on the sun
    grid's nodes."""
    path = tile.path
    for grids in angles.findall("Viewing_Incidence_Angles_Grids"):
        band = _band_name(grids.get("bandId"), path)
        detector = _number(grids.get("detectorId"), f"{band} Viewing_Incidence_Angles_Grids detectorId", path, int)
        zenith, *_ = _values_list(_find(grids, "Zenith", path), path, f"{band} detector {detector} view zenith")
        azimuth, *_ = _values_list(_find(grids, "Azimuth", path), path, f"{band} detector {detector} view azimuth")
        for what, grid in (("zenith", zenith), ("azimuth", azimuth)):
            if grid.shape != tile.sun_zenith.shape:
                raise SensorInputError(f"{path}: {band} detector {detector} view {what} grid has {grid.shape[0]} x "
                                       f"{grid.shape[1]} nodes, the sun grid {tile.sun_zenith.shape[0]} x "
                                       f"{tile.sun_zenith.shape[1]}")
        tile.view_zenith.setdefault(band, {})[detector] = zenith
        tile.view_azimuth.setdefault(band, {})[detector] = azimuth
    if not tile.view_zenith:
        raise SensorInputError(f"{path}: no <Viewing_Incidence_Angles_Grids> in the granule metadata")


def parse_mtd_tl(path: str | Path) -> TileAngles:
    """Parse the sun and viewing angle grids, image sizes and geoposition of a granule.

    Every field is checked before it is used: a known CRS, integer sizes, numeric corners, node
    steps > 0, band ids 0 to 12, integer detector ids, a date and time, grids of one shape.

    Raises
    ------
    SensorInputError
        Unreadable XML, a missing, empty or malformed element (named in the message, with its value).
    """
    path = Path(path)
    root = read_xml(path, "the granule metadata", SensorInputError)
    crs, sizes, geopositions = _geocoding(root, path)
    angles = _find(root, ".//Tile_Angles", path)
    sun = _find(angles, "Sun_Angles_Grid", path)
    sun_zenith, col_step, row_step = _values_list(_find(sun, "Zenith", path), path, "sun zenith")
    sun_azimuth, *_ = _values_list(_find(sun, "Azimuth", path), path, "sun azimuth")
    if sun_azimuth.shape != sun_zenith.shape:
        raise SensorInputError(f"{path}: the sun azimuth grid has {sun_azimuth.shape[0]} x {sun_azimuth.shape[1]} "
                               f"nodes, the sun zenith grid {sun_zenith.shape[0]} x {sun_zenith.shape[1]}")
    corner = next(iter(geopositions.values()))
    node_transform = Affine(col_step, 0.0, corner.c - col_step / 2, 0.0, -row_step, corner.f + row_step / 2)
    tile = TileAngles(path, crs, _sensing_time(root, path), sizes, geopositions, node_transform, sun_zenith,
                      sun_azimuth)
    _view_grids(angles, tile)
    return tile




def _nan_mean(stack: np.ndarray) -> np.ndarray:
    """Mean over axis 0 ignoring NaN; NaN where all are NaN (without numpy's empty-slice warning)."""
    valid = np.isfinite(stack)
    count = valid.sum(axis=0)
    total = np.where(valid, stack, 0.0).sum(axis=0)
    return np.divide(total, count, out=np.full(total.shape, np.nan), where=count > 0)


def fill_gaps(grid: np.ndarray, angle: bool = False, what: str = "an angle grid") -> np.ndarray:
    """Fill NaN nodes with the value of the nearest finite node (Euclidean distance in nodes).

    Nodes outside every detector's footprint lie at the tile edges, beyond the image data; the
    nearest value keeps the interpolation between the last valid node and the edge sensible. For
    ``angle=True`` the filled values are azimuths and stay in [0, 360). An all-NaN grid raises,
    naming it as ``what`` (its file and layer).
    """
    missing = ~np.isfinite(grid)
    if not missing.any():
        return grid
    if missing.all():
        raise SensorInputError(f"{what} has no finite value at all")
    nearest = ndimage.distance_transform_edt(missing, return_distances=False, return_indices=True)
    filled = grid[tuple(nearest)]
    return wrap_azimuth(filled) if angle else filled


def combined_view_vector(zenith: dict[int, np.ndarray], azimuth: dict[int, np.ndarray],
                         what: str = "the view") -> np.ndarray:
    """One gap-free ground-projected view vector grid (2, y, x) [-] (east, north:
    :func:`brdfcorr.io.sensors.grids.view_vector`) of a band from its per-detector view zenith and
    azimuth grids [deg].

    Where two detectors see the same node (the overlap of adjacent detectors), their vectors are
    averaged; each detector's NaN gaps are thereby filled from the others. Remaining gaps are
    filled by :func:`fill_gaps`, both components from the same nearest node.
    """
    detectors = sorted(zenith)
    vector = _nan_mean(np.stack([view_vector(zenith[d], azimuth[d]) for d in detectors]))
    return np.stack([fill_gaps(component, what=f"{what} grid") for component in vector])


def combine_detectors(zenith: dict[int, np.ndarray], azimuth: dict[int, np.ndarray], what: str = "the view"):
    """One view zenith and azimuth grid per band from its per-detector grids.

    The detectors are combined on the view vector (:func:`combined_view_vector`): where two
    detectors see the same node (the overlap of adjacent detectors) the result is the direction of
    their mean vector, not the mean of their zeniths and of their azimuths apart (ill-defined near
    the nadir line, where the azimuths of a near-vertical view differ widely); each detector's NaN
    gaps are thereby filled from the others. Remaining gaps are filled by :func:`fill_gaps`.

    Returns
    -------
    zenith, azimuth : numpy.ndarray
        Gap-free grids [deg], azimuth in [0, 360) (0 where the vector is 0).
    """
    return view_angles(combined_view_vector(zenith, azimuth, what))


def _node_array(tile: TileAngles, values: np.ndarray, name: str) -> xr.DataArray:
    """The node grid (y, x), or (component, y, x) for a view vector, with its coords, CRS and transform."""
    rows, cols = values.shape[-2:]
    x = (tile.node_transform @ (np.arange(cols) + 0.5, np.full(cols, 0.5)))[0]
    y = (tile.node_transform @ (np.full(rows, 0.5), np.arange(rows) + 0.5))[1]
    dims = ("component", "y", "x")[3 - values.ndim:]
    array = xr.DataArray(values, dims=dims, coords={"y": y, "x": x}, name=name)
    return array.rio.write_crs(tile.crs).rio.write_transform(tile.node_transform)


def read_sentinel2_angles(path: str | Path, like: xr.DataArray | None = None, *,
                          band: str | None = None, resolution: int = 10,
                          view_azimuth: str = "to_sensor", chunks=None) -> xr.Dataset:
    """Sun and view angles of a Sentinel-2 granule on an image grid, lazily.

    Parameters
    ----------
    path : str or Path
        The granule's ``MTD_TL.xml``.
    like : xarray.DataArray, optional
        The image (any georeferenced (y, x) grid: a band opened with rioxarray, a subset, another
        CRS). Default: the full tile at ``resolution`` as given by the metadata.
    band : str, optional
        Band whose view grids to use ("B01" ... "B12", "B8A"). Default: all bands, their view
        vectors averaged (the view angles of the bands differ by up to about 0.5 deg, the band
        focal-plane offsets).
    resolution : {10, 20, 60}
        Pixel size [m] of the default grid (ignored when ``like`` is given).
    view_azimuth : {"to_sensor", "from_sensor"}
        What the metadata's viewing azimuth holds; Sentinel-2: "to_sensor" (see module notes).
    chunks :
        Output chunks; default ``like``'s, else 2048.

    Returns
    -------
    xarray.Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] on (y, x), dask-backed, with CRS and transform.

    Notes
    -----
    ``vza`` and ``vaa`` are the zenith and azimuth of the ground-projected view vector
    (tan θv sin φv, tan θv cos φv) interpolated component by component (module notes), not the
    node zeniths and azimuths interpolated apart, which err near the nadir line (module notes).
    """
    tile = parse_mtd_tl(path)
    if view_azimuth not in ("to_sensor", "from_sensor"):
        raise SensorInputError(f"view_azimuth must be 'to_sensor' or 'from_sensor', got {view_azimuth!r}")
    if band is None:
        bands = sorted(tile.view_zenith, key=BAND_NAMES.index)
    elif band in tile.view_zenith:
        bands = [band]
    else:
        raise SensorInputError(
            f"{tile.path}: no viewing angle grids for band {band!r}; it has {sorted(tile.view_zenith)}"
        )
    vector = np.mean([combined_view_vector(tile.view_zenith[b], tile.view_azimuth[b], f"{tile.path}: the {b} view")
                      for b in bands], axis=0)
    if view_azimuth == "from_sensor":
        vector = -vector  # the azimuth turned by 180 deg
    if like is None:
        if resolution not in tile.sizes or resolution not in tile.geopositions:
            raise SensorInputError(
                f"{tile.path}: no image size/geoposition for resolution {resolution} m; "
                f"it has {sorted(tile.sizes)}"
            )
        like = grid_template(tile.geopositions[resolution], tile.sizes[resolution], tile.crs,
                             chunks=chunks or 2048)
    grids: dict[str, tuple[np.ndarray, Kind, str]] = {
        "sza": (fill_gaps(tile.sun_zenith, what=f"{tile.path}: the sun zenith grid"), False, "solar zenith angle"),
        "saa": (fill_gaps(tile.sun_azimuth, angle=True, what=f"{tile.path}: the sun azimuth grid"), True,
                "solar azimuth angle (pixel to sun, clockwise from north)"),
        "vza": (vector, "view_zenith", "view zenith angle"),
        "vaa": (vector, "view_azimuth", "view azimuth angle (pixel to sensor, clockwise from north)"),
    }
    variables = {
        key: to_grid(_node_array(tile, values, key), like, angle=angle, chunks=chunks, name=key,
                     source=f"{tile.path}: the {key} angle grid",
                     attrs={"units": "degree", "long_name": long_name})
        for key, (values, angle, long_name) in grids.items()
    }
    return xr.Dataset(variables, attrs={
        "source": str(tile.path), "source_kind": "sentinel2",
        "view_bands": ",".join(bands), "sensing_time": str(tile.sensing_time),
        "view_azimuth_stored": view_azimuth,
    })
