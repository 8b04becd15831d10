"""The sections of a chain config that say what a run writes and how it runs: ``outputs:`` and
``engine:``.

:class:`OutputsConfig` names the output directory, the file-name patterns and the raster format;
:class:`EngineConfig` the scheduler and its workers. Pydantic models, validated as part of
:class:`brdfcorr.chain.config.ChainConfig`; import them from :mod:`brdfcorr.chain.config`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from brdfcorr._validation import Integer, StrictModel, short_repr
from brdfcorr.chain.patterns import check_pattern
from brdfcorr.defaults import chunk_size_problem, default_threads
from brdfcorr.errors import InputError
from brdfcorr.io.paths import check_format

__all__ = ["OutputsConfig", "EngineConfig"]


class OutputsConfig(StrictModel):
    """Where and how results are written.

    Attributes
    ----------
    directory : str
        Output directory (created).
    naming, qa_naming, uncertainty_naming, quicklook_naming, strata_naming : str
        Patterns with ``{scene}``, ``{stem}``, ``{parent}`` for the corrected raster, the QA GeoTIFF,
        the uncertainty GeoTIFF, the quicklook PNG and the NDVI strata class map of ``steps.strata``
        (GeoTIFF). ``naming``'s extension must fit ``format``
        (:func:`brdfcorr.io.writer.check_format`); its default is ``{scene}_brdf.tif`` for GTiff and
        ``{scene}_brdf.img`` for ENVI.
    uncertainty : bool
        Also write the per-pixel 1-sigma of the corrected reflectance [1]
        (:func:`brdfcorr.correction.uncertainty.correction_uncertainty`, ``docs/uncertainty.md``): from the
        ``fit:`` covariance of each class's table entry, NaN for classes without one.
    format : {"GTiff", "ENVI"}
        Raster format of the corrected images (the QA and uncertainty rasters are GeoTIFFs). ENVI: a
        data file, its ``.hdr`` header (wavelengths, map info) and ``.aux.xml`` (tags);
        uncompressed, no ``cog``.
    interleave : {"bsq", "bil"}, optional
        Interleave of ENVI outputs: band sequential (default) or band interleaved by line; only with
        ``format: ENVI``.
    compress : {"deflate", "lzw", "zstd", "none"}
    cog : bool
        Write Cloud-Optimized GeoTIFFs.
    existing : {"error", "skip", "overwrite"}
        A scene whose outputs all exist: fail it, skip it (resume), or redo it.
    report : str
        Run report (JSON) file name in the output directory.
    """

    directory: str = Field(min_length=1)
    naming: str = "{scene}_brdf.tif"
    qa_naming: str = "{scene}_qa.tif"
    uncertainty_naming: str = "{scene}_uncertainty.tif"
    quicklook_naming: str = "{scene}_quicklook.png"
    strata_naming: str = "{scene}_strata.tif"
    uncertainty: bool = False
    format: Literal["GTiff", "ENVI"] = "GTiff"
    interleave: Literal["bsq", "bil"] | None = None
    compress: Literal["deflate", "lzw", "zstd", "none"] = "deflate"
    cog: bool = False
    existing: Literal["error", "skip", "overwrite"] = "skip"
    report: str = "run_report.json"

    @field_validator("naming", "qa_naming", "uncertainty_naming", "quicklook_naming", "strata_naming")
    @classmethod
    def _names(cls, value: str) -> str:
        check_pattern(value, ("parent", "stem", "scene"))
        if "/" in value or "\\" in value:
            raise ValueError(f"{short_repr(value)} must be a file name (no directory part)")
        if "{" not in value:
            raise ValueError(f"{short_repr(value)} must contain {{scene}}, {{stem}} or {{parent}}: "
                             "scenes need distinct names")
        return value

    @model_validator(mode="before")
    @classmethod
    def _envi_naming(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and data.get("format") == "ENVI" and "naming" not in data:
            data = {**data, "naming": "{scene}_brdf.img"}
        return data

    @model_validator(mode="after")
    def _format(self) -> OutputsConfig:
        for key, name, driver in (("naming", self.naming, self.format), ("qa_naming", self.qa_naming, "GTiff"),
                                  ("uncertainty_naming", self.uncertainty_naming, "GTiff"),
                                  ("strata_naming", self.strata_naming, "GTiff")):
            try:
                check_format(name, driver, f"outputs.{key}")
            except InputError as error:
                raise ValueError(str(error)) from None
        if self.format == "ENVI" and self.cog:
            raise ValueError("cog applies to GeoTIFF outputs, not format ENVI")
        if self.interleave is not None and self.format != "ENVI":
            raise ValueError(f"interleave applies to format ENVI, not {self.format!r}")
        return self


class EngineConfig(StrictModel):
    """How the work is executed.

    Attributes
    ----------
    scheduler : {"threads", "processes", "synchronous", "distributed"}
        ``threads``: scenes one after another, each scene's chunks on ``workers`` threads.
        ``processes``: ``workers`` scenes at a time in separate processes, and the fit step's
        classes (a goniometer fit's ``auto`` candidates) as many at a time
        (:mod:`brdfcorr.tasks.pool`).
        ``synchronous``: everything in the calling thread (debugging).
        ``distributed``: every scene spread chunk by chunk over all workers of a
        ``dask.distributed`` cluster at ``address`` (or of a local cluster of ``workers``
        processes when no address is given), ``workers`` scenes in flight at once.
    workers : int
        Threads (``threads``), processes (``processes``, local ``distributed``); with
        ``distributed`` also the number of scenes in flight at once. Default: the cores; with
        ``threads`` left out, the threads of ``brdfcorr correct`` (one per 4 cores,
        :func:`brdfcorr.defaults.default_threads`).
    threads_per_worker : int
        Threads for the chunks of a scene inside a process, and of each worker process of a local
        ``distributed`` cluster.
    chunk : int, optional
        Spatial chunk and output tile size [pixels], a multiple of 16 from 16 to 8192. Default: the rule of
        ``brdfcorr correct`` for each image (:func:`brdfcorr.io.rasters.auto_chunk`: 512, smaller
        for many bands, so that a chunk of all bands stays near 16 MB and a spectrum is read from
        one small tile).
    address : str, optional
        Scheduler address of a running cluster (``tcp://host:8786``); only with ``distributed``.

    Notes
    -----
    On one machine ``threads`` is usually fastest (GDAL, numpy and the model kernels release the
    GIL, and GDAL compresses the output tiles on all cores; measured: 6 scenes of 400 x 581 x 6
    on 2 cores, threads 3.6 s, processes 8.4 s, local distributed 8.7 s, mostly worker
    start-up). ``processes`` pays off for long batches of scenes, ``distributed`` for several
    machines (docs/scaling.md).
    """

    scheduler: Literal["threads", "processes", "synchronous", "distributed"] = "threads"
    workers: Integer = Field(default_factory=lambda: max(1, os.cpu_count() or 1), ge=1)
    threads_per_worker: Integer = Field(1, ge=1)
    chunk: Integer | None = None
    address: str | None = None

    @field_validator("chunk")
    @classmethod
    def _tile(cls, value: int | None) -> int | None:
        problem = None if value is None else chunk_size_problem(value)
        if problem:  # the rule of --chunk (brdfcorr.defaults.CHUNK_RANGE)
            raise ValueError(f"chunk {value} {problem}")
        return value

    @property
    def local_threads(self) -> int:
        """Threads of a scene's chunks computed in this process: ``workers`` where given with a local
        scheduler (``threads``, ``synchronous``), else the thread count of ``brdfcorr correct``
        (one per 4 cores, :func:`brdfcorr.defaults.default_threads`), not all cores."""
        given = self.scheduler in ("threads", "synchronous") and "workers" in self.model_fields_set
        return self.workers if given else default_threads()

    @model_validator(mode="after")
    def _address(self) -> EngineConfig:
        if self.address is not None and self.scheduler != "distributed":
            raise ValueError(f"address is only used with scheduler 'distributed', not {self.scheduler!r}")
        # A dask scheduler address: PROTOCOL://HOST:PORT (a typo would otherwise wait for a timeout).
        if self.address is not None and not re.fullmatch(r"(tcp|tls|ucx|ws|wss|inproc)://[^\s/]+\S*", self.address):
            raise ValueError(f"address {short_repr(self.address)} is not a dask scheduler address like "
                             "'tcp://host:8786'")
        return self
