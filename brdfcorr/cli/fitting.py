"""``brdfcorr fit`` (goniometer tables) and ``brdfcorr fit-classes`` (imagery)."""

from __future__ import annotations

import contextlib
import json
import math
import textwrap
from pathlib import Path

import click

from brdfcorr.cli._base import (
    FIT_MODEL_CHOICE,
    NAME_RANGE,
    NAME_VALUE,
    PROGRESS,
    _draw_figure,
    _format_table,
    class_bar,
    distinct_names,
    handle_errors,
    main,
    progress_bars,
)
from brdfcorr.cli._inputs import (
    prior_setting,
)
from brdfcorr.cli._settings import setting_options
from brdfcorr.errors import InputError
from brdfcorr.io.files import atomic_paths
from brdfcorr.io.paths import check_outputs, refuse_existing, update_target
from brdfcorr.tasks.options import FIT_CLASSES

# The library (scipy, dask, rasterio, matplotlib) is imported when a command runs, not when its
# options are parsed: --help and argument errors answer at once. --model is checked against the
# registry's names in brdfcorr.defaults (FIT_MODEL_CHOICE), without importing the models.


class _BandRange(click.ParamType):
    """``--bad-bands``: a wavelength range ``LOW:HIGH`` [nm] with 0 < LOW <= HIGH, or ``none``
    (None: leave no range out)."""

    name = "LOW:HIGH"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple) or value is None:
            return value
        if value.strip().lower() == "none":
            return None
        try:
            low, high = (float(part) for part in value.split(":"))
        except ValueError:
            self.fail(f"{value!r} is not LOW:HIGH in nm (e.g. 1340:1450) or none", param, ctx)
        if not 0 < low <= high < float("inf"):
            self.fail(f"{value!r}: the range must have 0 < LOW <= HIGH [nm]", param, ctx)
        return (low, high)


@main.command("fit-classes")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@setting_options(FIT_CLASSES, {"band_range": _BandRange()})
@handle_errors
def fit_classes_command(images, angles, angles_kind, angle_option, classes, align_classes, class_lookup,
                        model_name, class_model, names, deprecated_names, fix, max_samples, seed,
                        block_size, levels, patch_size, errors_cluster, cluster_layers, cluster_band, scale, offset,
                        flip_view_azimuth, min_samples, min_vza_spread, max_condition,
                        bad_bands, fallback, prior, prior_spread, output, report_path, plot_dir, overwrite, workers,
                        progress):
    """Fit per-class, per-band BRDF parameters from IMAGES themselves (one or many scenes).

    The images' stored values are read as reflectance factors with their GDAL scale/offset, or
    --scale and --offset; an image that still looks like raw counts is refused unless --scale is
    given. Bad bands (water vapour, those the ENVI header's bbl marks) are left out of the fit.

    IMAGES may instead be product folders of one grid, the dates of a time series (Sentinel-2 L2A
    SAFE, Landsat Collection-2 L2, Sentinel-2 STAC items with local assets, as brdfcorr nbar reads
    them): their bands, scaling, masks and angles come from each product (no --angles), and one
    --classes serves every date. The files in the folders are inputs too: never an output.
    """
    from brdfcorr.fit.classes import WATER_VAPOUR_BANDS, ClassModels, GuardRails, Sampling
    from brdfcorr.fit.settings import fallback_entry
    from brdfcorr.io.sensors.inputs import products_among
    from brdfcorr.tasks.classmaps import read_lookup
    from brdfcorr.tasks.fit import SceneFiles, fit_class_files
    from brdfcorr.tasks.series import find_products, product_files, stacked_products

    products = products_among(images, {"--angles": angles, "--angles-kind": angles_kind != "geotiff",
                                       "--angle-option": angle_option, "--scale": scale is not None,
                                       "--offset": offset is not None})
    found = find_products(images) if products else []  # identified once: the output guard and the stacks use them
    if products:
        classes = classes * len(images) if len(classes) == 1 else classes
        angles = tuple(str(image) for image in images)  # the products' own sources, for the checks below
    if not len(images) == len(angles) == len(classes):
        raise InputError(
            f"{len(images)} image(s), {len(angles)} --angles and {len(classes)} --classes: give one "
            "angle raster and one class map per image, in the same order"
        )
    if cluster_layers and len(cluster_layers) != len(images):
        raise InputError(f"{len(images)} image(s) and {len(cluster_layers)} --clusters: give one cluster layer per "
                         "image, in the same order")
    written = {"-o": output, "--report": report_path}
    read = [*(("IMAGES", path) for path in images), *(("--classes", path) for path in classes),
            *(("--angles", path) for path in angles if angles_kind != "solar"), ("--class-lookup", class_lookup),
            *(("--clusters", path) for path in cluster_layers), *product_files(found)]  # a product's files too
    check_outputs(written, read)
    if not overwrite:  # before the stacking and the fit: their work is not wasted on an output that would be refused
        refuse_existing(written.values())
    if fallback:
        fallback_entry(fallback, 1, "check")  # fail before the work if the name is wrong
    shape_prior = prior_setting(prior, prior_spread)
    lookup = read_lookup(class_lookup) if class_lookup else None
    options = dict(angle_option)
    if deprecated_names:
        click.echo("brdfcorr: warning: --name is deprecated; use --class-name ID=NAME", err=True)
    class_names = {**dict(deprecated_names), **dict(names)}
    ranges = WATER_VAPOUR_BANDS if not bad_bands else tuple(item for item in bad_bands if item is not None)
    # One bar over the dask passes (the checks, the class maps, angles and samples read), one over the classes fitted.
    with stacked_products(found) if products else contextlib.nullcontext([]) as stacked, \
            progress_bars(progress, "fit-classes"), class_bar(progress, "fit classes") as fitted:
        files = stacked if products else [
            {"image": image, "angles": angle_source, "angles_kind": angles_kind, "angle_options": options,
             "scale": scale, "offset": offset} for image, angle_source in zip(images, angles)]
        fit = fit_class_files(
            [SceneFiles(classes=class_map, align_classes=align_classes, class_lookup=lookup,
                        clusters=(cluster_layers[index], cluster_band) if cluster_layers else None, **sources)
             for index, (sources, class_map) in enumerate(zip(files, classes))],
            ClassModels(model_name, class_models=dict(class_model),
                        fixed=dict(fix) or None, fallback=fallback, names=class_names,
                        prior=shape_prior),
            sampling=Sampling(max_samples=max_samples, seed=seed, block_size=block_size, bad_bands=ranges,
                              levels=levels, patch_size=patch_size, errors_cluster=errors_cluster,
                              flip_view_azimuth=flip_view_azimuth),
            guard=GuardRails(min_samples=min_samples, min_vza_spread=min_vza_spread, max_condition=max_condition),
            progress=fitted, workers=workers,
        )
    plots = _class_plot_files(fit.result.fits, plot_dir) if plot_dir else {}
    check_outputs({**written, **{f"--plot-dir file {path}": path for path in plots.values()}}, read)
    for message in fit.warnings:
        click.echo(f"brdfcorr: warning: {message}", err=True)
    for class_fit in fit.result.fits:
        if class_fit.model_choice is not None:
            click.echo(f"class {class_fit.class_id} ({class_fit.name}): {class_fit.model_choice.table()}")
    click.echo(_format_table([_class_row(class_fit) for class_fit in fit.result.fits]))
    _echo_levels(fit.result.fits)
    for note in fit.notes:
        click.echo(note)
    if not fit.table.classes:  # a table that corrects nothing is never written as a result
        raise InputError(f"no class passed the guard rails (see the table above): nothing would be corrected; "
                         f"{output} not written")
    if shape_prior is not None:
        moved = sum(class_fit.prior is not None and class_fit.status == "fitted" for class_fit in fit.result.fits)
        click.echo(f"shape prior {shape_prior.label}: {moved} fitted class(es) at their posterior")
    _write_class_outputs(fit, output, report_path, plots)
    if plot_dir:
        click.echo(f"wrote plots to {plot_dir}")


def _write_class_outputs(fit, output: Path, report_path: Path | None, plots: dict[tuple[int, str], Path]) -> None:
    """The table, the report and the figures of fit-classes, together or not at all
    (:func:`brdfcorr.io.files.atomic_paths`): a table beside a report or figures that failed would
    look finished, and a rerun would refuse to replace it."""
    with atomic_paths([output, *filter(None, [report_path]), *plots.values()]) as temporaries:
        temporaries[output].write_text(fit.table.to_yaml_text())
        if report_path:
            temporaries[report_path].write_text(json.dumps(
                {"classes": fit.result.report(), "bad_bands": fit.result.bad_bands,
                 "bands_left_out": fit.result.bands_left_out, "notes": fit.notes}, indent=2))
        _plot_class_fits(fit, plots, temporaries)
    for written in (output, report_path):
        if written:
            click.echo(f"wrote {written}")


def _class_plot_files(fits, plot_dir: Path) -> dict[tuple[int, str], Path]:
    """The figures of :func:`_plot_class_fits`: {(class id, "fit" or "model_choice"): path}."""
    files = {}
    for class_fit in fits:
        stem = f"class_{class_fit.class_id}_{class_fit.name}"
        if class_fit.params:
            files[(class_fit.class_id, "fit")] = plot_dir / f"{stem}.png"
        if class_fit.model_choice is not None:
            files[(class_fit.class_id, "model_choice")] = plot_dir / f"{stem}_model_choice.png"
    return files


def _plot_class_fits(fit, files: dict[tuple[int, str], Path], temporaries: dict[Path, Path]) -> None:
    """Per class: observed and modelled against view zenith; the held-out error of each candidate
    model where ``auto`` chose it; drawn into the ``temporaries`` of the ``files``."""
    from brdfcorr.plot.materials import plot_class_fit
    from brdfcorr.plot.model_choice import plot_model_choice

    for class_fit in fit.result.fits:
        if (class_fit.class_id, "fit") in files:
            figure = plot_class_fit(class_fit, fit.result.samples[class_fit.class_id], fit.wavelengths)
            target = files[(class_fit.class_id, "fit")]
            _draw_figure(figure, temporaries[target], target)
        if (class_fit.class_id, "model_choice") in files:
            figure = plot_model_choice(class_fit.model_choice, f"class {class_fit.class_id} ({class_fit.name})")
            target = files[(class_fit.class_id, "model_choice")]
            _draw_figure(figure, temporaries[target], target)


def _echo_levels(fits) -> None:
    """One line saying that the fits left each pixel's or patch's level free, if they did."""
    within = [class_fit for class_fit in fits if class_fit.levels != "pooled"]
    if within:
        kind, groups = within[0].levels, sum(class_fit.n_groups or 0 for class_fit in within)
        click.echo(f"free levels per {kind}: the shapes are fitted to the differences between the views of each "
                   f"{kind} ({groups} seen two or more times); R2 and the spread are within them")
        for class_fit in within:  # lines on different grids: how much ground they share
            for note in (note for note in class_fit.notes if note.startswith("scenes on different grids")):
                click.echo(f"class {class_fit.class_id} ({class_fit.name}): {note}")


def _class_row(fit) -> dict[str, str]:
    from brdfcorr.models import get_model

    summary = fit.summary()
    linear = get_model(fit.model).linear
    return {
        "class": f"{fit.class_id} {fit.name}", "model": fit.model, "status": fit.status,
        "N": str(fit.n_samples), "vza spread": f"{fit.vza_spread:.1f}",
        "median R2": "-" if summary["median_r2"] is None else f"{summary['median_r2']:.3f}",
        "angular R2": "-" if summary["median_angular_r2"] is None else f"{summary['median_angular_r2']:.3f}",
        "shape": ", ".join(  # a held parameter's error is 0; a class in one block has none (NaN)
            f"{k}={v[0]:.4g}" + (f"±{fit.errors[k][0]:.2g}" if math.isfinite(fit.errors[k][0]) else "")
            for k, v in fit.params.items() if k not in linear and fit.errors[k][0] != 0
        ) or "-",
        "better model": f"{fit.better_model} (R2 {fit.better_r2:.3f})" if fit.better_model else "-",
        "errors": {None: "-", True: "reliable"}.get(  # the whole reason is in --report and the table's fit:
            fit.errors_reliable, "UNRELIABLE: " + textwrap.shorten(fit.errors_reason, 60, placeholder="...")),
    }


@main.command("fit")
@click.argument("measurements", type=click.Path(path_type=Path))
@click.option("--model", "model_name", type=FIT_MODEL_CHOICE, default="torrance_sparrow", show_default=True,
              help="Registered surface model to fit (see `brdfcorr models`), or auto: the candidate with the lowest "
                   "5-fold cross-validated error over the geometries (a more complex one only where it wins by more "
                   "than one standard error of the fold-by-fold difference).")
@click.option("--fix", multiple=True, metavar="NAME=VALUE", type=NAME_VALUE, callback=distinct_names,
              help="Hold a parameter fixed (repeatable, once per parameter); paper 003 uses --fix k=0.25.")
@click.option("--init", "initial", multiple=True, metavar="NAME=VALUE", type=NAME_VALUE, callback=distinct_names,
              help="Starting value of a parameter (repeatable, once per parameter).")
@click.option("--bound", "bounds", multiple=True, metavar="NAME=LOW:HIGH", type=NAME_RANGE, callback=distinct_names,
              help="Narrower bounds for a parameter (within its physical range; repeatable, once per parameter).")
@click.option("--min-phi", type=float, help="Fit only relative azimuths >= this [deg] (paper 003: 90).")
@click.option("--max-phi", type=float, help="Fit only relative azimuths <= this [deg].")
@click.option("--max-zenith", type=float, help="Fit only theta_i and theta_r <= this [deg].")
@click.option("--wavelength", type=float,
              help="Fit only this wavelength [nm] of a table with a wavelength column "
                   "[default: every wavelength, written as a spectral class].")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the fit as a class of this parameter table (YAML; a new file, an existing table needs "
                   "--overwrite).")
@click.option("--class-id", type=int, help="Class id in the table [default: 1 more than the largest].")
@click.option("--class-name", "class_name", help="Class name in the table [default: the CSV file's stem].")
@click.option("--overwrite", is_flag=True,
              help="Add the class to an existing table -o, or replace its class --class-id (rewritten: comments and "
                   "layout are not kept; a symbolic link stays a link, the file it points to is rewritten).")
@click.option("--name", "deprecated_name", hidden=True)  # brdfcorr <= 0.3; says so when used
@click.option("--plot-dir", type=click.Path(file_okay=False, path_type=Path),
              help="Write the principal-plane and azimuth figures (PNG) here.")
@click.option("--log", "log_scale", is_flag=True, help="Logarithmic BRDF axes in the figures.")
@click.option("--workers", type=click.IntRange(min=1),
              help="Processes that fit the candidates of --model auto side by side (the choice is the same) "
                   "[default: one per core this process may use].")
@PROGRESS
@handle_errors
def fit_command(measurements, model_name, fix, initial, bounds, min_phi, max_phi, max_zenith,
                wavelength, output, class_id, class_name, overwrite, deprecated_name, plot_dir, log_scale, workers,
                progress):
    """Fit a BRDF model to goniometer MEASUREMENTS (CSV: theta_i, theta_r, phi, brdf[, sigma,
    wavelength]).

    Prints the fitted parameters with 1-sigma errors and chi2/dof (as paper 003, Table 1) and the
    parameter correlations; with -o writes the fit as a class of a parameter table.
    """
    from brdfcorr.defaults import available_cores
    from brdfcorr.fit.measurements import MeasurementSelection
    from brdfcorr.params import ParameterTable
    from brdfcorr.tasks.goniometer import fit_measurement_file

    target = update_target(output, overwrite, inputs={"MEASUREMENTS": measurements}) if output is not None else None
    table = ParameterTable.load(target) if target is not None and target.exists() else None
    with class_bar(progress, "fit", unit="fit") as fitted:  # a candidate of --model auto or a wavelength
        fit = fit_measurement_file(
            measurements, model_name, fixed=dict(fix), initial=dict(initial), bounds=dict(bounds),
            select=MeasurementSelection(min_phi, max_phi, max_zenith, wavelength), progress=fitted,
            workers=workers or available_cores(),
        )
    for message in fit.warnings:
        click.echo(f"brdfcorr: warning: {message}", err=True)
    if deprecated_name is not None:
        click.echo("brdfcorr: warning: --name is deprecated; use --class-name NAME", err=True)
    name = class_name or deprecated_name or measurements.stem
    figures = _measurement_plot_files(fit, name, plot_dir) if plot_dir is not None else {}
    if figures:  # the figures' names are known now: check them before writing anything
        check_outputs({"-o": output, **{f"--plot-dir file {path}": path for path in figures.values()}},
                      {"MEASUREMENTS": measurements})
    for band, choice in fit.choices.items():
        click.echo(("" if band is None else f"{band:.10g} nm: ") + choice.table())
    _echo_measurement_fit(fit, name)
    table = table if table is not None else ParameterTable()
    class_id = max(table.class_ids, default=0) + 1 if class_id is None else class_id
    replaced = class_id in table
    # The figures and the table appear together or not at all (one that failed leaves none).
    with atomic_paths([*figures.values(), *filter(None, [target])]) as temporaries:
        if figures:
            _plot_measurement_fit(fit, name, {key: (path, temporaries[path]) for key, path in figures.items()},
                                  "log" if log_scale else "linear")
        if target is not None:
            temporaries[target].write_text(table.with_class(fit.table_entry(class_id, name)).to_yaml_text())
    for figure in figures.values():
        click.echo(f"wrote {figure}")
    if output is not None:
        click.echo(f"{'replaced' if replaced else 'wrote'} class {class_id} ({name}) in {output}")


def _echo_measurement_fit(fit, name: str) -> None:
    """Paper 003, Table 1 style: parameters with 1-sigma errors, chi2/dof, correlations."""
    bands = list(fit.results)
    rows = []
    for band, result in fit.results.items():
        subset = fit.fitted if band is None else fit.fitted.at_wavelength(band)
        label = {"sample": name} if band is None else {"sample": name, "λ [nm]": f"{band:.10g}"}
        rows.append({**label, "N": str(len(subset)), **result.summary()})
    data = fit.fitted
    weights = "weighted by sigma" if data.sigma is not None else "unweighted (no sigma column)"
    click.echo(f"{fit.path}: {len(data)} of {len(fit.everything)} measurements"
               f"{f' ({fit.selection})' if fit.selection else ''}, {weights}")
    first = fit.results[bands[0]]
    fitted_text = f"model {first.model.name}: {len(first.free)} free parameters"
    if len(bands) > 1:
        fitted_text += f", {len(bands)} wavelengths fitted separately"
    click.echo(fitted_text)
    click.echo()
    click.echo(_format_table(rows))
    if data.sigma is not None:
        click.echo("errors: 1 sigma from the measurement errors, not scaled by chi2/dof")
    elif first.errors_robust:
        click.echo("errors: 1 sigma from the residuals, robust to noise that differs between measurements (HC3)")
    else:
        click.echo("errors: 1 sigma scaled by the residual scatter (chi2/dof)")
    if len(bands) == 1 and len(first.free) > 1:
        click.echo(f"chi2 = {first.chi2:.4g} for {first.dof} dof"
                   + (f", P(chi2 larger) = {first.p_value:.3g}" if data.sigma is not None else "")
                   + f"; {first.n_converged} of {first.n_starts} starts reached the minimum")
        click.echo("\ncorrelations:")
        click.echo(_format_table([
            {"": row, **{column: f"{first.correlation_of(row, column):+.3f}" for column in first.free}}
            for row in first.free
        ]))


def _measurement_plot_files(fit, name: str, plot_dir: Path) -> dict[tuple, Path]:
    """The figure files of :func:`_plot_measurement_fit`: {(wavelength, kind): path}, with the
    model choice's where ``--model auto`` chose one."""
    kinds = {band: ("principal_plane", "azimuth", *(("model_choice",) if band in fit.choices else ()))
             for band in fit.results}
    return {(band, kind): plot_dir / f"{name if band is None else f'{name}_{band:.10g}nm'}_{kind}.png"
            for band in fit.results for kind in kinds[band]}


def _plot_measurement_fit(fit, name: str, files: dict[tuple, tuple[Path, Path]], scale: str) -> None:
    """Principal-plane and azimuth figures (paper 003, figs. 2 and 3) per wavelength, drawn into
    the temporary file of each of :func:`_measurement_plot_files` ({key: (target, temporary)})."""
    from brdfcorr.plot.fits import plot_azimuth, plot_principal_plane
    from brdfcorr.plot.model_choice import plot_model_choice

    others_all = fit.everything.select(~fit.keep, "not fitted") if not fit.keep.all() else None
    for band, result in fit.results.items():
        fitted, others = fit.fitted, others_all
        if band is not None:
            fitted = fit.fitted.at_wavelength(band)
            others = others.at_wavelength(band) if others is not None and band in others.wavelengths else None
        for suffix, plot in (("principal_plane", plot_principal_plane), ("azimuth", plot_azimuth)):
            _draw_figure(plot(result, fitted, others, yscale=scale), *reversed(files[(band, suffix)]), dpi=120)
        if band in fit.choices:
            title = name if band is None else f"{name}, {band:.10g} nm"
            _draw_figure(plot_model_choice(fit.choices[band], title), *reversed(files[(band, "model_choice")]),
                         dpi=120)
