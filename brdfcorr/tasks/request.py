"""One correction of one image file, described once: :class:`CorrectionRequest` (with its
:class:`OutputFiles`, :class:`Engine` and :class:`Terrain`).

The CLI (``brdfcorr correct``) and chains (the correct step) build a request from their options and
hand it to :func:`brdfcorr.tasks.correct.correct_files`; from Python::

    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, OutputFiles

    correct_files(CorrectionRequest(
        SceneSources("image.tif", "classes.tif", "angles.tif"), "params.yaml",
        OutputFiles("corrected.tif", qa="qa.tif"), reference={"sza": "mean", "vza": 0}))
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import rasterio
import xarray as xr

from brdfcorr.correction.terrain import (
    SlopeAspect,
    check_dem_slope,
    check_slope_aspect,
    slope_aspect,
    slope_aspect_layers,
)
from brdfcorr.correction.topographic import topographic_correction
from brdfcorr.defaults import chunk_size_problem, frame_conflict
from brdfcorr.errors import InputError
from brdfcorr.io.angles import RELATIVE_ONLY
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.opening import open_layer, reading
from brdfcorr.io.paths import PathLike
from brdfcorr.io.scene import SceneData, SceneSources
from brdfcorr.params import ParameterTable, ReferenceGeometry
from brdfcorr.tasks.options import CORRECT, BrdfFrame, FactorAt, Topographic, Unknown

if TYPE_CHECKING:
    import distributed

__all__ = ["CorrectionRequest", "OutputFiles", "Engine", "SceneSources", "Terrain"]


@dataclass(frozen=True)
class OutputFiles:
    """What a correction writes, and how.

    Attributes
    ----------
    corrected : path-like
        The corrected image (``format``).
    qa, uncertainty : path-like, optional
        The QA flags (uint8 GeoTIFF) and the per-pixel 1-sigma of the corrected reflectance (a
        GeoTIFF like the output, :func:`brdfcorr.correction.uncertainty.correction_uncertainty`; NaN for
        classes whose table entry has no ``fit:`` covariance), written in the same pass.
    format : {"GTiff", "ENVI"}, default "GTiff"
        Format of ``corrected``; its extension must fit (:func:`brdfcorr.io.writer.check_format`).
        ENVI: uncompressed, a header ``.hdr`` beside it, the tags in ``.aux.xml``.
    interleave : {"bsq", "bil"}, default "bsq"
        Interleave of an ENVI output.
    data_type : {"float", "input"}, default "float"
        ``"float"``: reflectance factors as float32 (float64 for a float64 input). ``"input"``: an
        integer input's own type, scale, offset and nodata
        (:func:`brdfcorr.io.writer.encode_integers`); values that do not fit are nodata and flagged. A
        64-bit integer input is refused (an :class:`~brdfcorr.errors.InputError`): its nodata would not
        read back.
    compress : str, default "deflate"
        GDAL compression of GeoTIFF outputs.
    cog : bool, default False
        Write Cloud-Optimized GeoTIFFs.
    overwrite : bool, default True
        Replace existing outputs; with False an existing output is an :class:`~brdfcorr.errors.OutputError`
        (the CLI's default). An input is never overwritten.
    fingerprint : str, optional
        Canonical JSON of everything the output depends on
        (:func:`brdfcorr.chain.resume.scene_fingerprint`), written in the tags ``brdf_fingerprint``
        (its SHA-256) and ``brdf_fingerprint_content``: a resumed chain redoes a stale output.
    """

    corrected: PathLike
    qa: PathLike | None = None
    uncertainty: PathLike | None = None
    format: Literal["GTiff", "ENVI"] = CORRECT.default("output_format")
    interleave: Literal["bsq", "bil"] = CORRECT.default("interleave")
    data_type: Literal["float", "input"] = CORRECT.default("output_type")
    compress: str = CORRECT.default("compress")
    cog: bool = CORRECT.default("cog")
    overwrite: bool = True
    fingerprint: str | None = None


@dataclass(frozen=True)
class Engine:
    """How the correction is computed.

    Attributes
    ----------
    chunks : int, optional
        Spatial chunk and tile size [pixels], a multiple of 16 from 16 to 8192 (else an
        :class:`~brdfcorr.errors.InputError`); by default :func:`brdfcorr.io.rasters.auto_chunk`.
    scheduler, num_workers : optional
        dask scheduler of the computations and its number of workers (as for :func:`dask.compute`):
        ``"threads"`` (dask's default) or ``"synchronous"`` on this machine, or a
        ``distributed.Client`` (or ``"distributed"``, dask's current client), which spreads the
        scene's chunks over the cluster's workers (a ``distributed.LocalCluster`` over this
        machine's processes). Dask's process pool (``"processes"``) is refused
        (:class:`~brdfcorr.errors.InputError`): the outputs are written through open GDAL handles
        and thread locks, which cannot be sent to another process.
    callbacks : sequence
        Dask callbacks active while computing (a progress bar).
    """

    chunks: int | None = None
    scheduler: str | distributed.Client | None = None
    num_workers: int | None = None
    callbacks: Sequence = ()

    def __post_init__(self):
        problem = None if self.chunks is None else chunk_size_problem(self.chunks)
        if problem:  # the rule of --chunk and engine.chunk, before anything is read
            raise InputError(f"chunk size {self.chunks} {problem}")
        import concurrent.futures

        import dask

        # The scheduler given, else dask's own setting (dask.config.set, DASK_SCHEDULER) that a pass would use.
        scheduler = self.scheduler if self.scheduler is not None else dask.config.get("scheduler", None)
        if scheduler in ("processes", "multiprocessing") or isinstance(
                scheduler, concurrent.futures.ProcessPoolExecutor) or \
                getattr(scheduler, "__module__", None) == "dask.multiprocessing":  # its ``get``
            raise InputError(f"scheduler {getattr(scheduler, '__name__', scheduler)!r}: dask's process "
                             "pool cannot take the writers' open GDAL handles and thread locks to its processes; "
                             "use 'threads' or 'synchronous', or a dask.distributed Client (a LocalCluster for "
                             "processes on this machine)")


@dataclass(frozen=True)
class Terrain:
    """Tilted surfaces in a correction (``docs/terrain.md``): where slope and aspect come from and
    what is done with them.

    Attributes
    ----------
    slope_aspect : path-like, optional
        A 2-band raster of slope and aspect [deg] on the image grid (band descriptions naming
        ``slope`` and ``aspect`` decide which is which, else that order), or an ENVI ``obs_ort``
        file (its bands "Slope" and "Aspect", :func:`brdfcorr.io.sensors.envi.read_envi_obs_terrain`).
        Their values are checked in one pass (:func:`brdfcorr.correction.terrain.check_slope_aspect`):
        radians, or no slope in [0, 90] deg at all, are an :class:`~brdfcorr.errors.InputError`.
    dem : path-like, optional
        Or a DEM/DSM [m] on the image grid in a projected CRS: slope and aspect by Horn's
        differences (:func:`brdfcorr.correction.terrain.slope_aspect`), the pixel size converted
        from the CRS's linear unit to metres (EPSG:2263, US survey feet). A DEM that gives no
        pixel a slope (nodata only: every 3x3 neighbourhood holds nodata) is an
        :class:`~brdfcorr.errors.InputError` (:func:`brdfcorr.correction.terrain.check_dem_slope`).
        Give one of the two.
    topographic : {"cosine", "c", "scs", "scs+c", "none"}, default "cosine"
        Illumination correction before the BRDF step (:func:`brdfcorr.correction.topographic.topographic_correction`;
        C fitted per class and band from the image for ``"c"`` and ``"scs+c"``).
    brdf_frame : {"surface", "horizontal"}, default "surface"
        Evaluate the BRDF in each surface's own frame (the observed geometry rotated by slope and
        aspect; the reference stays horizontal) or in the horizontal frame. ``"surface"`` takes
        the illumination's cos i into account itself only with ``"cosine"`` (or ``"none"``) before
        it; the empirical C of ``"c"``/``"scs+c"`` absorbs part of the BRDF's slope dependence, so
        those go with ``"horizontal"`` (combining them corrects the illumination twice, 15 % off
        between the sides of a synthetic hill in ``tests/correction/test_terrain.py``).
    """

    slope_aspect: str | os.PathLike | None = None
    dem: str | os.PathLike | None = None
    topographic: Topographic = CORRECT.default("topographic")
    brdf_frame: BrdfFrame = CORRECT.default("brdf_frame")

    def __post_init__(self):
        if (self.slope_aspect is None) == (self.dem is None):
            raise InputError("terrain: give slope and aspect (a 2-band raster or an obs file) or a DEM, one of them")
        conflict = frame_conflict(self.topographic, self.brdf_frame)
        if conflict:
            raise InputError(f"terrain: {conflict}")

    @property
    def inputs(self) -> list[tuple[str, object]]:
        return [("slope/aspect raster", self.slope_aspect), ("DEM", self.dem)]

    def open(self, like: xr.DataArray, chunks: int, compute: Mapping | None = None) -> SlopeAspect:
        """Slope and aspect [deg] (y, x) on ``like``'s grid, lazily; layers read from a file are
        checked in one pass (:func:`brdfcorr.correction.terrain.check_slope_aspect`: degrees, and
        the file read to its end), those of a DEM too (:func:`~brdfcorr.correction.terrain.check_dem_slope`:
        a slope somewhere), with the dask settings ``compute`` (``scheduler``, ``num_workers``)."""
        if self.dem is not None:
            dem = open_layer(self.dem, "DEM", chunks)
            if dem.shape[0] != 1:
                raise InputError(f"DEM file {self.dem} has {dem.shape[0]} bands; it needs 1")
            try:
                surface = slope_aspect(dem[0])
            except InputError as error:  # "DEM: no CRS ...": name the file
                raise InputError(f"DEM file {self.dem}: {str(error).removeprefix('DEM: ')}") from None
            check_same_grid({"image": like, f"DEM {self.dem}": surface.slope})
            with reading(f"DEM file {self.dem}"):
                check_dem_slope(surface, f"DEM file {self.dem}", **(compute or {}))
        else:
            if _is_envi(self.slope_aspect):
                from brdfcorr.io.sensors.envi import read_envi_obs_terrain  # sensors import this module's layer

                layers = read_envi_obs_terrain(self.slope_aspect, like=like)
                surface, source = SlopeAspect(layers["slope"], layers["aspect"]), f"obs file {self.slope_aspect}"
            else:
                surface = slope_aspect_layers(open_layer(self.slope_aspect, "slope/aspect", chunks))
                source = f"slope/aspect file {self.slope_aspect}"
            check_same_grid({"image": like, "slope": surface.slope, "aspect": surface.aspect})
            with reading(source):
                check_slope_aspect(surface, source, **(compute or {}))
        return surface

    def apply(self, scene: SceneData, chunks: int, limits, compute: Mapping | None = None):
        """The reflectance after the topographic step, the slope and aspect layers for
        :func:`brdfcorr.normalize` (none in the horizontal frame) and the topographic result."""
        if scene.angles["saa"].attrs.get(RELATIVE_ONLY):
            raise InputError("terrain: a tilted surface needs the sun's and the sensor's azimuths; the angle "
                             "source gives only their relative azimuth (raa)")
        slope, aspect = self.open(scene.reflectance, chunks, compute)
        reflectance, topographic = scene.reflectance, None
        if self.topographic != "none":
            topographic = topographic_correction(
                reflectance, {**scene.angles, "slope": slope, "aspect": aspect}, method=self.topographic,
                classes=scene.classes, limits=limits,
            )
            reflectance = topographic.reflectance
        surface = {"slope": slope, "aspect": aspect} if self.brdf_frame == "surface" else {}
        return reflectance, surface, topographic


def _is_envi(path) -> bool:
    try:
        with rasterio.open(path) as dataset:
            return dataset.driver == "ENVI"
    except rasterio.errors.RasterioIOError:
        return False  # the reader names the file


@dataclass(frozen=True)
class CorrectionRequest:
    """One correction of one image file: its inputs, the table, the reference, the outputs.

    Attributes
    ----------
    scene : SceneSources
        The image, class map and angle source.
    table : ParameterTable or path-like
        The parameter table (a path is loaded with :meth:`ParameterTable.load`).
    outputs : OutputFiles
        What is written.
    reference : ReferenceGeometry or mapping, optional
        The reference geometry (:func:`brdfcorr.correction.resolve_reference`: the table's, with
        these keys over it); a ``"mean"`` sun zenith becomes the scene mean.
    limits, extrapolate, unknown, flip_view_azimuth :
        As for :func:`brdfcorr.normalize`.
    terrain : Terrain, optional
        Tilted surfaces: slope and aspect, the topographic step and the BRDF's frame.
    align_classes : bool, default False
        Accept a class map on another grid or CRS: resample it onto the image grid by nearest
        neighbour. Off by default: a class map on another grid is an error.
    class_lookup : mapping of int to int, optional
        Remap the class map's codes to table ids (codes not in it: no class).
    engine : Engine
        Chunks, scheduler, progress.
    table_source : str, optional
        Where an in-memory ``table`` came from, for the provenance tag.
    reads : mapping of name to path, or sequence of paths
        Further files the caller read (a class lookup table): never overwritten either.
    factor_at : {"pixels", "nodes"}, default "pixels"
        Where the correction factor is evaluated: at every pixel, from the angles interpolated to
        it, or at the nodes of the sensor's coarse angle grid and interpolated bilinearly to the
        pixels (sen2nbar's method, :mod:`brdfcorr.correction.nodes`: faster; one class, no class
        map, terrain or uncertainty layer).
    """

    scene: SceneSources
    table: ParameterTable | PathLike
    outputs: OutputFiles
    reference: ReferenceGeometry | Mapping | None = None
    limits: tuple[float, float] | None = CORRECT.default("limits")
    extrapolate: bool = CORRECT.default("extrapolate")
    unknown: Unknown = CORRECT.default("unknown")
    flip_view_azimuth: bool = CORRECT.default("flip_view_azimuth")
    terrain: Terrain | None = None
    align_classes: bool = False
    class_lookup: Mapping[int, int] | None = None
    engine: Engine = Engine()
    table_source: str | None = None
    reads: Mapping[str, PathLike | None] | Sequence = ()
    factor_at: FactorAt = CORRECT.default("factor_at")

    @property
    def inputs(self) -> list:
        """Every file read, by role: never overwritten (:func:`brdfcorr.io.paths.check_outputs`)."""
        inputs: list = [*self.scene.inputs,
                        ("parameter table", None if isinstance(self.table, ParameterTable) else self.table)]
        inputs += list(self.reads.items()) if isinstance(self.reads, Mapping) else list(self.reads)
        return inputs + (self.terrain.inputs if self.terrain is not None else [])
