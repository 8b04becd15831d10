"""Defaults that the library, the command line and chain configs share, written once.

This module imports nothing but :mod:`os`, so that command modules and chain configs can show and
check these defaults without loading the library.
"""

import os

#: Range the BRDF correction factor f_ref / f_obs is clipped to (:func:`brdfcorr.normalize`):
#: beyond a factor of 5 either way a model is used far outside what it was fitted to. Also the
#: default range of the topographic factor and of the uncertainty's factor.
DEFAULT_LIMITS: tuple[float, float] = (0.2, 5.0)

#: Red and near-infrared ranges of the NDVI [nm] (:func:`brdfcorr.strata.ndvi`, a table's
#: ``strata`` section): they hold Sentinel-2 B4 (665) and B8/B8A (842/865), Landsat 8/9 OLI B4
#: (655) and B5 (865), and the 660/850 nm bands FlexBRDF uses.
RED_RANGE: tuple[float, float] = (620.0, 690.0)
NIR_RANGE: tuple[float, float] = (780.0, 900.0)
#: Default NDVI edges of the strata (:func:`brdfcorr.strata.ndvi_strata`): bare/built (< 0.1), sparse
#: (0.1-0.3), moderate (0.3-0.5), dense (0.5-0.7) and very dense (>= 0.7) vegetation. Fixed edges
#: give the same ids the same meaning in every scene.
DEFAULT_EDGES: tuple[float, ...] = (0.1, 0.3, 0.5, 0.7)

#: Chunk and output tile sizes [pixels] a user may give (``--chunk``, a chain's ``engine.chunk``):
#: multiples of 16 (GeoTIFF tiles are) from the first to the second.
CHUNK_RANGE: tuple[int, int] = (16, 8192)


#: Cores per dask thread of a writing pass on this machine when the caller names no thread count:
#: reading and correcting a chunk costs a third of compressing it (deflate with predictor, measured
#: on a 64-band cube), and GDAL compresses on all cores; every further dask thread holds its chunks
#: and their intermediates (about 170 MiB for a 16 MiB chunk), docs/scaling.md.
CORES_PER_THREAD = 4


def available_cores() -> int:
    """The cores this process may run on: its CPU affinity where the system has one (``taskset``,
    a container's CPU set), else the machine's cores."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity on macOS and Windows
        return max(1, os.cpu_count() or 1)


def default_threads() -> int:
    """The dask threads of a scene's pass on this machine when the user names none: one per
    :data:`CORES_PER_THREAD` of :func:`available_cores` (GDAL compresses on all of them). The one
    rule of ``brdfcorr correct`` (:func:`brdfcorr.io.writer.write_rasters`) and of a chain's ``threads`` engine."""
    return max(1, available_cores() // CORES_PER_THREAD)


#: Narrowest bin of the across-track profiles of ``assess`` [deg] (``--bin-width``): 2 x 90 / 0.01 =
#: 18 000 bins at most (a width of 1e-9 asked for 1.3 TiB of bin edges).
MIN_BIN_WIDTH = 0.01
#: Largest side of the blocks the slopes' 1-sigma is cluster-robust over [pixels] (``--block-size``):
#: larger than any image, so one block; beyond it block indices overflow 64-bit integers.
MAX_BLOCK_SIZE = 2**20


def chunk_size_problem(value: object) -> str | None:
    """What is wrong with ``value`` as a chunk and tile size (``"must be a multiple of 16 ..."``),
    or None for a good one: an integer, a multiple of 16 in :data:`CHUNK_RANGE`."""
    low, high = CHUNK_RANGE
    try:
        number = None if isinstance(value, bool) else value.__index__()  # type: ignore[attr-defined]
    except (AttributeError, TypeError):  # __index__: Python's and numpy's integers, no floats
        number = None
    if number is None:
        return "must be an integer"
    if not (low <= number <= high and number % 16 == 0):
        return f"must be a multiple of 16 from {low} to {high} (GeoTIFF tile size; e.g. 256 or 512)"
    return None


#: Names of the registered BRDF models, in :data:`brdfcorr.models.REGISTRY`'s order: for the
#: command line's ``--model`` choices and messages without importing the models (scipy).
#: tests/models/test_registry.py keeps them equal to the registry.
MODEL_NAMES: tuple[str, ...] = (
    "torrance_sparrow",
    "torrance_sparrow_simplified",
    "empirical",
    "lambertian",
    "specular_peak",
    "ross_thick_li_sparse",
    "ross_thin_li_sparse",
    "ross_thick_li_dense",
    "ross_thin_li_dense",
    "rpv",
    "ross_li_ts",
    "ross_li_peak",
    "rpv_peak",
)

#: Models that describe a whole surface (diffuse + specular) and so may be paired with a class in
#: a parameter table (:data:`brdfcorr.models.SURFACE_MODELS`); ``specular_peak`` is a facet BRDF
#: used by the V-cavity simulation.
SURFACE_MODEL_NAMES: tuple[str, ...] = tuple(name for name in MODEL_NAMES if name != "specular_peak")

#: The model "name" of the fits (``fit``, ``fit-classes``, chains) that asks for the surface model
#: with the lowest held-out error (:mod:`brdfcorr.fit.selection`).
AUTO_MODEL = "auto"

#: Whose brightness level an imagery fit leaves free (:func:`brdfcorr.fit.sampling.sample_classes`,
#: :mod:`brdfcorr.fit.within`): one for the class (``pooled``); one per pixel seen in several
#: scenes on one grid (``pixel``); one per square patch of pixels (``patch``: a composite's
#: neighbours come from other orbits); ``auto``: ``pixel`` where several scenes share one grid,
#: else ``pooled``.
LEVELS = ("auto", "pooled", "pixel", "patch")
#: How the errors of an imagery fit are clustered (``--errors-cluster``; :mod:`brdfcorr.fit.two_way`):
#: over spatial blocks, pixels or cluster-layer ids, or over those and the scenes at once.
ERROR_CLUSTERS = ("one-way", "two-way")

#: Topographic (illumination) corrections before the BRDF step
#: (:func:`brdfcorr.correction.topographic.topographic_correction`, whose ``METHODS`` these are).
TOPOGRAPHIC_METHODS: tuple[str, ...] = ("cosine", "c", "scs", "scs+c")
#: The topographic methods with a fitted, empirical C coefficient.
C_METHODS: tuple[str, ...] = ("c", "scs+c")
#: Frames a correction evaluates the BRDF of a tilted surface in: the surface's own, or the horizontal.
BRDF_FRAMES: tuple[str, ...] = ("surface", "horizontal")


def frame_conflict(method: str, brdf_frame: str) -> str | None:
    """Why topographic ``method`` cannot precede a BRDF evaluated in ``brdf_frame``, or None: the
    empirical C of :data:`C_METHODS` absorbs part of the BRDF's slope dependence, so with the BRDF
    in the surface's frame the illumination is corrected twice (15 % between the sides of the
    synthetic hill of ``tests/correction/test_terrain.py``)."""
    if method in C_METHODS and brdf_frame == "surface":
        return (f"topographic {method!r} fits an empirical C that absorbs part of the BRDF's slope "
                "dependence; combine it with brdf_frame 'horizontal', or use 'cosine' with 'surface'")
    return None


#: What a correction does with pixels of class 0 or of a class absent from the table: keep them
#: unchanged, or set them to NaN (:func:`brdfcorr.normalize`'s ``unknown``).
UNKNOWN_PIXELS: tuple[str, ...] = ("keep", "nan")
#: Below this fraction of the valid pixels corrected, a correction says so (a warning and a note;
#: :func:`brdfcorr.tasks.correct.too_few_corrected`, a chain's ``min_corrected_share``).
MOSTLY_UNCORRECTED = 0.5
#: Where a correction evaluates its factor: at every pixel, or at the nodes of a sensor's coarse
#: angle grid, interpolated to the pixels (:mod:`brdfcorr.correction.nodes`).
FACTOR_AT: tuple[str, ...] = ("pixels", "nodes")
#: Signs of the view zenith of an assessment (:func:`brdfcorr.analysis.view_angles.signed_view_zenith`):
#: positive towards forward scattering (``sun``) or right of the flight direction (``track``).
SIGN_CONVENTIONS: tuple[str, ...] = ("sun", "track")
#: The reference sun zenith's words besides a number [deg] (:class:`brdfcorr.params.ReferenceGeometry`).
REFERENCE_SZA_WORDS: tuple[str, ...] = ("mean", "observed", "hls")
