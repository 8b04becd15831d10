"""One correction of one image file, described once: :class:`CorrectionRequest`.

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

from brdfcorr.defaults import DEFAULT_LIMITS, chunk_size_problem
from brdfcorr.errors import InputError
from brdfcorr.io.scene import SceneSources
from brdfcorr.params import ParameterTable, ReferenceGeometry

if TYPE_CHECKING:
    import distributed

    from brdfcorr.tasks.correct import Terrain

__all__ = ["CorrectionRequest", "OutputFiles", "Engine", "SceneSources"]

PathLike = str | os.PathLike


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
        (:func:`brdfcorr.chain.plan.scene_fingerprint`), written in the tags ``brdf_fingerprint``
        (its SHA-256) and ``brdf_fingerprint_content``: a resumed chain redoes a stale output.
    """

    corrected: PathLike
    qa: PathLike | None = None
    uncertainty: PathLike | None = None
    format: Literal["GTiff", "ENVI"] = "GTiff"
    interleave: Literal["bsq", "bil"] = "bsq"
    data_type: Literal["float", "input"] = "float"
    compress: str = "deflate"
    cog: bool = False
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
        dask scheduler of the computations and its number of workers (as for :func:`dask.compute`);
        a ``distributed.Client`` spreads the scene's chunks over the cluster's workers.
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
    limits: tuple[float, float] | None = DEFAULT_LIMITS
    extrapolate: bool = False
    unknown: Literal["keep", "nan"] = "keep"
    flip_view_azimuth: bool = False
    terrain: Terrain | None = None
    align_classes: bool = False
    class_lookup: Mapping[int, int] | None = None
    engine: Engine = Engine()
    table_source: str | None = None
    reads: Mapping[str, PathLike | None] | Sequence = ()
    factor_at: Literal["pixels", "nodes"] = "pixels"

    @property
    def inputs(self) -> list:
        """Every file read, by role: never overwritten (:func:`brdfcorr.io.paths.check_outputs`)."""
        inputs: list = [*self.scene.inputs,
                        ("parameter table", None if isinstance(self.table, ParameterTable) else self.table)]
        inputs += list(self.reads.items()) if isinstance(self.reads, Mapping) else list(self.reads)
        return inputs + (self.terrain.inputs if self.terrain is not None else [])
