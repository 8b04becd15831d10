"""Helpers of the options the commands that read scenes share (their settings are in
:mod:`brdfcorr.tasks.options`): ``--scale``/``--offset`` of ``classes ndvi``, the prior of a fit
(``--prior``, ``--prior-spread``) and the reference sun zenith (``--ref-sza``)."""

from __future__ import annotations

import click

from brdfcorr.cli._settings import setting_options
from brdfcorr.defaults import REFERENCE_SZA_WORDS
from brdfcorr.tasks.options import SCALE, settings

#: ``--scale`` and ``--offset`` (``classes ndvi``; the commands with a table of settings have them in it).
scale_options = setting_options(settings(SCALE))


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
