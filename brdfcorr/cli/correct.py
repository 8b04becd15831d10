"""``brdfcorr correct``: normalize one image (library: :func:`brdfcorr.tasks.correct.correct_files`)."""

from __future__ import annotations

import contextlib
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import click
import click.shell_completion

from brdfcorr.cli._base import handle_errors, main, progress_bars
from brdfcorr.cli._inputs import reference_sza
from brdfcorr.cli._settings import setting_options
from brdfcorr.defaults import C_METHODS
from brdfcorr.errors import BrdfcorrWarning, UnknownNameError
from brdfcorr.tasks.options import CORRECT

if TYPE_CHECKING:
    from brdfcorr.tasks.request import Terrain

# The library (dask, rasterio, scipy) is imported when the command runs, not when its options are
# parsed: --help and argument errors answer at once.


class _ClassMaterial(click.ParamType):
    """``--material ID=NAME``: a class id and a built-in material, converted to ``(id, name)``."""

    name = "ID=MATERIAL"
    pairs = True

    def shell_complete(self, ctx, param, incomplete):
        from brdfcorr.models.materials import material_names

        key, separator, text = incomplete.partition("=")
        if not separator:
            return []
        return [click.shell_completion.CompletionItem(f"{key}={name}")
                for name in material_names() if name.startswith(text)]

    def convert(self, value, param, ctx):
        from brdfcorr.models.materials import load_material

        if isinstance(value, tuple):
            return value
        key, separator, name = str(value).partition("=")
        if not separator or not key.strip().isdigit() or int(key) < 1 or not name.strip():
            self.fail(f"{value!r}: expected CLASS_ID=MATERIAL, e.g. 1=roof_tile", param, ctx)
        try:
            load_material(name.strip())
        except UnknownNameError as error:
            self.fail(str(error), param, ctx)
        return int(key), name.strip()


def _show_warnings(caught: list[warnings.WarningMessage]) -> None:
    """brdfcorr's own warnings as ``brdfcorr: warning:`` lines; others (--debug) as Python formats
    them, written to stderr: ``warnings.showwarning`` inside the recording block appended each to
    ``caught`` again, an endless loop until memory ran out."""
    for warning in list(caught):
        if issubclass(warning.category, BrdfcorrWarning):
            click.echo(f"brdfcorr: warning: {warning.message}", err=True)
        else:
            click.echo(warnings.formatwarning(warning.message, warning.category, warning.filename, warning.lineno),
                       err=True, nl=False)


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
    from brdfcorr.tasks.request import Terrain
    if slope_aspect is None and dem is None:
        if topographic is not None or brdf_frame is not None:
            raise click.UsageError("--topographic and --brdf-frame need --slope-aspect or --dem")
        return None
    topographic = topographic or CORRECT.default("topographic")
    brdf_frame = brdf_frame or ("horizontal" if topographic in C_METHODS else CORRECT.default("brdf_frame"))
    return Terrain(slope_aspect=slope_aspect, dem=dem, topographic=topographic, brdf_frame=brdf_frame)


@main.command("correct")
@click.argument("image", type=click.Path(path_type=Path))
@setting_options(CORRECT, {"material": _ClassMaterial()})
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

    IMAGE may be a product folder (Sentinel-2 L2A SAFE, Landsat Collection-2 L2, a Sentinel-2 STAC
    item with local assets, as brdfcorr nbar reads it): its bands, scaling, masks and angles come
    from the product, e.g. one date of a series corrected with the table brdfcorr fit-classes
    fitted over all the dates.
    """
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.params import ClassEntry
    from brdfcorr.tasks.classmaps import read_lookup
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles

    if params_path is None and not materials:
        raise click.UsageError("give a parameter table (--params) or at least one --material")
    table = _parameter_table(params_path)
    for class_id, name in materials:
        table = table.with_class(ClassEntry(id=class_id, material=name))
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
                      + [f"--material {class_id}={name}" for class_id, name in materials])
    start = time.perf_counter()
    outputs = OutputFiles(output, qa=qa_path, uncertainty=uncertainty_path, format=output_format,
                          interleave=interleave.lower(), data_type=output_type, compress=compress, cog=cog,
                          overwrite=overwrite)
    terrain = _terrain(slope_aspect, dem, topographic, brdf_frame)
    lookup = read_lookup(class_lookup) if class_lookup else None
    # The products are stacked last: nothing that may fail stands between the stack and its with block.
    scratch, product_reads = contextlib.ExitStack(), {}
    from brdfcorr.io.sensors.inputs import products_among
    from brdfcorr.tasks.series import find_products, product_files, stacked_products

    if products_among([image], {"--angles": angles, "--angle-option": angle_option, "--sza": sza, "--saa": saa,
                           "--vza": vza, "--vaa": vaa, "--raa": raa, "--wavelengths": wavelengths,
                           "--scale": scale, "--offset": offset, "--angles-kind": angles_kind != "geotiff"}):
        products = find_products([image])  # identified once: the output guard and the stack use it
        product_reads = dict(product_files(products))  # the output guard's inputs, as fit-classes'
        [found] = scratch.enter_context(stacked_products(products, **({"chunks": chunk} if chunk else {})))
        sources = SceneSources(classes=classes, **found)
    else:
        sources = SceneSources(image, classes, angles, angles_kind=angles_kind,
                               angle_options=dict(angle_option), sza=sza, saa=saa, vza=vza,
                               vaa=vaa, raa=raa, wavelengths=wavelengths, scale=scale, offset=offset)
    # The bar runs from the first pass (the angle and scale checks) to the write.
    with scratch, _cluster(scheduler) as client, warnings.catch_warnings(record=True) as caught, \
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
                       "--class-lookup": class_lookup, **product_reads},  # never overwritten either
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


