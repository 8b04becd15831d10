"""Options shared by the commands that read scenes (``correct``, ``fit-classes``, ``assess-lines``):
the angle source, the class map's grid and codes, the image's scale and offset, and the prior of
an imagery fit."""

from __future__ import annotations

from pathlib import Path

import click

from brdfcorr.cli._base import READER_OPTION
from brdfcorr.defaults import MAX_BLOCK_SIZE
from brdfcorr.io.sensors import ANGLE_KINDS


def _stack(*options):
    def decorate(command):
        for option in reversed(options):
            command = option(command)
        return command

    return decorate


#: ``--angles-kind`` and ``--angle-option``: which reader the angle source goes through.
angle_source_options = _stack(
    click.option("--angles-kind", type=click.Choice(["geotiff", *ANGLE_KINDS]), default="geotiff",
                 show_default=True,
                 help="What --angles is: a 4-band GeoTIFF, an ENVI obs file (AVIRIS-NG/-3), a Sentinel-2 "
                      "MTD_TL.xml, a Landsat C2 angle band (…_SZA.TIF), a NEON AOP reflectance .h5, an "
                      "EMIT L1B OBS .nc or, for 'solar', a UTC time."),
    click.option("--angle-option", "angle_option", multiple=True, metavar="KEY=VALUE", type=READER_OPTION,
                 help="Option of the angle reader (repeatable), e.g. band=B04, resolution=20, "
                      "ang=LC08_..._ANG.txt."),
)

#: ``--align-classes`` and ``--class-lookup``: a class map on another grid, or with other codes.
class_map_options = _stack(
    click.option("--align-classes", is_flag=True,
                 help="The class map may lie on another grid or CRS: resample it by nearest neighbour."),
    click.option("--class-lookup", type=click.Path(dir_okay=False, path_type=Path),
                 help="YAML mapping of class-map codes to table class ids (e.g. land-cover codes)."),
)

#: ``--scale`` and ``--offset``: stored values to reflectance factors, applied on read.
scale_options = _stack(
    click.option("--scale", type=click.FloatRange(min=0, min_open=True),
                 help="Reflectance factor per stored unit, e.g. 0.0001 for 0-10000, applied on read "
                      "[default: the image's GDAL scale, else 1]; replaces a tagged scale."),
    click.option("--offset", type=float,
                 help="Reflectance factor of a stored 0, e.g. -0.2 for Landsat C2 L2 [default: the "
                      "image's GDAL offset, else 0]."),
)


#: ``--prior`` and ``--prior-spread``: a coefficient set's kernel shape as the prior of a fit.
prior_options = _stack(
    click.option("--prior", metavar="SET",
                 help="Built-in coefficient set (brdfcorr coefficients: roy2016, roy2017) whose kernel shape "
                      "(f_vol/f_iso, f_geo/f_iso) is a prior of the fitted ross_thick_li_sparse classes: each "
                      "band's weights become their posterior (docs/parameter-tables.md) [default: none]."),
    click.option("--prior-spread", type=click.FloatRange(min=0.0, min_open=True),
                 help="With --prior: its 1-sigma of either ratio; smaller trusts the prior more [default: 0.2]."),
)


#: ``--block-size`` of ``assess`` and ``assess-lines``: the blocks of the slopes' 1-sigma.
slope_block_option = click.option(
    "--block-size", type=click.IntRange(min=1, max=MAX_BLOCK_SIZE), default=32, show_default=True,
    help="Side [pixels] of the square blocks the slopes' 1-sigma is cluster-robust over (pixels of a block may "
         "share their errors: a field, a roof); the 1-sigma over blocks twice as large is reported too, with a "
         "warning where it is more than 1.25x larger (errors correlated beyond the blocks).")


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
    """--ref-sza: a zenith [deg] or 'mean' / 'observed' / 'hls' (validated by ReferenceGeometry)."""
    if value is None or value in ("mean", "observed", "hls"):
        return value
    try:
        return float(value)
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a number, 'mean', 'observed' or 'hls'") from None
