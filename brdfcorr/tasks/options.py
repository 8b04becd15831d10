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

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from brdfcorr.defaults import (
    BRDF_FRAMES,
    DEFAULT_LIMITS,
    FACTOR_AT,
    REFERENCE_SZA_WORDS,
    TOPOGRAPHIC_METHODS,
    UNKNOWN_PIXELS,
)
from brdfcorr.io import FORMATS
from brdfcorr.io.sensors import ANGLE_KINDS

__all__ = ["Setting", "Settings", "ANGLE_SOURCE", "CLASS_MAP", "SCALE", "CORRECT", "OUTPUT_TYPES", "INTERLEAVES",
           "Unknown", "FactorAt", "Topographic", "BrdfFrame"]

#: Kinds of setting: a text, a file path (no folder), a number, an integer, a flag (off unless
#: given), an on/off switch (``--x/--no-x``, default None: decided later), a word of ``choices``,
#: or a type the command line names itself (``cli_type``).
Kind = Literal["text", "path", "float", "int", "flag", "switch", "choice", "custom"]

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
        :data:`Kind`: how a value is read.
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
    given_only: bool = False

    def bounds(self) -> dict[str, float]:
        """The given bounds as pydantic's ``Field`` keywords (``{"ge": 0.0}``)."""
        given = {"ge": self.ge, "gt": self.gt, "le": self.le, "lt": self.lt}
        return {key: value for key, value in given.items() if value is not None}


@dataclass(frozen=True)
class Settings:
    """The settings of one command, in the order ``--help`` lists them."""

    items: tuple[Setting, ...]

    def __iter__(self) -> Iterator[Setting]:
        return iter(self.items)

    def __getitem__(self, name: str) -> Setting:
        for setting in self.items:
            if setting.name == name:
                return setting
        raise KeyError(name)

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
                 "--params' class of that id; repeatable, the last wins for an id."),
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
            help="Pixels of class 0 or of classes not in the table: keep unchanged, or set to NaN."),
    Setting("wavelengths", ("--wavelengths",), "text",
            help="Band centres [nm], comma-separated (overrides the image's)."),
    SCALE,
    _flag("extrapolate", "--extrapolate", "Allow band centres outside a class's table wavelengths."),
    _flag("flip_view_azimuth", "--flip-view-azimuth", "View azimuths are stored as seen from the sensor: add 180 deg."),
    Setting("factor_at", ("--factor-at",), "choice", choices=FACTOR_AT, default="pixels", show_default=True,
            help="Evaluate the factor at every pixel, or at the nodes of the sensor's coarse angle grid "
                 "(--angles-kind sentinel2) and interpolate it to the pixels: sen2nbar's method, faster; one "
                 "class, no --classes, --dem, --slope-aspect or --uncertainty."),
    _path("qa_path", "--qa", "Also write the QA flags (uint8) to this GeoTIFF."),
    Setting("compress", ("--compress",), "text", default="deflate", show_default=True, help="GDAL compression."),
    _flag("cog", "--cog", "Write Cloud-Optimized GeoTIFFs."),
    Setting("chunk", ("--chunk",), "custom", cli_type="chunk",
            help="Chunk and tile size [pixels], a multiple of 16 [default: the largest multiple of the "
                 "image's tiles with at most 16 MiB of all bands as float32, else 512, 256, 128 or 64]."),
    Setting("progress", ("--progress/--no-progress",), "switch", help="Progress bar [default: on a terminal]."),
    _flag("overwrite", "--overwrite", "Replace existing outputs (-o, --qa) [default: refuse]."),
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
            given_only=True,
            help="Illumination correction before the BRDF step, with --slope-aspect or --dem [default: cosine]."),
    Setting("brdf_frame", ("--brdf-frame",), "choice", choices=BRDF_FRAMES, default="surface", given_only=True,
            help="Evaluate the BRDF in each tilted surface's frame or the horizontal one [default: surface; "
                 "horizontal for c and scs+c]."),
)
