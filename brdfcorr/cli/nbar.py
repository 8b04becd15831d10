"""``brdfcorr nbar``: NBAR of a product folder (library: :func:`brdfcorr.tasks.nbar.nbar_files`)."""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import click

from brdfcorr.cli._base import CHUNK_SIZE, PROGRESS, handle_errors, main, progress_bars
from brdfcorr.cli._inputs import reference_sza
from brdfcorr.errors import BrdfcorrWarning

# The library (dask, rasterio, scipy) is imported when the command runs, not when its options are
# parsed: --help and argument errors answer at once.


@main.command("nbar")
@click.argument("product", type=click.Path(path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Output GeoTIFF: NBAR reflectance factors (float32), the product's bands in its order.")
@click.option("--qa", "qa_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the QA flags (uint8) to this GeoTIFF.")
@click.option("--resolution", type=click.Choice(["10", "20"]), default=None,
              help="Sentinel-2 output pixel size [m]; other bands are resampled onto it [default: 20].")
@click.option("--bands", help="Band names in output order, comma-separated (B04,B8A or SR_B4,SR_B5) "
                              "[default: every band with coefficients].")
@click.option("--coefficients", default="roy2017", show_default=True,
              help="Built-in coefficient set (brdfcorr coefficients): roy2017, or roy2016 (no red-edge bands).")
@click.option("--ref-sza", default="mean", show_default=True,
              help="Reference sun zenith [deg], 'mean' (the scene's), 'hls' (HLS v1.4's for the scene centre's "
                   "latitude) or 'observed' (each pixel's, as sen2nbar). The reference view is nadir.")
@click.option("--view-band", help="Sentinel-2: the view angles of this band's grids (e.g. B04) for every band, or "
                                  "'each': every band its own (as sen2nbar; one correction per band, slower) "
                                  "[default: the mean of all bands' grids].")
@click.option("--factor-at", type=click.Choice(["pixels", "nodes"]), default="pixels", show_default=True,
              help="Sentinel-2: evaluate the c-factor at every pixel, or at the 5 km nodes of the angle grids and "
                   "interpolate it to the pixels (sen2nbar's method, faster), except where the view azimuth jumps "
                   "between nodes (within 0.15 %).")
@click.option("--keep-stack", type=click.Path(dir_okay=False, path_type=Path),
              help="Also keep the uncorrected bands as a small virtual raster (.vrt) reading the product's files, "
                   "masked and scaled: e.g. BEFORE for brdfcorr assess.")
@click.option("--keep-clouds", is_flag=True,
              help="Correct cloudy, shadowed and saturated pixels too (only the product's fill is no data).")
@click.option("--compress", default="deflate", show_default=True, help="GDAL compression.")
@click.option("--cog", is_flag=True, help="Write Cloud-Optimized GeoTIFFs.")
@click.option("--chunk", type=CHUNK_SIZE, help="Chunk and tile size [pixels], a multiple of 16 [default: 512].")
@PROGRESS
@click.option("--overwrite", is_flag=True, help="Replace existing outputs (-o, --qa) [default: refuse].")
@handle_errors
def nbar_command(product, output, qa_path, resolution, bands, coefficients, ref_sza, view_band, factor_at,
                 keep_stack, keep_clouds, compress, cog, chunk, progress, overwrite):
    """NBAR of a Sentinel-2 L2A SAFE or Landsat Collection-2 L2 folder with built-in coefficients.

    PRODUCT is a Sentinel-2 L2A .SAFE folder (bands from IMG_DATA, angles from the granule's
    MTD_TL.xml, scaling from MTD_MSIL2A.xml, clouds from the SCL) or a Landsat Collection-2
    Level-2 folder (SR_B* bands, QA_PIXEL, angles from the angle bands or the ANG.txt). An HLS
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
