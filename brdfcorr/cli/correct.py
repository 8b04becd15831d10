"""``brdfcorr correct``: normalize one image (library: :func:`brdfcorr.tasks.correct.correct_files`)."""

from __future__ import annotations

import contextlib
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import click
import click.shell_completion

from brdfcorr.cli._base import CHUNK_SIZE, _options, handle_errors, main, progress_bars
from brdfcorr.cli._inputs import angle_source_options, class_map_options, reference_sza, scale_options
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import BrdfcorrWarning, UnknownNameError
from brdfcorr.io import FORMATS

if TYPE_CHECKING:
    from brdfcorr.tasks.correct import Terrain

# The library (dask, rasterio, scipy) is imported when the command runs, not when its options are
# parsed: --help and argument errors answer at once.


class _ClassMaterial(click.ParamType):
    """``--material ID=NAME``: a class id and a built-in material, as a parameter table class."""

    name = "ID=MATERIAL"

    def shell_complete(self, ctx, param, incomplete):
        from brdfcorr.models.materials import material_names

        key, separator, text = incomplete.partition("=")
        if not separator:
            return []
        return [click.shell_completion.CompletionItem(f"{key}={name}")
                for name in material_names() if name.startswith(text)]

    def convert(self, value, param, ctx):
        from brdfcorr.models.materials import load_material
        from brdfcorr.params import ClassEntry

        if isinstance(value, ClassEntry):
            return value
        key, separator, name = str(value).partition("=")
        if not separator or not key.strip().isdigit() or int(key) < 1 or not name.strip():
            self.fail(f"{value!r}: expected CLASS_ID=MATERIAL, e.g. 1=roof_tile", param, ctx)
        try:
            load_material(name.strip())
        except UnknownNameError as error:
            self.fail(str(error), param, ctx)
        return ClassEntry(id=int(key), material=name.strip())


def _show_warnings(caught: list[warnings.WarningMessage]) -> None:
    """brdfcorr's own warnings as ``brdfcorr: warning:`` lines; others (--debug) as Python shows them."""
    for warning in caught:
        if issubclass(warning.category, BrdfcorrWarning):
            click.echo(f"brdfcorr: warning: {warning.message}", err=True)
        else:
            warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)


def _cluster(address: str | None):
    """The client of the dask.distributed scheduler at ``address`` (None: this machine's threads)."""
    if not address:
        return contextlib.nullcontext(None)
    from brdfcorr.io.cluster import connect_cluster  # imported only for a cluster

    return connect_cluster(address, setting="--scheduler")


def _parameter_table(params_path: Path | None):
    """The table of --params: a YAML file, or where no such file exists a built-in coefficient set
    (:mod:`brdfcorr.models.coefficients`) as class 1 (:func:`brdfcorr.params.as_parameter_table`)."""
    from brdfcorr.params import ParameterTable, as_parameter_table

    if params_path is None:
        return ParameterTable()
    return as_parameter_table(params_path, argument="--params")


def _terrain(slope_aspect, dem, topographic, brdf_frame) -> Terrain | None:
    """The tilted-surface options as a :class:`Terrain` (None without --slope-aspect or --dem)."""
    from brdfcorr.correction.topographic import C_METHODS
    from brdfcorr.tasks.correct import Terrain
    if slope_aspect is None and dem is None:
        if topographic is not None or brdf_frame is not None:
            raise click.UsageError("--topographic and --brdf-frame need --slope-aspect or --dem")
        return None
    topographic = topographic or "cosine"
    brdf_frame = brdf_frame or ("horizontal" if topographic in C_METHODS else "surface")
    return Terrain(slope_aspect=slope_aspect, dem=dem, topographic=topographic, brdf_frame=brdf_frame)


@main.command("correct")
@click.argument("image", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--angles", help="Angle source: a 4-band raster of sza, saa, vza, vaa [deg] on the image grid, or "
                                "what --angles-kind names (a sensor file, or a UTC time for 'solar').")
@angle_source_options
@click.option("--sza", type=click.Path(dir_okay=False, path_type=Path), help="Solar zenith raster [deg].")
@click.option("--saa", type=click.Path(dir_okay=False, path_type=Path), help="Solar azimuth raster [deg].")
@click.option("--vza", type=click.Path(dir_okay=False, path_type=Path), help="View zenith raster [deg].")
@click.option("--vaa", type=click.Path(dir_okay=False, path_type=Path), help="View azimuth raster [deg].")
@click.option("--raa", type=click.Path(dir_okay=False, path_type=Path),
              help="Relative azimuth raster [deg], vaa - saa (0 at the hotspot), with --sza and --vza, for "
                   "products that give no absolute azimuths (MODIS, VIIRS).")
@click.option("--classes", type=click.Path(dir_okay=False, path_type=Path),
              help="Class map raster (ids of the parameter table; 0 = no class) [default: none, the whole image "
                   "is class 1].")
@class_map_options
@click.option("--params", "params_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Parameter table (YAML), or a built-in coefficient set (brdfcorr coefficients: roy2016, "
                   "roy2017) as class 1; optional with --material.")
@click.option("--material", "materials", multiple=True, type=_ClassMaterial(),
              help="Class ID takes a built-in material (brdfcorr materials; a fit at 550 nm), over "
                   "--params' class of that id; repeatable, the last wins for an id.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Output raster (.tif for GTiff; .img, .bsq, .bil, .dat or no extension for ENVI).")
@click.option("--format", "output_format", type=click.Choice(FORMATS), default="GTiff", show_default=True,
              help="Output format; ENVI writes the data file, a .hdr header (wavelengths, map info) and "
                   ".aux.xml (tags). The QA layer is always a GeoTIFF.")
@click.option("--output-type", type=click.Choice(["float", "input"]), default="float", show_default=True,
              help="float: reflectance factors as float32; input: an integer input's own type (up to 32 bits; "
                   "64-bit integers are refused), scale, offset and nodata (smaller files; values that do not fit "
                   "are nodata and flagged).")
@click.option("--interleave", type=click.Choice(["bsq", "bil"], case_sensitive=False), default="bsq",
              show_default=True, help="Interleave of an ENVI output.")
@click.option("--ref-sza", help="Reference sun zenith [deg], 'mean', 'observed' or 'hls' (HLS v1.4's for the "
                                "scene's latitude) [default: table, else observed].")
@click.option("--ref-vza", type=float, help="Reference view zenith [deg] [default: table, else 0].")
@click.option("--ref-raa", type=float, help="Reference relative azimuth [deg] [default: table, else 0].")
@click.option("--limits", nargs=2, type=float, default=DEFAULT_LIMITS, show_default=True,
              help="Lower and upper limit of the correction factor.")
@click.option("--no-limits", is_flag=True, help="Do not limit the correction factor.")
@click.option("--unknown", type=click.Choice(["keep", "nan"]), default="keep", show_default=True,
              help="Pixels of class 0 or of classes not in the table: keep unchanged, or set to NaN.")
@click.option("--wavelengths", help="Band centres [nm], comma-separated (overrides the image's).")
@scale_options
@click.option("--extrapolate", is_flag=True, help="Allow band centres outside a class's table wavelengths.")
@click.option("--flip-view-azimuth", is_flag=True,
              help="View azimuths are stored as seen from the sensor: add 180 deg.")
@click.option("--factor-at", type=click.Choice(["pixels", "nodes"]), default="pixels", show_default=True,
              help="Evaluate the factor at every pixel, or at the nodes of the sensor's coarse angle grid "
                   "(--angles-kind sentinel2) and interpolate it to the pixels: sen2nbar's method, faster; one "
                   "class, no --classes, --dem, --slope-aspect or --uncertainty.")
@click.option("--qa", "qa_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the QA flags (uint8) to this GeoTIFF.")
@click.option("--compress", default="deflate", show_default=True, help="GDAL compression.")
@click.option("--cog", is_flag=True, help="Write Cloud-Optimized GeoTIFFs.")
@click.option("--chunk", type=CHUNK_SIZE,
              help="Chunk and tile size [pixels], a multiple of 16 [default: the largest multiple of the "
                   "image's tiles with at most 16 MiB of all bands as float32, else 512, 256, 128 or 64].")
@click.option("--progress/--no-progress", default=None, help="Progress bar [default: on a terminal].")
@click.option("--overwrite", is_flag=True, help="Replace existing outputs (-o, --qa) [default: refuse].")
@click.option("--scheduler", metavar="ADDRESS", envvar="DASK_SCHEDULER_ADDRESS", show_envvar=True,
              help="Address of a dask.distributed scheduler (tcp://host:8786): spread the scene chunk by chunk "
                   "over all its workers, which need the file system of the inputs and outputs [default: all "
                   "cores of this machine].")
@click.option("--uncertainty", "uncertainty_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the per-pixel 1-sigma of the corrected reflectance (from the table's fit: "
                   "covariances; NaN for classes without one) to this GeoTIFF.")
@click.option("--slope-aspect", type=click.Path(dir_okay=False, path_type=Path),
              help="Tilted surfaces: a 2-band raster of slope and aspect [deg] on the image grid, or an ENVI "
                   "obs_ort file (bands Slope, Aspect).")
@click.option("--dem", type=click.Path(dir_okay=False, path_type=Path),
              help="Tilted surfaces: a DEM/DSM [m] on the image grid (projected CRS; its pixel size in the CRS's "
                   "unit, e.g. US survey feet, is converted to metres); slope and aspect by Horn's differences.")
@click.option("--topographic", type=click.Choice(["cosine", "c", "scs", "scs+c", "none"]), default=None,
              help="Illumination correction before the BRDF step, with --slope-aspect or --dem [default: cosine].")
@click.option("--brdf-frame", type=click.Choice(["surface", "horizontal"]), default=None,
              help="Evaluate the BRDF in each tilted surface's frame or the horizontal one [default: surface; "
                   "horizontal for c and scs+c].")
@handle_errors
def correct_command(image, angles, angles_kind, angle_option, sza, saa, vza, vaa, raa, classes, align_classes,
                    class_lookup, params_path, materials, output, ref_sza, ref_vza,
                    ref_raa, limits, no_limits, unknown, wavelengths, scale, offset, extrapolate,
                    flip_view_azimuth, factor_at, qa_path, compress, cog, chunk, progress, overwrite, output_format,
                    interleave, output_type, scheduler, uncertainty_path, slope_aspect, dem, topographic, brdf_frame):
    """Normalize IMAGE to a reference sun/view geometry with per-class BRDF models.

    IMAGE's stored values are read as reflectance factors with its GDAL scale/offset, or --scale
    and --offset; an image that still looks like raw counts is refused unless --scale is given.
    Outputs are written to temporary names beside them and renamed when complete; an existing
    output is replaced only with --overwrite, and an input never.

    Classes come from --params, and from --material ID=NAME (a built-in material, over the
    table's class of that id); a material applied to bands more than 100 nm from its fit's
    wavelength (550 nm) is warned about once per class.
    """
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.classmaps import read_lookup
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles

    if params_path is None and not materials:
        raise click.UsageError("give a parameter table (--params) or at least one --material")
    table = _parameter_table(params_path)
    for entry in materials:
        table = table.with_class(entry)
    reference = table.reference.model_dump() if table.reference else {}
    for key, value in (("sza", reference_sza(ref_sza)), ("vza", ref_vza), ("raa", ref_raa)):
        if value is not None:
            reference[key] = value
    if wavelengths is not None:
        try:
            wavelengths = [float(value) for value in wavelengths.split(",")]
        except ValueError:
            raise click.BadParameter(f"{wavelengths!r} is not a comma-separated list of numbers",
                                     param_hint="--wavelengths") from None
    source = " ".join([str(params_path)] * (params_path is not None)
                      + [f"--material {entry.id}={entry.material}" for entry in materials])
    start = time.perf_counter()
    sources = SceneSources(image, classes, angles, angles_kind=angles_kind,
                           angle_options=_options("--angle-option", angle_option), sza=sza, saa=saa, vza=vza,
                           vaa=vaa, raa=raa, wavelengths=wavelengths, scale=scale, offset=offset)
    outputs = OutputFiles(output, qa=qa_path, uncertainty=uncertainty_path, format=output_format,
                          interleave=interleave.lower(), data_type=output_type, compress=compress, cog=cog,
                          overwrite=overwrite)
    terrain = _terrain(slope_aspect, dem, topographic, brdf_frame)
    lookup = read_lookup(class_lookup) if class_lookup else None
    # The bar runs from the first pass (the angle and scale checks) to the write.
    with _cluster(scheduler) as client, warnings.catch_warnings(record=True) as caught, \
            progress_bars(progress, "correct"):
        warnings.simplefilter("always", BrdfcorrWarning)  # each class's caveat, however often run
        try:
            summary = correct_files(CorrectionRequest(
                sources, table, outputs, reference=reference, limits=None if no_limits else limits,
                extrapolate=extrapolate, unknown=unknown, flip_view_azimuth=flip_view_azimuth, terrain=terrain,
                factor_at=factor_at,
                align_classes=align_classes, class_lookup=lookup,
                engine=Engine(chunks=chunk, scheduler=client), table_source=source,
                reads={"--params": params_path if params_path is None or params_path.exists() else None,
                       "--class-lookup": class_lookup},  # never overwritten either
            ))
        finally:  # shown also when the correction then fails
            _show_warnings(caught)
    counts = summary.counts
    click.echo(
        f"wrote {output}: {counts['corrected']} pixels corrected, {counts['limited']} limited, "
        f"{counts['unknown_class']} unknown class, {counts['no_class']} no class, "
        f"{counts['nodata']} nodata ({summary.reference.describe()}) in "
        f"{time.perf_counter() - start:.1f} s"
    )
    topographic = summary.topographic
    if topographic is not None:
        rows, rejected = topographic.c, topographic.rejected
        click.echo(f"topographic correction {topographic.method}: "
                   f"{len(rows) - rejected} class-band C fits used, {rejected} rejected (flagged)" if rows else
                   f"topographic correction {topographic.method}")


