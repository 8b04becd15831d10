"""``brdfcorr fit`` (goniometer tables) and ``brdfcorr fit-classes`` (imagery)."""

from __future__ import annotations

from pathlib import Path

import click

from brdfcorr.cli._base import (
    _assignments,
    _format_table,
    _pairs,
    _refuse_overwriting_inputs,
    handle_errors,
    main,
)


@main.command("fit-classes")
@click.argument("images", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--angles", multiple=True, required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="4-band angle raster (sza, saa, vza, vaa [deg]) per image, in the images' order.")
@click.option("--classes", multiple=True, required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Class map per image, in the images' order.")
@click.option("--model", "model_name", default="torrance_sparrow", show_default=True,
              help="Model for every class (see `brdfcorr models`).")
@click.option("--class-model", multiple=True, metavar="ID=MODEL", help="Model of one class (repeatable).")
@click.option("--name", "names", multiple=True, metavar="ID=NAME", help="Name of a class (repeatable).")
@click.option("--fix", multiple=True, metavar="NAME=VALUE", help="Hold a shape parameter fixed [default: k=0.25 for TS].")
@click.option("--max-samples", type=int, default=50_000, show_default=True, help="Samples per class, over all images.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the pixel sampler.")
@click.option("--scale", "reflectance_scale", type=float, default=1.0, show_default=True,
              help="Multiplier from stored values to reflectance factors (e.g. 0.0001).")
@click.option("--min-samples", type=int, default=500, show_default=True, help="Guard rail: minimum samples per class.")
@click.option("--min-vza-spread", type=float, default=10.0, show_default=True,
              help="Guard rail: minimum 5-95 %% view zenith spread [deg].")
@click.option("--fallback", help="Built-in material for classes that fail the guard rails [default: leave uncorrected].")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Parameter table to write (YAML).")
@click.option("--report", "report_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Fit report to write (JSON).")
@click.option("--plot-dir", type=click.Path(file_okay=False, path_type=Path),
              help="Directory for one PNG per class (observed vs modelled against view zenith).")
@handle_errors
def fit_classes_command(images, angles, classes, model_name, class_model, names, fix, max_samples, seed,
                        reflectance_scale, min_samples, min_vza_spread, fallback, output, report_path, plot_dir):
    """Fit per-class, per-band BRDF parameters from IMAGES themselves (one or many scenes)."""
    import json
    import warnings

    import xarray as xr

    from brdfcorr.io import rasters as rio_io
    from brdfcorr.fit.classes import ClassFitWarning, GuardRails, fit_classes
    from brdfcorr.errors import InputError
    from brdfcorr.io.files import atomic_path
    from brdfcorr.models.materials import load_material

    if not len(images) == len(angles) == len(classes):
        raise InputError(
            f"{len(images)} image(s), {len(angles)} --angles and {len(classes)} --classes: give one "
            "angle raster and one class map per image, in the same order"
        )
    _refuse_overwriting_inputs({"-o": output, "--report": report_path}, (*images, *angles, *classes))
    if fallback:
        load_material(fallback)  # fail before the work if the name is wrong
    scenes = []
    for image_path, angle_path, class_path in zip(images, angles, classes):
        image, class_map, layers = rio_io.open_scene(image_path, class_path, angle_path)
        scenes.append((image, class_map, xr.Dataset(layers)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ClassFitWarning)
        result = fit_classes(
            [s[0] for s in scenes], [s[1] for s in scenes], [s[2] for s in scenes], model_name,
            class_models=_pairs("--class-model", class_model), names=_pairs("--name", names), fixed=_assignments("--fix", fix) or None,
            max_samples=max_samples, seed=seed, reflectance_scale=reflectance_scale,
            guard=GuardRails(min_samples=min_samples, min_vza_spread=min_vza_spread), fallback=fallback,
        )
    for warning in caught:
        click.echo(f"brdfcorr: warning: {warning.message}", err=True)
    rows = []
    for fit in result.fits:
        summary = fit.summary()
        rows.append({
            "class": f"{fit.class_id} {fit.name}", "model": fit.model, "status": fit.status,
            "N": str(fit.n_samples), "vza spread": f"{fit.vza_spread:.1f}",
            "median R2": "-" if summary["median_r2"] is None else f"{summary['median_r2']:.3f}",
            "shape": ", ".join(
                f"{k}={v[0]:.4g}±{fit.errors[k][0]:.2g}" for k, v in fit.params.items()
                if k not in ("t0", "t1", "a") and fit.errors[k][0] > 0
            ) or "-",
        })
    click.echo(_format_table(rows))
    for target in (output, report_path):
        if target is not None:
            target.parent.mkdir(parents=True, exist_ok=True)
    path = result.table.save(output)
    click.echo(f"wrote {path}")
    if report_path:
        with atomic_path(report_path) as temporary:
            temporary.write_text(json.dumps({"classes": result.report()}, indent=2))
        click.echo(f"wrote {report_path}")
    if plot_dir:
        from brdfcorr.plot.materials import plot_class_fit

        plot_dir.mkdir(parents=True, exist_ok=True)
        wavelengths = scenes[0][0].coords["wavelength"].values if "wavelength" in scenes[0][0].coords else None
        for fit in result.fits:
            if fit.params:
                target = plot_dir / f"class_{fit.class_id}_{fit.name}.png"
                with atomic_path(target) as temporary:
                    plot_class_fit(fit, result.samples[fit.class_id], wavelengths).savefig(
                        temporary, dpi=100, format="png"
                    )
        click.echo(f"wrote plots to {plot_dir}")


@main.command("fit")
@click.argument("measurements", type=click.Path(path_type=Path))
@click.option("--model", "model_name", default="torrance_sparrow", show_default=True,
              help="Registered surface model to fit (see `brdfcorr models`).")
@click.option("--fix", multiple=True, metavar="NAME=VALUE",
              help="Hold a parameter fixed (repeatable); paper 003 uses --fix k=0.25.")
@click.option("--init", "initial", multiple=True, metavar="NAME=VALUE", help="Starting value of a parameter.")
@click.option("--bound", "bounds", multiple=True, metavar="NAME=LOW:HIGH",
              help="Narrower bounds for a parameter (within its physical range).")
@click.option("--min-phi", type=float, help="Fit only relative azimuths >= this [deg] (paper 003: 90).")
@click.option("--max-phi", type=float, help="Fit only relative azimuths <= this [deg].")
@click.option("--max-zenith", type=float, help="Fit only theta_i and theta_r <= this [deg].")
@click.option("--wavelength", type=float,
              help="Fit only this wavelength [nm] of a table with a wavelength column "
                   "[default: every wavelength, written as a spectral class].")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Parameter table (YAML) to write, or to add the class to if it exists.")
@click.option("--class-id", type=int, help="Class id in the table [default: 1 more than the largest].")
@click.option("--name", "class_name", help="Class name in the table [default: the CSV file's stem].")
@click.option("--plot-dir", type=click.Path(file_okay=False, path_type=Path),
              help="Write the principal-plane and azimuth figures (PNG) here.")
@click.option("--log", "log_scale", is_flag=True, help="Logarithmic BRDF axes in the figures.")
@handle_errors
def fit_command(measurements, model_name, fix, initial, bounds, min_phi, max_phi, max_zenith,
                wavelength, output, class_id, class_name, plot_dir, log_scale):
    """Fit a BRDF model to goniometer MEASUREMENTS (CSV: theta_i, theta_r, phi, brdf[, sigma,
    wavelength]).

    Prints the fitted parameters with 1-sigma errors and chi2/dof (as paper 003, Table 1) and the
    parameter correlations; with -o writes the fit as a class of a parameter table.
    """
    import warnings

    from brdfcorr.fit.goniometer import FitWarning, fit_measurements, spectral_table_entry
    from brdfcorr.io.files import atomic_path
    from brdfcorr.fit.measurements import filter_measurements, read_measurements, selection_mask
    from brdfcorr.params import ParameterTable

    _refuse_overwriting_inputs({"-o": output}, (measurements,))
    table = ParameterTable.load(output) if output is not None and output.exists() else None
    everything = read_measurements(measurements)
    if wavelength is not None:
        everything = everything.at_wavelength(wavelength)
    selection = {"min_phi": min_phi, "max_phi": max_phi, "max_zenith": max_zenith}
    data = filter_measurements(everything, **selection)
    keep, selection = selection_mask(everything, **selection)
    options = {
        "fixed": _assignments("--fix", fix),
        "initial": _assignments("--init", initial),
        "bounds": _assignments("--bound", bounds, ranges=True),
    }

    name = class_name or measurements.stem
    bands = data.wavelengths or (None,)
    results, rows = {}, []
    for band in bands:
        subset = data if band is None else data.at_wavelength(band)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FitWarning)
            results[band] = fit_measurements(model_name, subset, **options)
        for warning in caught:
            if issubclass(warning.category, FitWarning):
                where = "" if band is None or len(bands) == 1 else f"{band:g} nm: "
                click.echo(f"brdfcorr: warning: {where}{warning.message}", err=True)
        label = {"sample": name} if band is None else {"sample": name, "λ [nm]": f"{band:g}"}
        rows.append({**label, "N": str(len(subset)), **results[band].summary()})

    weights = "weighted by sigma" if data.sigma is not None else "unweighted (no sigma column)"
    click.echo(f"{measurements}: {len(data)} of {len(everything)} measurements"
               f"{f' ({selection})' if selection else ''}, {weights}")
    first = results[bands[0]]
    fitted_text = f"model {first.model.name}: {len(first.free)} free parameters"
    if len(bands) > 1:
        fitted_text += f", {len(bands)} wavelengths fitted separately"
    click.echo(fitted_text)
    click.echo()
    click.echo(_format_table(rows))
    if data.sigma is not None:
        click.echo("errors: 1 sigma from the measurement errors, not scaled by chi2/dof")
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

    if plot_dir is not None:
        from brdfcorr.plot.fits import plot_azimuth, plot_principal_plane

        plot_dir.mkdir(parents=True, exist_ok=True)
        scale = "log" if log_scale else "linear"
        for band, result in results.items():
            fitted, others = data, (everything.select(~keep, "not fitted") if not keep.all() else None)
            stem = name
            if band is not None:
                fitted = data.at_wavelength(band)
                if others is not None and band in others.wavelengths:
                    others = others.at_wavelength(band)
                elif others is not None:
                    others = None
                stem = f"{name}_{band:g}nm"
            for suffix, plot in (("principal_plane", plot_principal_plane), ("azimuth", plot_azimuth)):
                target = plot_dir / f"{stem}_{suffix}.png"
                with atomic_path(target) as temporary:
                    plot(result, fitted, others, yscale=scale).savefig(temporary, dpi=120, format="png")
                click.echo(f"wrote {target}")
    if output is not None:
        table = table if table is not None else ParameterTable()
        if class_id is None:
            class_id = max(table.class_ids, default=0) + 1
        replaced = class_id in table
        table.with_class(spectral_table_entry(results, class_id, name)).save(output)
        click.echo(f"{'replaced' if replaced else 'wrote'} class {class_id} ({name}) in {output}")


