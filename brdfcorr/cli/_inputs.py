"""Options shared by the commands that read scenes (``correct``, ``fit-classes``, ``assess-lines``):
the angle source, the class map's grid and codes, the image's scale and offset, and the prior of
an imagery fit, made from their settings in :mod:`brdfcorr.tasks.options`."""

from __future__ import annotations

import click

from brdfcorr.cli._settings import setting_options
from brdfcorr.defaults import REFERENCE_SZA_WORDS
from brdfcorr.tasks.options import ANGLE_SOURCE, CLASS_MAP, PRIOR, SCALE, SLOPE_BLOCK, settings

#: ``--angles-kind`` and ``--angle-option``: which reader the angle source goes through.
angle_source_options = setting_options(settings(ANGLE_SOURCE))

#: ``--align-classes`` and ``--class-lookup``: a class map on another grid, or with other codes.
class_map_options = setting_options(settings(CLASS_MAP))

#: ``--scale`` and ``--offset``: stored values to reflectance factors, applied on read.
scale_options = setting_options(settings(SCALE))

#: ``--prior`` and ``--prior-spread``: a coefficient set's kernel shape as the prior of a fit.
prior_options = setting_options(settings(PRIOR))

#: ``--block-size`` of ``assess`` and ``assess-lines``: the blocks of the slopes' 1-sigma.
slope_block_option = setting_options(settings(SLOPE_BLOCK))


def prior_setting(prior: str | None, spread: float | None):
    """``--prior`` and ``--prior-spread`` as a :class:`brdfcorr.fit.prior.ShapePrior`, or None
    without a prior; an unknown set or a spread without a prior is an error before any work."""
    if spread is not None and prior is None:
        raise click.UsageError("--prior-spread needs --prior")
    if prior is None:
        return None
    from brdfcorr.fit.prior import ShapePrior

    return ShapePrior.given(prior, spread)


def reference_sza(value: str | None):
    """--ref-sza: a zenith [deg] or a word of :data:`brdfcorr.defaults.REFERENCE_SZA_WORDS` ('mean',
    'observed', 'hls'; validated by ReferenceGeometry)."""
    if value is None or value in REFERENCE_SZA_WORDS:
        return value
    try:
        return float(value)
    except ValueError:
        words = ", ".join(map(repr, REFERENCE_SZA_WORDS[:-1])) + f" or {REFERENCE_SZA_WORDS[-1]!r}"
        raise click.BadParameter(f"{value!r} is not a number, {words}") from None
