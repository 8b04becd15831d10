"""``brdfcorr classes ndvi`` / ``brdfcorr classes align``: class maps when the user has none, or
has one on another grid (library: :mod:`brdfcorr.tasks.classmaps`)."""

from __future__ import annotations

from pathlib import Path

import click

from brdfcorr.cli._base import PROGRESS, _format_table, handle_errors, main, progress_bars
from brdfcorr.cli._inputs import scale_options

# brdfcorr.tasks.classmaps (rasterio, dask) is imported when a command runs, not when its options
# are parsed: --help and argument errors answer at once.


def _numbers(value: str | None) -> list[float] | None:
    if value is None:
        return None
    try:
        return [float(part) for part in value.split(",")]
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a comma-separated list of numbers") from None


@main.group("classes")
def classes_group():
    """Make class maps: NDVI strata of an image, or a land-cover map brought onto its grid."""


@classes_group.command("ndvi")
@click.argument("image", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Class map GeoTIFF to write (uint8; 0 = no class).")
@click.option("--edges", help="NDVI bin edges, comma-separated [default: 0.1,0.3,0.5,0.7].")
@click.option("--percentiles", help="Scene NDVI percentiles as edges instead, e.g. 20,40,60,80.")
@click.option("--water-id", type=int, default=0, show_default=True, help="Class of water pixels (0: no class).")
@click.option("--shadow-id", type=int, default=0, show_default=True, help="Class of shadow pixels (0: no class).")
@click.option("--wavelengths", help="Band centres [nm], comma-separated (overrides the image's).")
@scale_options
@click.option("--overwrite", is_flag=True, help="Replace an existing output.")
@PROGRESS
@handle_errors
def classes_ndvi_command(image, output, edges, percentiles, water_id, shadow_id, wavelengths, scale, offset,
                         overwrite, progress):
    """Classes of IMAGE by NDVI bins (strata for per-class kernel-model fits), water and shadow masked.

    IMAGE's stored values are read as reflectance factors with its GDAL scale/offset, or --scale
    and --offset (an offset changes NDVI); an image that does not look like reflectance factors
    is refused unless --scale is given."""
    from brdfcorr.tasks.classmaps import NdviBins, ndvi_class_file

    bins = NdviBins(edges=_numbers(edges), percentiles=_numbers(percentiles), water_id=water_id, shadow_id=shadow_id)
    with progress_bars(progress, "classes ndvi"):  # the scale check, the percentiles, the write
        strata = ndvi_class_file(image, output, bins=bins, wavelengths=_numbers(wavelengths), scale=scale,
                                 offset=offset, overwrite=overwrite)
    click.echo(_format_table([{"class": str(ident), "stratum": name} for ident, name in sorted(strata.names.items())]))
    click.echo(f"wrote {output} (NDVI edges {', '.join(f'{edge:.3g}' for edge in strata.edges)})")


@classes_group.command("align")
@click.argument("landcover", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--like", "image", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The image whose grid the class map is brought onto.")
@click.option("--lookup", type=click.Path(dir_okay=False, path_type=Path),
              help="YAML mapping of land-cover codes to table class ids (e.g. '10: 3').")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Class map GeoTIFF to write.")
@click.option("--overwrite", is_flag=True, help="Replace an existing output.")
@handle_errors
def classes_align_command(landcover, image, lookup, output, overwrite):
    """Bring LANDCOVER (any grid and CRS) onto the grid of an image by nearest neighbour."""
    from brdfcorr.tasks.classmaps import align_class_file, read_lookup

    aligned = align_class_file(landcover, image, output, lookup=read_lookup(lookup) if lookup else None,
                               overwrite=overwrite, reads={"--lookup": lookup})
    click.echo(f"wrote {output} ({aligned.attrs.get('resampled_from_crs', '')} -> {aligned.rio.crs})")
