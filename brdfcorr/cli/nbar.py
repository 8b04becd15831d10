"""``brdfcorr nbar``: NBAR of a product folder (library: :func:`brdfcorr.tasks.nbar.nbar_files`)."""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import click

from brdfcorr.cli._base import handle_errors, main, progress_bars
from brdfcorr.cli._inputs import reference_sza
from brdfcorr.cli._settings import setting_options
from brdfcorr.errors import BrdfcorrWarning
from brdfcorr.tasks.options import NBAR

# The library (dask, rasterio, scipy) is imported when the command runs, not when its options are
# parsed: --help and argument errors answer at once.


@main.command("nbar")
@click.argument("product", type=click.Path(path_type=Path))
@setting_options(NBAR)
@handle_errors
def nbar_command(product, output, qa_path, resolution, bands, coefficients, ref_sza, view_band, factor_at,
                 keep_stack, keep_clouds, compress, cog, chunk, progress, overwrite):
    """NBAR of a Sentinel-2 L2A SAFE or Landsat Collection-2 L2 folder with built-in coefficients.

    PRODUCT is a Sentinel-2 L2A .SAFE folder (bands from IMG_DATA, angles from the granule's
    MTD_TL.xml, scaling from MTD_MSIL2A.xml, clouds from the SCL) or a Landsat Collection-2
    Level-2 folder (SR_B* bands, QA_PIXEL, angles from the angle bands or the ANG.txt), or a
    Sentinel-2 STAC item (.json) whose assets are local files. An HLS
    S30/L30 granule is NBAR already: it is only moved to another sun zenith (--ref-sza DEG). Every
    pixel is normalized to nadir view with the published global RTLSR coefficients of its band
    (Roy et al. 2016, 2017): the c-factor method of HLS and sen2nbar.
    """
    from brdfcorr.tasks.nbar import NbarMethod, nbar_files
    from brdfcorr.tasks.request import Engine, OutputFiles

    band_list = [name.strip() for name in bands.split(",") if name.strip()] if bands else None
    outputs = OutputFiles(output, qa=qa_path, compress=compress, cog=cog, overwrite=overwrite)
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught, progress_bars(progress, "nbar"):
        warnings.simplefilter("always", BrdfcorrWarning)
        try:
            summary = nbar_files(product, outputs, resolution=int(resolution) if resolution else None,
                                 bands=band_list, masked=() if keep_clouds else None,
                                 method=NbarMethod(coefficients, reference_sza(ref_sza), view_band, factor_at),
                                 keep_stack=keep_stack, engine=Engine(chunks=chunk))
        finally:
            for warning in caught:
                if issubclass(warning.category, BrdfcorrWarning):
                    click.echo(f"brdfcorr: warning: {warning.message}", err=True)
    folder, counts = summary.product, summary.counts
    click.echo(
        f"wrote {output}: {', '.join(folder.bands)} at {folder.resolution:g} m, {counts['corrected']} pixels "
        f"corrected, {counts['limited']} limited, {counts['nodata']} nodata or masked "
        f"({summary.reference.describe()}) in {time.perf_counter() - start:.1f} s"
    )
