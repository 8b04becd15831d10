"""The settings of the tasks, each described once: :class:`Setting` and one table per command.

A :class:`Setting` carries what the command line, a chain config and a request need to know of one
setting: its name, its command-line flags, its kind (a path, a number, a word from a list, ...), its
default, its bounds, its help text and its allowed words. The command line's options are made from
these tables (:func:`brdfcorr.cli._settings.setting_options`), the chain steps' fields take their
defaults, bounds and words from them (:mod:`brdfcorr.chain.config_steps`) and the requests their
defaults (:mod:`brdfcorr.tasks.request`). The allowed words come from the modules that own them
(:mod:`brdfcorr.defaults`, whose words :mod:`brdfcorr.correction.topographic` and the models
registry use, and :data:`brdfcorr.io.FORMATS`).

Adding a setting to a command: one :class:`Setting` in its table here, and the code that uses it.

This module imports nothing heavy: ``brdfcorr --help`` shows these tables without loading the
library.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from brdfcorr.defaults import (
    AUTO_MODEL,
    BRDF_FRAMES,
    DEFAULT_LIMITS,
    ERROR_CLUSTERS,
    FACTOR_AT,
    LEVELS,
    MAX_BLOCK_SIZE,
    MIN_BIN_WIDTH,
    REFERENCE_SZA_WORDS,
    SIGN_CONVENTIONS,
    TOPOGRAPHIC_METHODS,
    UNKNOWN_PIXELS,
)
from brdfcorr.io import FORMATS
from brdfcorr.io.sensors import ANGLE_KINDS

__all__ = ["Setting", "Settings", "ANGLE_SOURCE", "CLASS_MAP", "SCALE", "FLIP_VIEW_AZIMUTH", "PRIOR", "SLOPE_BLOCK",
           "CORRECT", "FIT_CLASSES", "ASSESS", "ASSESS_LINES", "NBAR", "CHAIN_INPUTS", "OUTPUT_TYPES", "INTERLEAVES",
           "Unknown", "FactorAt", "Topographic", "BrdfFrame"]

#: Kinds of setting: a text, a file path (no folder), a number, an integer, a flag (off unless
#: given), an on/off switch (``--x/--no-x``, default None: decided later), a word of ``choices``,
#: or a type the command line names itself (``cli_type``).
Kind = Literal["text", "path", "dir", "float", "int", "flag", "switch", "choice", "custom"]

#: Type aliases of the words (for annotations; the words are the tuples of :mod:`brdfcorr.defaults`).
Unknown = Literal[UNKNOWN_PIXELS]  # type: ignore[valid-type]
FactorAt = Literal[FACTOR_AT]  # type: ignore[valid-type]
Topographic = Literal[(*TOPOGRAPHIC_METHODS, "none")]  # type: ignore[valid-type]
BrdfFrame = Literal[BRDF_FRAMES]  # type: ignore[valid-type]

#: Data types of a corrected image: float32 reflectance factors, or the integer input's own type.
OUTPUT_TYPES: tuple[str, ...] = ("float", "input")
#: Interleaves of an ENVI output (band sequential, band interleaved by line).
INTERLEAVES: tuple[str, ...] = ("bsq", "bil")


@dataclass(frozen=True)
class Setting:
    """One setting of a task.

    Attributes
    ----------
    name : str
        Python name: the command's parameter, the chain key and the request field where there is one.
    flags : tuple of str
        Command-line flags, e.g. ``("-o", "--output")`` or ``("--progress/--no-progress",)``.
    kind : str
        :data:`Kind`: how a value is read (``"dir"``: a folder path).
    help : str
        Help text, as ``--help`` shows it (units in brackets, ``[default: ...]`` where it is not shown).
    default : object, optional
        Default value (None: not given).
    choices : tuple of str
        Allowed words of a ``"choice"``.
    ge, gt, le, lt : float, optional
        Bounds of a number (greater or equal, greater, ...).
    nargs : int
        Values per use (2: a pair of numbers).
    multiple : bool
        Repeatable; the values are collected in a tuple.
    required, show_default, case_sensitive : bool
        Required on the command line; its default shown in ``--help``; words compared case-sensitively.
    metavar, envvar : str, optional
        The value's placeholder in ``--help``; an environment variable giving the default.
    cli_type : str, optional
        Name of a command-line type (``"chunk"``, ``"material"``, ``"reader_option"``, ...) of a
        ``"custom"`` setting: :data:`brdfcorr.cli._settings.CUSTOM_TYPES`.
    hidden : bool
        Left out of ``--help`` (a deprecated spelling).
    chain : str, optional
        The chain step (``"correct"``, ``"terrain"``, ``"fit"``, ``"assess"``) or section
        (``"inputs"``: :data:`CHAIN_INPUTS`) that has this setting as a key of the same name, its
        field made from this setting (:func:`brdfcorr.chain.config_steps.step_fields`).
    chain_bounds : tuple of (str, object)
        The chain key's own pydantic ``Field`` keywords over the bounds (a stricter bound,
        ``allow_inf_nan``).
    given_only : bool
        The command line passes None where the option is not given (its ``default`` is applied
        later, after checking what it goes with; ``--help`` says ``[default: ...]``).
    """

    name: str
    flags: tuple[str, ...]
    kind: Kind
    help: str
    default: object = None
    choices: tuple[str, ...] = ()
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    nargs: int = 1
    multiple: bool = False
    required: bool = False
    show_default: bool = False
    case_sensitive: bool = True
    metavar: str | None = None
    envvar: str | None = None
    cli_type: str | None = None
    hidden: bool = False
    given_only: bool = False
    chain: str | None = None
    chain_bounds: tuple[tuple[str, object], ...] = ()

    def bounds(self) -> dict[str, float]:
        """The given bounds as pydantic's ``Field`` keywords (``{"ge": 0.0}``)."""
        given = {"ge": self.ge, "gt": self.gt, "le": self.le, "lt": self.lt}
        return {key: value for key, value in given.items() if value is not None}

    def chained(self, step: str, **chain_bounds: object) -> Setting:
        """This setting, also a key of the chain step ``step`` (with the chain's own ``Field`` keywords)."""
        return dataclasses.replace(self, chain=step, chain_bounds=tuple(chain_bounds.items()))


@dataclass(frozen=True)
class Settings:
    """The settings of one command, in the order ``--help`` lists them."""

    items: tuple[Setting, ...]

    def __iter__(self) -> Iterator[Setting]:
        return iter(self.items)

    def __getitem__(self, name: str) -> Setting:
        return {setting.name: setting for setting in self.items}[name]

    def default(self, name: str) -> Any:
        """The default of the setting ``name``."""
        return self[name].default

    def names(self) -> list[str]:
        """The settings' names, in order."""
        return [setting.name for setting in self.items]


def _path(name: str, flag: str, text: str, **more) -> Setting:
    """A file-path setting (no folder)."""
    return Setting(name, (flag,), "path", text, **more)


def _flag(name: str, flag: str, text: str) -> Setting:
    """A flag, off unless given."""
    return Setting(name, (flag,), "flag", text, default=False)


def settings(*parts: Setting | Sequence[Setting]) -> Settings:
    """A command's table from single settings and shared groups (:data:`ANGLE_SOURCE`, ...)."""
    items: list[Setting] = []
    for part in parts:
        items += [part] if isinstance(part, Setting) else list(part)
    return Settings(tuple(items))


#: ``--angles-kind`` and ``--angle-option``: which reader the angle source goes through.
ANGLE_SOURCE = (
    Setting("angles_kind", ("--angles-kind",), "choice", default="geotiff", show_default=True,
            choices=("geotiff", *ANGLE_KINDS),
            help="What --angles is: a 4-band GeoTIFF, an ENVI obs file (AVIRIS-NG/-3), a Sentinel-2 "
                 "MTD_TL.xml, a Landsat C2 angle band (…_SZA.TIF), a NEON AOP reflectance .h5, an "
                 "EMIT L1B OBS .nc or, for 'solar', a UTC time."),
    Setting("angle_option", ("--angle-option",), "custom", cli_type="reader_option", multiple=True,
            metavar="KEY=VALUE",
            help="Option of the angle reader (repeatable), e.g. band=B04, resolution=20, "
                 "ang=LC08_..._ANG.txt."),
)

#: ``--align-classes`` and ``--class-lookup``: a class map on another grid, or with other codes.
CLASS_MAP = (
    _flag("align_classes", "--align-classes",
          "The class map may lie on another grid or CRS: resample it by nearest neighbour."),
    _path("class_lookup", "--class-lookup",
          "YAML mapping of class-map codes to table class ids (e.g. land-cover codes)."),
)

#: ``--scale`` and ``--offset``: stored values to reflectance factors, applied on read.
SCALE = (
    Setting("scale", ("--scale",), "float", gt=0,
            help="Reflectance factor per stored unit, e.g. 0.0001 for 0-10000, applied on read "
                 "[default: the image's GDAL scale, else 1]; replaces a tagged scale."),
    Setting("offset", ("--offset",), "float",
            help="Reflectance factor of a stored 0, e.g. -0.2 for Landsat C2 L2 [default: the "
                 "image's GDAL offset, else 0]."),
)

#: ``--flip-view-azimuth`` of ``correct`` and ``fit-classes``: a property of the angle sources, so a
#: chain sets it once for every step that reads them (:data:`CHAIN_INPUTS`), or as the correct
#: step's key.
FLIP_VIEW_AZIMUTH = _flag("flip_view_azimuth", "--flip-view-azimuth",
                          "View azimuths are stored as seen from the sensor: add 180 deg.")

#: ``--prior`` and ``--prior-spread``: a coefficient set's kernel shape as the prior of a fit.
PRIOR = (
    Setting("prior", ("--prior",), "text", metavar="SET",
            help="Built-in coefficient set (brdfcorr coefficients: roy2016, roy2017) whose kernel shape "
                 "(f_vol/f_iso, f_geo/f_iso) is a prior of the fitted ross_thick_li_sparse classes: each "
                 "band's weights become their posterior (docs/parameter-tables.md) [default: none]."),
    Setting("prior_spread", ("--prior-spread",), "float", gt=0.0,
            help="With --prior: its 1-sigma of either ratio; smaller trusts the prior more [default: 0.2]."),
)

#: ``--block-size`` of ``assess`` and ``assess-lines``: the blocks of the slopes' 1-sigma.
SLOPE_BLOCK = (
    Setting("block_size", ("--block-size",), "int", ge=1, le=MAX_BLOCK_SIZE, default=32, show_default=True,
            help="Side [pixels] of the square blocks the slopes' 1-sigma is cluster-robust over (pixels of a block "
                 "may share their errors: a field, a roof); the 1-sigma over blocks twice as large is reported too, "
                 "with a warning where it is more than 1.25x larger (errors correlated beyond the blocks)."),
)

_OVERWRITE_OUTPUTS = _flag("overwrite", "--overwrite", "Replace existing outputs (-o, --qa) [default: refuse].")
_PROGRESS = Setting("progress", ("--progress/--no-progress",), "switch", help="Progress bar [default: on a terminal].")
_COMPRESS = Setting("compress", ("--compress",), "text", default="deflate", show_default=True, help="GDAL compression.")
_COG = _flag("cog", "--cog", "Write Cloud-Optimized GeoTIFFs.")
_QA = _path("qa_path", "--qa", "Also write the QA flags (uint8) to this GeoTIFF.")
_SIGN_BY = Setting("sign_by", ("--sign-by",), "choice", choices=SIGN_CONVENTIONS, default="sun", show_default=True,
                   help="Sign of the view zenith: + forward scattering (sun), or + right of the flight direction "
                        "(track, with --heading).")
_HEADING = Setting("heading", ("--heading",), "float", help="Flight direction [deg from north] for --sign-by track.")
_CLUSTER_BAND = "The band of {} that holds the ids."
_ASSESS_CHUNK = Setting("chunk", ("--chunk",), "custom", cli_type="chunk",
                        help="Chunk size [pixels], a multiple of 16 [default: a multiple of the input's tiles, about "
                             "16 MiB of all bands].")

_ANGLE_RASTERS = tuple(
    _path(name, f"--{name}", f"{what} raster [deg].")
    for name, what in (("sza", "Solar zenith"), ("saa", "Solar azimuth"), ("vza", "View zenith"),
                       ("vaa", "View azimuth"))
)

#: ``brdfcorr correct`` (:class:`brdfcorr.tasks.request.CorrectionRequest`); the chain's correct
#: step takes ``limits``, ``unknown``, ``extrapolate``, ``flip_view_azimuth``, ``factor_at``,
#: ``topographic`` and ``brdf_frame`` from here.
CORRECT = settings(
    Setting("angles", ("--angles",), "text",
            help="Angle source: a 4-band raster of sza, saa, vza, vaa [deg] on the image grid, or "
                 "what --angles-kind names (a sensor file, or a UTC time for 'solar')."),
    ANGLE_SOURCE,
    _ANGLE_RASTERS,
    _path("raa", "--raa", "Relative azimuth raster [deg], vaa - saa (0 at the hotspot), with --sza and --vza, for "
                          "products that give no absolute azimuths (MODIS, VIIRS)."),
    _path("classes", "--classes", "Class map raster (ids of the parameter table; 0 = no class) [default: none, the "
                                  "whole image is class 1]."),
    CLASS_MAP,
    _path("params_path", "--params", "Parameter table (YAML), or a built-in coefficient set (brdfcorr coefficients: "
                                     "roy2016, roy2017) as class 1; optional with --material."),
    Setting("materials", ("--material",), "custom", cli_type="material", multiple=True,
            help="Class ID takes a built-in material (brdfcorr materials; a fit at 550 nm), over "
                 "--params' class of that id; repeatable, one material an id."),
    Setting("output", ("-o", "--output"), "path", required=True,
            help="Output raster (.tif for GTiff; .img, .bsq, .bil, .dat or no extension for ENVI)."),
    Setting("output_format", ("--format",), "choice", choices=FORMATS, default="GTiff", show_default=True,
            help="Output format; ENVI writes the data file, a .hdr header (wavelengths, map info) and "
                 ".aux.xml (tags). The QA layer is always a GeoTIFF."),
    Setting("output_type", ("--output-type",), "choice", choices=OUTPUT_TYPES, default="float", show_default=True,
            help="float: reflectance factors as float32; input: an integer input's own type (up to 32 bits; "
                 "64-bit integers are refused), scale, offset and nodata (smaller files; values that do not fit "
                 "are nodata and flagged)."),
    Setting("interleave", ("--interleave",), "choice", choices=INTERLEAVES, case_sensitive=False, default="bsq",
            show_default=True, help="Interleave of an ENVI output."),
    Setting("ref_sza", ("--ref-sza",), "text",
            help=f"Reference sun zenith [deg], {', '.join(map(repr, REFERENCE_SZA_WORDS[:-1]))} or "
                 f"{REFERENCE_SZA_WORDS[-1]!r} (HLS v1.4's for the scene's latitude) [default: table, else observed]."),
    Setting("ref_vza", ("--ref-vza",), "float", help="Reference view zenith [deg] [default: table, else 0]."),
    Setting("ref_raa", ("--ref-raa",), "float", help="Reference relative azimuth [deg] [default: table, else 0]."),
    Setting("limits", ("--limits",), "float", nargs=2, default=DEFAULT_LIMITS, show_default=True,
            help="Lower and upper limit of the correction factor."),
    _flag("no_limits", "--no-limits", "Do not limit the correction factor."),
    Setting("unknown", ("--unknown",), "choice", choices=UNKNOWN_PIXELS, default="keep", show_default=True,
            help="Pixels of class 0 or of classes not in the table: keep unchanged, or set to NaN.", chain="correct"),
    Setting("wavelengths", ("--wavelengths",), "text",
            help="Band centres [nm], comma-separated (overrides the image's)."),
    SCALE,
    _flag("extrapolate", "--extrapolate", "Allow band centres outside a class's table wavelengths.").chained("correct"),
    FLIP_VIEW_AZIMUTH.chained("correct"),
    Setting("factor_at", ("--factor-at",), "choice", choices=FACTOR_AT, default="pixels", show_default=True,
            help="Evaluate the factor at every pixel, or at the nodes of the sensor's coarse angle grid "
                 "(--angles-kind sentinel2) and interpolate it to the pixels: sen2nbar's method, faster; one "
                 "class, no --classes, --dem, --slope-aspect or --uncertainty.", chain="correct"),
    _QA,
    _COMPRESS,
    _COG,
    Setting("chunk", ("--chunk",), "custom", cli_type="chunk",
            help="Chunk and tile size [pixels], a multiple of 16 [default: the largest multiple of the "
                 "image's tiles with at most 16 MiB of all bands as float32, else 512, 256, 128 or 64]."),
    _PROGRESS,
    _OVERWRITE_OUTPUTS,
    Setting("scheduler", ("--scheduler",), "text", metavar="ADDRESS", envvar="DASK_SCHEDULER_ADDRESS",
            help="Address of a dask.distributed scheduler (tcp://host:8786): spread the scene chunk by chunk "
                 "over all its workers, which need the file system of the inputs and outputs [default: all "
                 "cores of this machine]."),
    _path("uncertainty_path", "--uncertainty",
          "Also write the per-pixel 1-sigma of the corrected reflectance (from the table's fit: "
          "covariances; NaN for classes without one) to this GeoTIFF."),
    _path("slope_aspect", "--slope-aspect",
          "Tilted surfaces: a 2-band raster of slope and aspect [deg] on the image grid, or an ENVI "
          "obs_ort file (bands Slope, Aspect)."),
    _path("dem", "--dem",
          "Tilted surfaces: a DEM/DSM [m] on the image grid (projected CRS; its pixel size in the CRS's "
          "unit, e.g. US survey feet, is converted to metres); slope and aspect by Horn's differences."),
    Setting("topographic", ("--topographic",), "choice", choices=(*TOPOGRAPHIC_METHODS, "none"), default="cosine",
            given_only=True, chain="terrain",
            help="Illumination correction before the BRDF step, with --slope-aspect or --dem [default: cosine]."),
    Setting("brdf_frame", ("--brdf-frame",), "choice", choices=BRDF_FRAMES, default="surface", given_only=True,
            chain="terrain",
            help="Evaluate the BRDF in each tilted surface's frame or the horizontal one [default: surface; "
                 "horizontal for c and scs+c]."),
)

#: ``brdfcorr fit-classes`` (:func:`brdfcorr.tasks.fit.fit_class_files`); the chain's imagery fit
#: step takes the defaults of the sampling and the guard rails from here.
FIT_CLASSES = settings(
    Setting("angles", ("--angles",), "text", multiple=True,
            help="Angle source per image, in the images' order: a 4-band raster (sza, saa, vza, vaa "
                 "[deg]) or what --angles-kind names (none for product folders: each has its own)."),
    ANGLE_SOURCE,
    Setting("classes", ("--classes",), "path", multiple=True, required=True,
            help="Class map per image, in the images' order (product folders of one grid: one for every date)."),
    CLASS_MAP,
    Setting("model_name", ("--model",), "custom", cli_type="fit_model",
            help="Model for every class (see `brdfcorr models`), or auto: per class the candidate with the lowest "
                 "held-out error over spatial blocks [default: ross_thick_li_sparse on an NDVI strata map "
                 "(brdfcorr classes ndvi), else torrance_sparrow]."),
    Setting("class_model", ("--class-model",), "custom", cli_type="class_model", multiple=True, metavar="ID=MODEL",
            help=f"Model of one class, or {AUTO_MODEL} (repeatable)."),
    Setting("names", ("--class-name",), "custom", cli_type="class_name", multiple=True, metavar="ID=NAME",
            help="Name of a class (repeatable) [default: the class map's class_names tag, else class_ID]."),
    Setting("deprecated_names", ("--name",), "custom", cli_type="class_name", multiple=True, hidden=True,
            help="brdfcorr <= 0.3's --class-name; says so when used."),
    Setting("fix", ("--fix",), "custom", cli_type="name_value", multiple=True, metavar="NAME=VALUE",
            help="Hold a shape parameter fixed [default: k=0.25 for TS]."),
    Setting("max_samples", ("--max-samples",), "int", default=50_000, show_default=True,
            help="Samples per class, over all images.").chained("fit", ge=10),
    Setting("seed", ("--seed",), "int", default=0, show_default=True, help="Seed of the pixel sampler.", chain="fit"),
    Setting("block_size", ("--block-size",), "int", ge=1, default=32, show_default=True, chain="fit",
            help="Side [pixels] of the spatial blocks the fit's errors are cluster-robust over: smaller for "
                 "coarse pixels or small images (errors from few blocks are flagged UNRELIABLE)."),
    Setting("levels", ("--levels",), "choice", choices=LEVELS, default="auto", show_default=True, chain="fit",
            help="Whose brightness level is free: auto frees each pixel's where several images share one grid "
                 "(the shape is fitted to each pixel's own views, so land-cover differences between pixels never "
                 "enter it) and pools a single image; patch frees each --patch-size square's (a composite, "
                 "whose neighbours were seen from other orbits); pooled: one level per class."),
    Setting("patch_size", ("--patch-size",), "int", ge=1, default=8, show_default=True, chain="fit",
            help="Side [pixels] of the patches of --levels patch (a divisor of --block-size)."),
    Setting("errors_cluster", ("--errors-cluster",), "choice", choices=ERROR_CLUSTERS, default="one-way",
            show_default=True, chain="fit",
            help="one-way: the fit's errors are cluster-robust over --block-size squares (or pixels, patches, "
                 "--clusters ids); two-way: over those and the images at once (errors shared by every pixel of "
                 "a date or line: its atmosphere, its calibration; Cameron, Gelbach & Miller 2011). Needs many "
                 "images to be trusted."),
    Setting("cluster_layers", ("--clusters",), "path", multiple=True,
            help="Per image, in the images' order: a raster on its grid of integer ids of the units whose pixels "
                 "share their errors (a composite's day-of-year band, a flight-line id); the fit's errors are "
                 "cluster-robust over these instead of --block-size squares (an id is one cluster in every image)."),
    Setting("cluster_band", ("--cluster-band",), "int", ge=1, default=1, show_default=True,
            help=_CLUSTER_BAND.format("each --clusters raster")),
    SCALE,
    FLIP_VIEW_AZIMUTH,
    Setting("min_samples", ("--min-samples",), "int", default=500, show_default=True,
            help="Guard rail: minimum samples per class.").chained("fit", ge=1),
    Setting("min_vza_spread", ("--min-vza-spread",), "float", default=10.0, show_default=True,
            help="Guard rail: minimum 5-95 % view zenith spread [deg] (with free levels: the spread of the "
                 "geometry within each pixel or patch).").chained("fit", ge=0),
    Setting("max_condition", ("--max-condition",), "float", ge=1.0, default=1000.0, show_default=True,
            help="Guard rail: maximum condition number of the linear design (above it the geometry does not "
                 "separate the model's terms).").chained("fit", allow_inf_nan=False),
    Setting("bad_bands", ("--bad-bands",), "custom", cli_type="band_range", multiple=True,
            help="Wavelength range [nm] left out of the fit (repeatable; `none`: no range); bands the ENVI "
                 "header's bbl marks bad are left out too. They get no parameters and `correct` passes them "
                 "through uncorrected [default: the water-vapour bands 1340:1450 and 1800:1960]."),
    Setting("fallback", ("--fallback",), "text",
            help="Built-in material (brdfcorr materials) or coefficient set (brdfcorr coefficients: roy2016, "
                 "roy2017) for classes that fail the guard rails [default: leave uncorrected].", chain="fit"),
    PRIOR[0].chained("fit"),
    PRIOR[1].chained("fit", allow_inf_nan=False),
    Setting("output", ("-o", "--output"), "path", required=True, help="Parameter table to write (YAML)."),
    _path("report_path", "--report", "Fit report to write (JSON)."),
    Setting("plot_dir", ("--plot-dir",), "dir",
            help="Directory for one PNG per class (observed vs modelled against view zenith)."),
    _flag("overwrite", "--overwrite", "Replace an existing table (-o) and report [default: refuse]."),
    Setting("workers", ("--workers",), "int", ge=1, default=1, show_default=True,
            help="Processes that fit the classes side by side (the same fits); each first imports the fits "
                 "(about a second): for many classes or many samples."),
    _PROGRESS,
)

#: ``brdfcorr assess`` (:func:`brdfcorr.tasks.assess.assess_files`); the chain's assess step takes
#: ``sign_by``, ``heading``, ``bin_width``, ``min_vza``, ``block_size`` and ``cluster_band`` from here.
ASSESS = settings(
    Setting("classes", ("--classes",), "path", required=True,
            help="Class map raster of BEFORE (ids > 0; 0 = no class)."),
    CLASS_MAP,
    Setting("angles", ("--angles",), "text", required=True,
            help="Angle source of BEFORE: a 4-band raster of sza, saa, vza, vaa [deg] on its grid, or what "
                 "--angles-kind names."),
    ANGLE_SOURCE,
    SCALE,
    Setting("overlap", ("--overlap",), "path", nargs=2, metavar="OTHER_BEFORE OTHER_AFTER",
            help="Another line's input and corrected image: compare the two lines where they overlap."),
    Setting("class_names", ("--class-name",), "custom", cli_type="class_name", multiple=True, metavar="ID=NAME",
            help="Name of a class in the report and figures (repeatable), e.g. 1=roof_tile."),
    _SIGN_BY.chained("assess"),
    _HEADING.chained("assess", ge=0, lt=360, allow_inf_nan=False),
    Setting("bin_width", ("--bin-width",), "float", ge=MIN_BIN_WIDTH, le=90, default=2.0, show_default=True,
            help="Bin width of the across-track profiles [deg of signed view zenith].").chained("assess", le=45),
    Setting("min_vza", ("--min-vza",), "float", ge=0, lt=90, default=0.0, show_default=True,
            help="The side ratio compares pixels at least this far from nadir [deg].", chain="assess"),
    _flag("flip_view_azimuth", "--flip-view-azimuth", "View azimuths are stored as seen from the sensor."),
    SLOPE_BLOCK[0].chained("assess"),
    _path("cluster_layer", "--clusters",
          "Raster on BEFORE's grid of integer ids of the units whose pixels share their errors (a "
          "composite's day-of-year band, a flight-line id): the slopes' 1-sigma is cluster-robust over "
          "these instead of square blocks."),
    Setting("cluster_band", ("--cluster-band",), "int", ge=1, default=1, show_default=True,
            help=_CLUSTER_BAND.format("--clusters"), chain="assess"),
    Setting("resampling", ("--resampling",), "text", default="nearest", show_default=True,
            help="Resampling of the other line onto this line's grid (rasterio name)."),
    Setting("output", ("-o", "--output"), "path", required=True, help="JSON report to write."),
    Setting("figures_dir", ("--figures",), "dir",
            help="Directory for the PNG figures (assess_profiles.png, assess_overlap.png)."),
    _ASSESS_CHUNK,
    _flag("overwrite", "--overwrite", "Replace existing outputs [default: refuse]."),
    _PROGRESS,
)

#: ``brdfcorr assess-lines`` (:func:`brdfcorr.tasks.assess.leave_one_line_out_files`): the fit's and
#: the assessment's settings, some with their own help.
ASSESS_LINES = settings(
    FIT_CLASSES["classes"],
    CLASS_MAP,
    FIT_CLASSES["angles"],
    ANGLE_SOURCE,
    SCALE,
    Setting("model_name", ("--model",), "custom", cli_type="model", default="torrance_sparrow", show_default=True,
            help="Model fitted for every class (see `brdfcorr models`)."),
    dataclasses.replace(FIT_CLASSES["class_model"], help="Model of one class (repeatable)."),
    dataclasses.replace(ASSESS["class_names"], help="Name of a class in the fit and the report (repeatable), e.g. "
                                                    "1=roof_tile."),
    dataclasses.replace(FIT_CLASSES["fix"], help="Hold a shape parameter fixed in the fits."),
    PRIOR,
    dataclasses.replace(FIT_CLASSES["max_samples"], help="Samples per class, over the training lines."),
    FIT_CLASSES["seed"],
    Setting("ref_sza", ("--ref-sza",), "text",
            help="Reference sun zenith [deg], 'mean' (one sun for every line: the mean of the lines' mean sun "
                 "zeniths, so that an overlap compares two lines at one sun), 'observed' or 'hls' [default: mean]; "
                 "the view is normalized to nadir."),
    ASSESS["sign_by"],
    ASSESS["heading"],
    ASSESS["flip_view_azimuth"],
    SLOPE_BLOCK,
    Setting("cluster_layers", ("--clusters",), "path", multiple=True,
            help="Per image, in the images' order: a raster of integer ids of the units whose pixels share their "
                 "errors (detectors, acquisition days); the slopes' 1-sigma is cluster-robust over these."),
    dataclasses.replace(ASSESS["cluster_band"], help=_CLUSTER_BAND.format("each --clusters raster")),
    ASSESS["output"],
    _ASSESS_CHUNK,
    _flag("overwrite", "--overwrite", "Replace an existing report [default: refuse]."),
)

#: ``brdfcorr nbar`` (:func:`brdfcorr.tasks.nbar.nbar_files`).
NBAR = settings(
    Setting("output", ("-o", "--output"), "path", required=True,
            help="Output GeoTIFF: NBAR reflectance factors (float32), the product's bands in its order."),
    _QA,
    Setting("resolution", ("--resolution",), "choice", choices=("10", "20"),
            help="Sentinel-2 output pixel size [m]; other bands are resampled onto it [default: 20]."),
    Setting("bands", ("--bands",), "text",
            help="Band names in output order, comma-separated (B04,B8A or SR_B4,SR_B5) "
                 "[default: every band with coefficients]."),
    Setting("coefficients", ("--coefficients",), "text", default="roy2017", show_default=True,
            help="Built-in coefficient set (brdfcorr coefficients): roy2017, or roy2016 (no red-edge bands)."),
    Setting("ref_sza", ("--ref-sza",), "text", default="mean", show_default=True,
            help="Reference sun zenith [deg], 'mean' (the scene's), 'hls' (HLS v1.4's for the scene centre's "
                 "latitude) or 'observed' (each pixel's, as sen2nbar). The reference view is nadir."),
    Setting("view_band", ("--view-band",), "text",
            help="Sentinel-2: the view angles of this band's grids (e.g. B04) for every band, or "
                 "'each': every band its own (as sen2nbar; one correction per band, slower) "
                 "[default: the mean of all bands' grids]."),
    Setting("factor_at", ("--factor-at",), "choice", choices=FACTOR_AT, default="pixels", show_default=True,
            help="Sentinel-2: evaluate the c-factor at every pixel, or at the 5 km nodes of the angle grids and "
                 "interpolate it to the pixels (sen2nbar's method, faster; within 0.004 % on a real tile)."),
    _path("keep_stack", "--keep-stack",
          "Also keep the uncorrected bands as a small virtual raster (.vrt) reading the product's files, "
          "masked and scaled: e.g. BEFORE for brdfcorr assess."),
    _flag("keep_clouds", "--keep-clouds",
          "Correct cloudy, shadowed and saturated pixels too (only the product's fill is no data)."),
    _COMPRESS,
    _COG,
    Setting("chunk", ("--chunk",), "custom", cli_type="chunk",
            help="Chunk and tile size [pixels], a multiple of 16 [default: 512]."),
    _PROGRESS,
    _OVERWRITE_OUTPUTS,
)

#: The keys of a chain's ``inputs:`` section that are settings of the tasks
#: (:class:`brdfcorr.chain.config.InputsConfig`): properties of the input files, so every step
#: that reads them takes them (``flip_view_azimuth``: the imagery fit, the correction and the
#: assessment). Not given (None): a fit-only chain reads the azimuths as they are, a chain with a
#: correct step as its ``flip_view_azimuth`` says.
CHAIN_INPUTS = settings(dataclasses.replace(FLIP_VIEW_AZIMUTH, default=None, chain="inputs"))
