"""Chain configs: a whole processing run (inputs, parameters, steps, outputs, engine) as YAML.

A chain config makes a run repeatable and reviewable. It is validated with pydantic v2 models
(``extra="forbid"``: a misspelt key is an error, not ignored); errors name the key path and, for
enumerations and unknown keys, the allowed values::

    chain.yaml: engine.scheduler: 'thread' is not allowed; allowed: 'threads', 'processes', ...
    chain.yaml: outputs.compres: unknown key; allowed keys: directory, naming, ...

Relative paths and patterns in a config are relative to the directory of the config file. Per-scene
sources (angles, class map) and outputs are *name patterns* (:mod:`brdfcorr.workflow.patterns`).
A commented example of every key is in ``configs/`` (``configs/demo.yaml`` is the chain
``brdfcorr demo`` runs).

Example
-------
>>> config = ChainConfig.from_dict({
...     "inputs": {"images": ["scenes/*_image.tif"], "scene_regex": "(?P<scene>.+)_image",
...                "angles": {"kind": "geotiff", "path": "{dir}/{scene}_angles.tif"},
...                "classes": "{dir}/{scene}_classes.tif"},
...     "parameters": {"materials": {1: "roof_tile"}},
...     "outputs": {"directory": "out"},
... })
>>> config.engine.scheduler, config.outputs.naming
('threads', '{scene}_brdf.tif')
"""

from __future__ import annotations

import copy
import os
import re
from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from brdfcorr._validation import Integer, Number, describe_errors, short_repr
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import ConfigError, InputError, UnknownNameError
from brdfcorr.io.files import parse_yaml, read_document
from brdfcorr.io.sensors import ANGLE_KINDS
from brdfcorr.io.writer import check_format
from brdfcorr.models import SURFACE_MODELS
from brdfcorr.models.materials import load_material, material_names
from brdfcorr.params import ClassEntry, ReferenceGeometry
from brdfcorr.topographic import frame_conflict
from brdfcorr.workflow.patterns import PATTERN_FIELDS, check_pattern, format_pattern

__all__ = [
    "ChainConfig",
    "ConfigError",
    "InputsConfig",
    "AngleSource",
    "ParametersConfig",
    "ImageryFit",
    "GoniometerFit",
    "MeasurementSet",
    "CorrectStep",
    "TerrainStep",
    "QuicklookStep",
    "AssessStep",
    "StepsConfig",
    "OutputsConfig",
    "EngineConfig",
    "load_config",
    "apply_overrides",
    "format_pattern",
    "PATTERN_FIELDS",
]

#: A surface model of the registry (its names are the allowed values).
SurfaceModel = Literal[SURFACE_MODELS]  # type: ignore[valid-type]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


#: ``geotiff`` or a sensor product kind of :data:`brdfcorr.io.sensors.ANGLE_KINDS`.
AngleKind = Literal[("geotiff", *ANGLE_KINDS)]  # type: ignore[valid-type]


class AngleSource(_Strict):
    """Where a scene's sun/view angles come from.

    Attributes
    ----------
    kind : {"geotiff", "envi_obs", "sentinel2", "landsat", "solar"}
        ``geotiff``: a 4-band raster sza, saa, vza, vaa [deg] on the image grid; the others are
        sensor products read by :func:`brdfcorr.io.sensors.read_angles`.
    path : str
        Name pattern of the source: the angle raster, the obs file, the ``MTD_TL.xml``, the Landsat
        product; for ``solar`` the acquisition time (ISO 8601 with time zone).
    options : dict
        Keyword options of the kind's reader (e.g. ``{view_azimuth: from_sensor}``,
        ``{view_zenith: 0, view_azimuth: 0}`` for ``solar``).
    """

    kind: AngleKind = "geotiff"
    path: str = Field(min_length=1)
    options: dict[str, Any] = Field(default_factory=dict)

    @field_validator("path")
    @classmethod
    def _pattern(cls, value: str) -> str:
        return check_pattern(value)

    @model_validator(mode="after")
    def _options_for_kind(self) -> AngleSource:
        if self.kind == "geotiff" and self.options:
            raise ValueError(f"kind 'geotiff' takes no options, got {', '.join(self.options)}")
        return self


class InputsConfig(_Strict):
    """The scenes of a run.

    Attributes
    ----------
    images : list of str
        Image paths or globs (``scenes/*_image.tif``); every match is one scene, sorted by path.
    scene_regex : str, optional
        Regular expression with a named group ``scene``, matched on the image file name, giving the
        scene name used in patterns (default: the file stem).
    angles : AngleSource
        Per-scene angle source.
    classes : str
        Name pattern of the per-scene class map raster.
    align_classes : bool
        The class maps may lie on another grid or CRS (a land-cover product): resample them onto
        each image's grid by nearest neighbour (recorded in the outputs' tags). Default False: a
        class map on another grid is an error.
    class_lookup : dict of int to int
        Class-map code -> table class id (e.g. ESA WorldCover 10 -> 3); codes not listed: no class.
    slope_aspect, dem : str, optional
        Name patterns of the per-scene terrain source of ``steps.correct.terrain``
        (:class:`brdfcorr.workflow.correction.Terrain`): a 2-band slope/aspect raster [deg] (or an ENVI
        ``obs_ort`` file), or a DEM [m] in a projected CRS, on the image grid; give one of them.
    wavelengths : list of float, optional
        Band centres [nm] for every image, overriding what the files say.
    scale, offset : float, optional
        Reflectance factor per stored unit (> 0) and of a stored 0, for every image, for products
        that do not tag them (e.g. 0.0001 for 0-10000; Landsat C2 L2 2.75e-5 and -0.2); a given
        value replaces the files' GDAL scale/offset (default: the files', else 1 and 0). Applied on
        read by the fit and correct steps and recorded in the outputs' tags.
    """

    images: list[str] = Field(min_length=1)
    scene_regex: str | None = None
    angles: AngleSource
    classes: str = Field(min_length=1)
    align_classes: bool = False
    class_lookup: dict[Integer, Annotated[Integer, Field(ge=0, le=65535)]] = Field(default_factory=dict)
    slope_aspect: str | None = Field(None, min_length=1)
    dem: str | None = Field(None, min_length=1)
    wavelengths: list[Annotated[Number, Field(gt=0)]] | None = None
    scale: Number | None = Field(None, gt=0, allow_inf_nan=False)
    offset: Number | None = Field(None, allow_inf_nan=False)

    @field_validator("images")
    @classmethod
    def _no_empty(cls, value: list[str]) -> list[str]:
        if any(not item.strip() for item in value):
            raise ValueError("image paths must not be empty")
        return value

    @field_validator("scene_regex")
    @classmethod
    def _regex(cls, value: str | None) -> str | None:
        if value is None:
            return value
        try:
            compiled = re.compile(value)
        except re.error as error:
            raise ValueError(f"not a regular expression: {error}") from None
        if "scene" not in compiled.groupindex:
            raise ValueError(f"{short_repr(value)} has no named group (?P<scene>...)")
        return value

    @field_validator("classes")
    @classmethod
    def _pattern(cls, value: str) -> str:
        return check_pattern(value)

    @field_validator("slope_aspect", "dem")
    @classmethod
    def _terrain_pattern(cls, value: str | None) -> str | None:
        return value if value is None else check_pattern(value)

    @model_validator(mode="after")
    def _one_terrain_source(self) -> InputsConfig:
        if self.slope_aspect is not None and self.dem is not None:
            raise ValueError("give slope_aspect or dem, not both: slope and aspect come from one of them")
        return self


class MeasurementSet(_Strict):
    """One goniometer measurement table fitted as one class (``brdfcorr fit`` in a chain).

    Attributes
    ----------
    file : str
        Measurements CSV (``theta_i, theta_r, phi, brdf[, sigma, wavelength]``).
    class_id : int
        Class id in the parameter table (>= 1).
    name : str
        Class name.
    model : str
        Registered surface model (``brdfcorr models``).
    fixed, initial : dict of str to float
        Parameters held fixed / starting values (paper 003 fixes k = 0.25).
    min_phi, max_phi, max_zenith : float, optional
        Measurement selection [deg] (paper 003 fits phi >= 90).
    """

    file: str = Field(min_length=1)
    class_id: Integer = Field(ge=1)
    name: str = Field(min_length=1)
    model: SurfaceModel = "torrance_sparrow"
    fixed: dict[str, Number] = Field(default_factory=dict)
    initial: dict[str, Number] = Field(default_factory=dict)
    min_phi: Number | None = Field(None, ge=0, le=180)
    max_phi: Number | None = Field(None, ge=0, le=180)
    max_zenith: Number | None = Field(None, gt=0, lt=90)



class GoniometerFit(_Strict):
    """Fit step from goniometer measurements: one class per measurement table."""

    source: Literal["goniometer"]
    measurements: list[MeasurementSet] = Field(min_length=1)
    output: str = "fitted_params.yaml"

    @model_validator(mode="after")
    def _unique(self) -> GoniometerFit:
        ids = [m.class_id for m in self.measurements]
        if len(set(ids)) != len(ids):
            raise ValueError(f"class ids {ids} of measurements must be distinct")
        return self


class ImageryFit(_Strict):
    """Fit step from the imagery itself: per-class fits pooled over the run's scenes
    (:func:`brdfcorr.fit.classes.fit_classes`)."""

    source: Literal["imagery"]
    model: SurfaceModel = "torrance_sparrow"
    class_models: dict[Annotated[Integer, Field(ge=1)], SurfaceModel] = Field(default_factory=dict)
    names: dict[Annotated[Integer, Field(ge=1)], str] = Field(default_factory=dict)
    fixed: dict[str, Number] | None = None
    max_samples: Integer = Field(50_000, ge=10)
    seed: Integer = 0
    reflectance_scale: Number = Field(1.0, gt=0)
    min_samples: Integer = Field(500, ge=1)
    min_vza_spread: Number = Field(10.0, ge=0)
    fallback: str | None = None
    output: str = "fitted_params.yaml"

    @field_validator("fallback")
    @classmethod
    def _fallback(cls, value: str | None) -> str | None:
        if value is not None:
            _check_material(value)
        return value


def _check_material(name: str) -> str:
    try:
        load_material(name)
    except UnknownNameError:
        allowed = ", ".join(map(repr, material_names()))
        raise ValueError(f"{short_repr(name)} is not a built-in material; allowed: {allowed}") from None
    return name


class ParametersConfig(_Strict):
    """The parameter table of the run, merged from (later wins for a class id): built-in
    ``materials``, inline ``classes``, the ``table`` file, and the output of the ``fit`` step.

    Attributes
    ----------
    table : str, optional
        Parameter table YAML (``docs/parameter-tables.md`` format).
    materials : dict of int to str
        Class id -> built-in material name (paper 003, Table 1; ``brdfcorr materials``).
    classes : list
        Classes written inline, as under ``classes:`` of a parameter table file.
    """

    table: str | None = None
    materials: dict[Annotated[Integer, Field(ge=1)], str] = Field(default_factory=dict)
    classes: list[ClassEntry] = Field(default_factory=list)

    @field_validator("materials")
    @classmethod
    def _materials(cls, value: dict[int, str]) -> dict[int, str]:
        for name in value.values():
            _check_material(name)
        return value

    @field_validator("classes")
    @classmethod
    def _unique(cls, value: list[ClassEntry]) -> list[ClassEntry]:
        duplicates = sorted(i for i, count in Counter(entry.id for entry in value).items() if count > 1)
        if duplicates:
            raise ValueError(f"class id(s) {', '.join(map(str, duplicates))} appear more than once")
        return value


class TerrainStep(_Strict):
    """Tilted surfaces in the correct step (:class:`brdfcorr.workflow.correction.Terrain`,
    ``docs/terrain.md``); slope and aspect come from ``inputs.slope_aspect`` or ``inputs.dem``.

    Attributes
    ----------
    topographic : {"cosine", "c", "scs", "scs+c", "none"}
        Illumination correction before the BRDF step
        (:func:`brdfcorr.topographic.topographic_correction`).
    brdf_frame : {"surface", "horizontal"}
        Evaluate the BRDF in each surface's own frame or in the horizontal frame. The empirical C
        of ``"c"`` and ``"scs+c"`` goes with ``"horizontal"`` only (it absorbs part of the BRDF's
        slope dependence).
    """

    topographic: Literal["cosine", "c", "scs", "scs+c", "none"] = "cosine"
    brdf_frame: Literal["surface", "horizontal"] = "surface"

    @model_validator(mode="after")
    def _frame(self) -> TerrainStep:
        conflict = frame_conflict(self.topographic, self.brdf_frame)
        if conflict:
            raise ValueError(conflict)
        return self


class CorrectStep(_Strict):
    """The normalization step (:func:`brdfcorr.correct.correct_files` options).

    Attributes
    ----------
    limits : (float, float) or None
        Limits of the correction factor [-] (default 0.2 to 5); null for none.
    unknown : {"keep", "nan"}
        Pixels of class 0 or of classes absent from the table: unchanged, or NaN.
    extrapolate : bool
        Let band centres outside a class's table wavelengths take the edge values.
    flip_view_azimuth : bool
        View azimuths are stored as seen from the sensor: add 180 deg.
    qa : bool
        Also write the QA flag raster.
    terrain : TerrainStep, optional
        Correct tilted surfaces (needs ``inputs.slope_aspect`` or ``inputs.dem``); null: a flat
        surface.
    """

    limits: tuple[Annotated[Number, Field(gt=0)], Annotated[Number, Field(gt=0)]] | None = DEFAULT_LIMITS
    unknown: Literal["keep", "nan"] = "keep"
    extrapolate: bool = False
    flip_view_azimuth: bool = False
    qa: bool = True
    terrain: TerrainStep | None = None

    @field_validator("limits")
    @classmethod
    def _limits(cls, value):
        if value is not None and not value[0] <= 1.0 <= value[1]:
            raise ValueError(f"limits {list(value)} must satisfy lower <= 1 <= upper")
        return value


class QuicklookStep(_Strict):
    """Before/after quicklook PNG of every scene.

    Attributes
    ----------
    bands : list of int
        1-based bands shown as red, green, blue (three), or one band in grey.
    percentiles : (float, float)
        Contrast stretch of the *input* image, applied to both panels so they compare [%].
    max_size : int
        Longest side of the quicklook [pixels]; larger images are block-averaged.
    """

    bands: list[Annotated[Integer, Field(ge=1)]] = Field(default_factory=lambda: [3, 2, 1])
    percentiles: tuple[Annotated[Number, Field(ge=0, le=100)], Annotated[Number, Field(ge=0, le=100)]] = (2.0, 98.0)
    max_size: Integer = Field(800, ge=16)

    @field_validator("bands")
    @classmethod
    def _count(cls, value: list[int]) -> list[int]:
        if len(value) not in (1, 3):
            raise ValueError(f"give 1 or 3 bands, got {len(value)}")
        return value

    @field_validator("percentiles")
    @classmethod
    def _order(cls, value):
        if not value[0] < value[1]:
            raise ValueError(f"percentiles {list(value)} must be increasing")
        return value


class AssessStep(_Strict):
    """The view-angle signal left in every scene, before and after the correction
    (:func:`brdfcorr.workflow.assessment.assess_files`): ``{scene}_assess.json`` and the figure
    ``{scene}_assess_profiles.png`` (:func:`brdfcorr.plot.assess.write_assessment_figures`) in
    the output directory.

    Attributes
    ----------
    sign_by : {"sun", "track"}
        Sign of the view zenith (:func:`brdfcorr.analysis.assess.signed_view_zenith`): positive
        towards forward scattering (``sun``) or right of the flight direction (``track``).
    heading : float, optional
        Flight direction [deg] clockwise from north; needed for ``sign_by: track`` (only there).
    bin_width : float
        Width of the bins of signed view zenith of the across-track profiles [deg].
    min_vza : float
        The side ratio compares pixels with ``|signed vza| >= min_vza`` [deg] (and never 0).
    """

    sign_by: Literal["sun", "track"] = "sun"
    heading: Number | None = Field(None, ge=0, lt=360, allow_inf_nan=False)
    bin_width: Number = Field(2.0, gt=0, le=45)
    min_vza: Number = Field(0.0, ge=0, lt=90)

    @model_validator(mode="after")
    def _heading(self) -> AssessStep:
        if self.sign_by == "track" and self.heading is None:
            raise ValueError("sign_by 'track' needs the flight direction: set heading [deg]")
        if self.sign_by == "sun" and self.heading is not None:
            raise ValueError("heading is only used with sign_by 'track'")
        return self


class StepsConfig(_Strict):
    """The steps, always run in the order fit -> correct -> assess -> quicklook; leave one out (or
    null) to skip it. ``correct`` is on by default."""

    fit: Annotated[Union[ImageryFit, GoniometerFit], Field(discriminator="source")] | None = None
    correct: CorrectStep | None = Field(default_factory=CorrectStep)
    assess: AssessStep | None = None
    quicklook: QuicklookStep | None = None

    @model_validator(mode="after")
    def _something(self) -> StepsConfig:
        if self.correct is None and self.quicklook is not None:
            raise ValueError("quicklook compares input and corrected images: it needs the correct step")
        if self.correct is None and self.assess is not None:
            raise ValueError("assess compares input and corrected images: it needs the correct step")
        return self


class OutputsConfig(_Strict):
    """Where and how results are written.

    Attributes
    ----------
    directory : str
        Output directory (created).
    naming, qa_naming, uncertainty_naming, quicklook_naming : str
        Patterns with ``{scene}``, ``{stem}``, ``{parent}`` for the corrected raster, the QA GeoTIFF,
        the uncertainty GeoTIFF and the quicklook PNG. ``naming``'s extension must fit ``format``
        (:func:`brdfcorr.io.writer.check_format`); its default is ``{scene}_brdf.tif`` for GTiff and
        ``{scene}_brdf.img`` for ENVI.
    uncertainty : bool
        Also write the per-pixel 1-sigma of the corrected reflectance [1]
        (:func:`brdfcorr.uncertainty.correction_uncertainty`, ``docs/uncertainty.md``): from the
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
    uncertainty: bool = False
    format: Literal["GTiff", "ENVI"] = "GTiff"
    interleave: Literal["bsq", "bil"] | None = None
    compress: Literal["deflate", "lzw", "zstd", "none"] = "deflate"
    cog: bool = False
    existing: Literal["error", "skip", "overwrite"] = "skip"
    report: str = "run_report.json"

    @field_validator("naming", "qa_naming", "uncertainty_naming", "quicklook_naming")
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
                                  ("uncertainty_naming", self.uncertainty_naming, "GTiff")):
            try:
                check_format(name, driver, f"outputs.{key}")
            except InputError as error:
                raise ValueError(str(error)) from None
        if self.format == "ENVI" and self.cog:
            raise ValueError("cog applies to GeoTIFF outputs, not format ENVI")
        if self.interleave is not None and self.format != "ENVI":
            raise ValueError(f"interleave applies to format ENVI, not {self.format!r}")
        return self


class EngineConfig(_Strict):
    """How the work is executed.

    Attributes
    ----------
    scheduler : {"threads", "processes", "synchronous", "distributed"}
        ``threads``: scenes one after another, each scene's chunks on ``workers`` threads.
        ``processes``: ``workers`` scenes at a time in separate processes.
        ``synchronous``: everything in the calling thread (debugging).
        ``distributed``: every scene spread chunk by chunk over all workers of a
        ``dask.distributed`` cluster at ``address`` (or of a local cluster of ``workers``
        processes when no address is given), ``workers`` scenes in flight at once.
    workers : int
        Threads (``threads``), processes (``processes``, local ``distributed``); with
        ``distributed`` also the number of scenes in flight at once.
    threads_per_worker : int
        Threads for the chunks of a scene inside a process, and of each worker process of a local
        ``distributed`` cluster.
    chunk : int, optional
        Spatial chunk and output tile size [pixels], a multiple of 16. Default: the rule of
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
    chunk: Integer | None = Field(None, ge=16, le=8192)
    address: str | None = None

    @field_validator("chunk")
    @classmethod
    def _tile(cls, value: int | None) -> int | None:
        if value is not None and value % 16:
            raise ValueError(f"chunk {value} must be a multiple of 16 (GeoTIFF tile size)")
        return value

    @model_validator(mode="after")
    def _address(self) -> EngineConfig:
        if self.address is not None and self.scheduler != "distributed":
            raise ValueError(f"address is only used with scheduler 'distributed', not {self.scheduler!r}")
        # A dask scheduler address: PROTOCOL://HOST:PORT (a typo would otherwise wait for a timeout).
        if self.address is not None and not re.fullmatch(r"(tcp|tls|ucx|ws|wss|inproc)://[^\s/]+\S*", self.address):
            raise ValueError(f"address {short_repr(self.address)} is not a dask scheduler address like "
                             "'tcp://host:8786'")
        return self


class ChainConfig(_Strict):
    """A whole processing chain. Load with :func:`load_config` (paths relative to the file).

    Attributes
    ----------
    inputs, parameters, reference, steps, outputs, engine :
        See :class:`InputsConfig`, :class:`ParametersConfig`,
        :class:`brdfcorr.params.ReferenceGeometry` (optional: default the table's, else observed
        sun and nadir view), :class:`StepsConfig`, :class:`OutputsConfig`, :class:`EngineConfig`.
    name : str
        A label for the run report.
    base_dir : Path
        Directory relative paths are resolved against (set by :func:`load_config`; not a key).
    """

    name: str = "brdfcorr chain"
    inputs: InputsConfig
    parameters: ParametersConfig = Field(default_factory=ParametersConfig)
    reference: ReferenceGeometry | None = None
    steps: StepsConfig = Field(default_factory=StepsConfig)
    outputs: OutputsConfig
    engine: EngineConfig = Field(default_factory=EngineConfig)

    _base_dir: Path = Path(".")
    _source: str = "chain config"

    @model_validator(mode="after")
    def _has_parameters(self) -> ChainConfig:
        if (self.steps.correct is not None and self.parameters.table is None
                and not self.parameters.materials and not self.parameters.classes
                and self.steps.fit is None):
            raise ValueError(
                "the correct step needs a parameter table: set parameters.table, parameters.materials, "
                "parameters.classes or a steps.fit step"
            )
        correct, inputs = self.steps.correct, self.inputs
        has_terrain = inputs.slope_aspect is not None or inputs.dem is not None
        if correct is not None and correct.terrain is not None and not has_terrain:
            raise ValueError("steps.correct.terrain needs slope and aspect: set inputs.slope_aspect or inputs.dem")
        if has_terrain and (correct is None or correct.terrain is None):
            raise ValueError("inputs.slope_aspect and inputs.dem are read by steps.correct.terrain: set it "
                             "(e.g. terrain: {}) or leave the terrain inputs out")
        if self.outputs.uncertainty and correct is None:
            raise ValueError("outputs.uncertainty is written by the correct step: it needs steps.correct")
        return self

    @property
    def base_dir(self) -> Path:
        return self._base_dir

    @property
    def source(self) -> str:
        return self._source

    def resolve(self, path: str | os.PathLike) -> Path:
        """A config path made absolute against :attr:`base_dir` (``~`` expanded)."""
        path = Path(os.path.expanduser(str(path)))
        return path if path.is_absolute() else self._base_dir / path

    @classmethod
    def from_dict(cls, data: object, source: str = "chain config", base_dir: str | os.PathLike = ".") -> ChainConfig:
        """Validate a parsed document; :class:`ConfigError` names ``source`` and the key path."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: expected a mapping of sections (inputs, outputs, ...), "
                              f"got {type(data).__name__}")
        try:
            config = cls.model_validate(dict(data))
        except ValidationError as error:
            raise ConfigError(f"{source}: {describe_errors(error, ChainConfig)}") from None
        config._base_dir = Path(base_dir).resolve()
        config._source = source
        return config

    def to_dict(self) -> dict:
        """The config as plain data (JSON/YAML-friendly), defaults filled in."""
        return self.model_dump(mode="json")


def load_config(path: str | os.PathLike, overrides: Mapping[str, object] | None = None) -> ChainConfig:
    """Read and validate a chain config (YAML, ``yaml.safe_load``).

    Parameters
    ----------
    path : path-like
        The config file; its directory is the base of relative paths.
    overrides : mapping of str to object, optional
        Dotted keys replaced before validation (``{"engine.workers": 2}``), see
        :func:`apply_overrides`.

    Raises
    ------
    ConfigError
        Unreadable file (also: not a regular file, larger than
        :data:`brdfcorr.io.files.MAX_DOCUMENT_BYTES`, not UTF-8), invalid YAML (with line and
        column) or invalid content (key path and allowed values).
    """
    path = Path(path)
    data = parse_yaml(read_document(path, "chain config", ConfigError), str(path), ConfigError)
    return config_from_document(data, path, overrides)


def config_from_document(
    data: object, path: str | os.PathLike, overrides: Mapping[str, object] | None = None
) -> ChainConfig:
    """Validate the parsed YAML ``data`` of the chain config file ``path`` (see :func:`load_config`)."""
    path = Path(path)
    if data is None:
        data = {}
    if overrides:
        data = apply_overrides(data, overrides, source=str(path))
    return ChainConfig.from_dict(data, source=str(path), base_dir=path.parent)


def apply_overrides(data: object, overrides: Mapping[str, object], source: str = "chain config") -> dict:
    """A copy of ``data`` with dotted keys set (``"engine.workers"``), creating sections as needed."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: expected a mapping of sections, got {type(data).__name__}")
    result = copy.deepcopy(dict(data))
    for key, value in overrides.items():
        parts = [part for part in str(key).split(".") if part]
        if not parts:
            raise ConfigError(f"override {key!r}: empty key")
        node = result
        for depth, part in enumerate(parts[:-1]):
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                raise ConfigError(f"override {key!r}: {'.'.join(parts[:depth + 1])} is not a section")
            node = child
        node[parts[-1]] = value
    return result
