"""``brdfcorr correct``: normalize one image (library: :func:`brdfcorr.workflow.tasks.correct_files`)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click
from tqdm.dask import TqdmCallback

from brdfcorr.cli._base import _options, handle_errors, main
from brdfcorr.cli._inputs import angle_source_options, class_map_options, scale_options
from brdfcorr.io.writer import FORMATS
from brdfcorr.params import ParameterTable
from brdfcorr.workflow.classmaps import read_lookup
from brdfcorr.workflow.tasks import correct_files


def _reference_sza(value: str | None):
    """--ref-sza: a zenith [deg] or 'mean' / 'observed' (validated by ReferenceGeometry)."""
    if value is None or value in ("mean", "observed"):
        return value
    try:
        return float(value)
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a number, 'mean' or 'observed'") from None


@main.command("correct")
@click.argument("image", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--angles", help="Angle source: a 4-band raster of sza, saa, vza, vaa [deg] on the image grid, or "
                                "what --angles-kind names (a sensor file, or a UTC time for 'solar').")
@angle_source_options
@click.option("--sza", type=click.Path(dir_okay=False, path_type=Path), help="Solar zenith raster [deg].")
@click.option("--saa", type=click.Path(dir_okay=False, path_type=Path), help="Solar azimuth raster [deg].")
@click.option("--vza", type=click.Path(dir_okay=False, path_type=Path), help="View zenith raster [deg].")
@click.option("--vaa", type=click.Path(dir_okay=False, path_type=Path), help="View azimuth raster [deg].")
@click.option("--classes", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Class map raster (ids of the parameter table; 0 = no class).")
@class_map_options
@click.option("--params", "params_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Parameter table (YAML).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Output raster (.tif for GTiff; .img, .bsq, .bil, .dat or no extension for ENVI).")
@click.option("--format", "output_format", type=click.Choice(FORMATS), default="GTiff", show_default=True,
              help="Output format; ENVI writes the data file, a .hdr header (wavelengths, map info) and "
                   ".aux.xml (tags). The QA layer is always a GeoTIFF.")
@click.option("--interleave", type=click.Choice(["bsq", "bil"], case_sensitive=False), default="bsq",
              show_default=True, help="Interleave of an ENVI output.")
@click.option("--ref-sza", help="Reference sun zenith [deg], 'mean' or 'observed' [default: table, else observed].")
@click.option("--ref-vza", type=float, help="Reference view zenith [deg] [default: table, else 0].")
@click.option("--ref-raa", type=float, help="Reference relative azimuth [deg] [default: table, else 0].")
@click.option("--limits", nargs=2, type=float, default=(0.2, 5.0), show_default=True,
              help="Lower and upper limit of the correction factor.")
@click.option("--no-limits", is_flag=True, help="Do not limit the correction factor.")
@click.option("--unknown", type=click.Choice(["keep", "nan"]), default="keep", show_default=True,
              help="Pixels of class 0 or of classes not in the table: keep unchanged, or set to NaN.")
@click.option("--wavelengths", help="Band centres [nm], comma-separated (overrides the image's).")
@scale_options
@click.option("--extrapolate", is_flag=True, help="Allow band centres outside a class's table wavelengths.")
@click.option("--flip-view-azimuth", is_flag=True,
              help="View azimuths are stored as seen from the sensor: add 180 deg.")
@click.option("--qa", "qa_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the QA flags (uint8) to this GeoTIFF.")
@click.option("--compress", default="deflate", show_default=True, help="GDAL compression.")
@click.option("--cog", is_flag=True, help="Write Cloud-Optimized GeoTIFFs.")
@click.option("--chunk", type=int, help="Chunk and tile size [pixels] [default: 512, less for many bands].")
@click.option("--progress/--no-progress", default=None, help="Progress bar [default: on a terminal].")
@click.option("--overwrite", is_flag=True, help="Replace existing outputs (-o, --qa) [default: refuse].")
@handle_errors
def correct_command(image, angles, angles_kind, angle_option, sza, saa, vza, vaa, classes, align_classes,
                    class_lookup, params_path, output, ref_sza, ref_vza,
                    ref_raa, limits, no_limits, unknown, wavelengths, scale, offset, extrapolate,
                    flip_view_azimuth, qa_path, compress, cog, chunk, progress, overwrite, output_format,
                    interleave):
    """Normalize IMAGE to a reference sun/view geometry with per-class BRDF models.

    IMAGE's stored values are read as reflectance factors with its GDAL scale/offset, or --scale
    and --offset; an image that still looks like raw counts is refused unless --scale is given.
    Outputs are written to temporary names beside them and renamed when complete; an existing
    output is replaced only with --overwrite, and an input never.
    """
    table = ParameterTable.load(params_path)
    reference = table.reference.model_dump() if table.reference else {}
    for key, value in (("sza", _reference_sza(ref_sza)), ("vza", ref_vza), ("raa", ref_raa)):
        if value is not None:
            reference[key] = value
    if wavelengths is not None:
        try:
            wavelengths = [float(value) for value in wavelengths.split(",")]
        except ValueError:
            raise click.BadParameter(f"{wavelengths!r} is not a comma-separated list of numbers",
                                     param_hint="--wavelengths") from None
    if progress is None:
        progress = sys.stderr.isatty()
    callbacks = [TqdmCallback(desc="correct", leave=False)] if progress else []
    start = time.perf_counter()
    summary = correct_files(
        image, output, params=table, angles=angles, sza=sza, saa=saa, vza=vza, vaa=vaa,
        classes=classes, reference=reference, qa_output=qa_path, wavelengths=wavelengths,
        extrapolate=extrapolate, limits=None if no_limits else limits, unknown=unknown,
        flip_view_azimuth=flip_view_azimuth, chunks=chunk, compress=compress, cog=cog,
        callbacks=callbacks, table_source=str(params_path), angles_kind=angles_kind,
        angle_options=_options("--angle-option", angle_option), overwrite=overwrite,
        align_classes=align_classes, class_lookup=read_lookup(class_lookup) if class_lookup else None,
        scale=scale, offset=offset, output_format=output_format, interleave=interleave.lower(),
        reads={"--params": params_path, "--class-lookup": class_lookup},  # never overwritten either
    )
    click.echo(
        f"wrote {output}: {summary['corrected']} pixels corrected, {summary['limited']} limited, "
        f"{summary['unknown_class']} unknown class, {summary['no_class']} no class, "
        f"{summary['nodata']} nodata ({summary['reference'].describe()}) in "
        f"{time.perf_counter() - start:.1f} s"
    )


