"""``brdfcorr models``, ``brdfcorr materials`` and ``brdfcorr coefficients``: the registry, the material
library and the coefficient library."""

from __future__ import annotations

from pathlib import Path

import click

from brdfcorr.cli._base import (
    _format_table,
    handle_errors,
    main,
)

# The registry and the material library (scipy) are imported when a command runs, not when its
# options are parsed: --help and argument errors answer at once.


def material_names() -> tuple[str, ...]:
    """The built-in materials' names, importing the material library only when called."""
    from brdfcorr.models import materials

    return materials.material_names()


#: Width [columns] of the text of ``brdfcorr models``.
MODELS_WIDTH = 100

#: The ``--overwrite`` option of the commands that add a class to a parameter table ``-o``.
def as_class_options(what: str):
    """NAME and the options that write ``what`` as a class of a parameter table (``materials``,
    ``coefficients``)."""
    decorators = (
        click.argument("name", required=False),
        click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
                     help=f"Write {what} as a class of this parameter table (a new file; an existing table "
                          "needs --overwrite)."),
        click.option("--class-id", type=int, help="Its class id [default: 1 more than the largest]."),
        click.option("--overwrite", is_flag=True,
                     help="Add the class to an existing table -o (rewritten: its comments and layout are not "
                          "kept; a symbolic link stays a link, the file it points to is rewritten)."),
    )

    def decorate(command):
        for decorator in reversed(decorators):
            command = decorator(command)
        return command

    return decorate


@main.command("models")
@click.argument("name", required=False)
@handle_errors
def models_command(name):
    """List the BRDF models and their parameters (units, defaults, physical range).

    With NAME, show that model: what it is, its reference and what each parameter means.
    """
    import textwrap

    from brdfcorr import models

    rows = models.parameter_table_rows()
    if name is not None:
        model = models.get_model(name)
        click.echo(textwrap.fill(f"{model.name}: {model.description}", MODELS_WIDTH, subsequent_indent="  "))
        click.echo(textwrap.fill(f"Reference: {model.reference}", MODELS_WIDTH, subsequent_indent="  "))
        for row in (row for row in rows if row["model"] == model.name):
            click.echo(f"\n{row['parameter']} [{row['units']}], default {row['default']}, range {row['range']}")
            click.echo(textwrap.fill(row["description"], MODELS_WIDTH, initial_indent="  ", subsequent_indent="  "))
        return
    width = max(len(model_name) for model_name in models.REGISTRY)
    for model in models.REGISTRY.values():
        click.echo(textwrap.fill(f"{model.name.ljust(width)}  {model.description}", MODELS_WIDTH,
                                 subsequent_indent=" " * (width + 2)))
    click.echo()
    table = _format_table([{key: value for key, value in row.items() if key != "description"} for row in rows])
    click.echo("\n".join(line.rstrip() for line in table.splitlines()))
    click.echo("\nbrdfcorr models NAME: what each parameter of the model NAME means, and its reference")


def _named(name: str | None, what: str) -> str:
    if name is None:
        raise click.UsageError(f"-o needs {what}")
    return name


def _add_class(output: Path, overwrite: bool, class_id: int | None, entry) -> int:
    """Add ``entry(class_id)`` to the table ``output`` (a new file, or an existing one with
    ``overwrite``: :func:`brdfcorr.io.paths.update_target`); the id defaults to one more than the
    table's largest. Returns the id."""
    from brdfcorr.io.paths import update_target
    from brdfcorr.params import ParameterTable

    target = update_target(output, overwrite)
    table = ParameterTable.load(target) if target.exists() else ParameterTable()
    class_id = max(table.class_ids, default=0) + 1 if class_id is None else class_id
    table.with_class(entry(class_id)).save(target)
    return class_id


@main.command("materials")
@as_class_options("the material NAME")
@handle_errors
def materials_command(name, output, class_id, overwrite):
    """List the built-in materials, or show one material's parameters with errors.

    With -o, the material becomes a class of a parameter table. The library's fits are at one
    wavelength (paper 003: 550 nm) and apply to every band of an image.
    """
    from brdfcorr.models.materials import load_material

    if output is not None:
        material = load_material(_named(name, "a material NAME"))
        class_id = _add_class(output, overwrite, class_id, material.table_entry)
        click.echo(f"wrote class {class_id} ({name}, {material.wavelength:g} nm fit) to {output}")
        return

    names = [name] if name else material_names()
    rows = []
    for material in map(load_material, names):
        row = {"material": material.name}
        row.update(
            {key: f"{value:g} ± {material.errors[key]:g}" for key, value in material.params.items()}
        )
        row["chi2/dof"] = f"{material.reduced_chi2:g}"
        rows.append(row)
    click.echo(_format_table(rows))
    click.echo(f"\nmodel {material.model.name}, {material.wavelength:g} nm. Source: {material.source}")
    if name is None:
        click.echo("Vegetation and soil per Landsat and Sentinel-2 band (Roy et al. 2016, 2017): brdfcorr coefficients")


@main.command("coefficients")
@as_class_options("the coefficient set NAME")
@handle_errors
def coefficients_command(name, output, class_id, overwrite):
    """List the built-in BRDF coefficient sets, or show one set's weights per band.

    The sets are published global RTLSR weights (model ross_thick_li_sparse) for Landsat and
    Sentinel-2 bands, as used by HLS and sen2nbar. Weights are shown as published (reflectance
    factors) and as brdfcorr parameters (divided by pi, sr^-1). With -o, the set becomes a class
    of a parameter table, interpolated to an image's band centres.
    """
    import math

    from brdfcorr.models.coefficients import coefficient_names, load_coefficients

    if output is not None:
        class_id = _add_class(output, overwrite, class_id,
                              load_coefficients(_named(name, "a coefficient set NAME")).table_entry)
        click.echo(f"wrote class {class_id} ({name}) to {output}")
        return
    if name is None:
        sets = [load_coefficients(key) for key in coefficient_names()]
        click.echo(_format_table([{"set": s.name, "model": s.model.name, "bands": ", ".join(s.published)}
                                  for s in sets]))
        click.echo()
        for coefficients in sets:
            click.echo(f"{coefficients.name}: {coefficients.source}")
        return
    coefficients = load_coefficients(name)
    rows = []
    for band, weights in coefficients.published.items():
        low, high = coefficients.centres[band]
        rows.append({"band": band, "centres [nm]": f"{low:g}-{high:g}",
                     **{f"{key} (BRF)": f"{value:.4f}" for key, value in weights.items()},
                     **{f"{key} [sr^-1]": f"{value / math.pi:.5f}" for key, value in weights.items()}})
    click.echo(_format_table(rows))
    for sensor, bands in coefficients.sensor_bands.items():
        used = [f"{band}={spectral}" for band, spectral in bands.items() if spectral in coefficients.published]
        click.echo(f"{sensor}: {' '.join(used)}")
    click.echo(f"\nmodel {coefficients.model.name}. Source: {coefficients.source}")
