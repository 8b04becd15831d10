"""Defaults that the library, the command line and chain configs share, written once.

This module imports nothing, so that command modules can show these defaults in ``--help``
without loading the library.
"""

#: Range the BRDF correction factor f_ref / f_obs is clipped to (:func:`brdfcorr.normalize`):
#: beyond a factor of 5 either way a model is used far outside what it was fitted to. Also the
#: default range of the topographic factor and of the uncertainty's factor.
DEFAULT_LIMITS: tuple[float, float] = (0.2, 5.0)

#: Red and near-infrared ranges of the NDVI [nm] (:func:`brdfcorr.strata.ndvi`, a table's
#: ``strata`` section): they hold Sentinel-2 B4 (665) and B8/B8A (842/865), Landsat 8/9 OLI B4
#: (655) and B5 (865), and the 660/850 nm bands FlexBRDF uses.
RED_RANGE: tuple[float, float] = (620.0, 690.0)
NIR_RANGE: tuple[float, float] = (780.0, 900.0)

#: Chunk and output tile sizes [pixels] a user may give (``--chunk``, a chain's ``engine.chunk``):
#: multiples of 16 (GeoTIFF tiles are) from the first to the second.
CHUNK_RANGE: tuple[int, int] = (16, 8192)


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
#: What a correction does with pixels of class 0 or of a class absent from the table: keep them
#: unchanged, or set them to NaN (:func:`brdfcorr.normalize`'s ``unknown``).
UNKNOWN_PIXELS: tuple[str, ...] = ("keep", "nan")
#: Where a correction evaluates its factor: at every pixel, or at the nodes of a sensor's coarse
#: angle grid, interpolated to the pixels (:mod:`brdfcorr.correction.nodes`).
FACTOR_AT: tuple[str, ...] = ("pixels", "nodes")
#: Signs of the view zenith of an assessment (:func:`brdfcorr.analysis.view_angles.signed_view_zenith`):
#: positive towards forward scattering (``sun``) or right of the flight direction (``track``).
SIGN_CONVENTIONS: tuple[str, ...] = ("sun", "track")
#: The reference sun zenith's words besides a number [deg] (:class:`brdfcorr.params.ReferenceGeometry`).
REFERENCE_SZA_WORDS: tuple[str, ...] = ("mean", "observed", "hls")
