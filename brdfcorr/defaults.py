"""Defaults that the library, the command line and chain configs share, written once.

This module imports nothing, so that command modules can show these defaults in ``--help``
without loading the library.
"""

#: Range the BRDF correction factor f_ref / f_obs is clipped to (:func:`brdfcorr.normalize`):
#: beyond a factor of 5 either way a model is used far outside what it was fitted to. Also the
#: default range of the topographic factor and of the uncertainty's factor.
DEFAULT_LIMITS: tuple[float, float] = (0.2, 5.0)

#: Chunk and output tile sizes [pixels] a user may give (``--chunk``, a chain's ``engine.chunk``):
#: multiples of 16 (GeoTIFF tiles are) from the first to the second.
CHUNK_RANGE: tuple[int, int] = (16, 8192)


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
