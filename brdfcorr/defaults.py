"""Defaults that the library, the command line and chain configs share, written once.

This module imports nothing, so that command modules can show these defaults in ``--help``
without loading the library.
"""

#: Range the BRDF correction factor f_ref / f_obs is clipped to (:func:`brdfcorr.normalize`):
#: beyond a factor of 5 either way a model is used far outside what it was fitted to. Also the
#: default range of the topographic factor and of the uncertainty's factor.
DEFAULT_LIMITS: tuple[float, float] = (0.2, 5.0)
