"""``brdfcorr models`` and ``brdfcorr materials``: the registry and the material library."""

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


@main.command("models")
def models_command():
    """List the BRDF models and their parameters (units, defaults, physical range)."""
    from brdfcorr import models

    for model in models.REGISTRY.values():
        click.echo(f"{model.name}: {model.description} [{model.reference}]")
    click.echo()
    click.echo(_format_table(models.parameter_table_rows()))


@main.command("materials")
@click.argument("name", required=False)
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Add the material NAME as a class to this parameter table (created if absent).")
@click.option("--class-id", type=int, help="Its class id [default: 1 more than the largest].")
@handle_errors
def materials_command(name, output, class_id):
    """List the built-in materials, or show one material's parameters with errors.

    With -o, the material becomes a class of a parameter table. The library's fits are at one
    wavelength (paper 003: 550 nm) and apply to every band of an image.
    """
    from brdfcorr.models.materials import load_material
    from brdfcorr.params import ParameterTable

    if output is not None:
        if name is None:
            raise click.UsageError("-o needs a material NAME")
        table = ParameterTable.load(output) if output.exists() else ParameterTable()
        class_id = max(table.class_ids, default=0) + 1 if class_id is None else class_id
        material = load_material(name)
        table.with_class(material.table_entry(class_id)).save(output)
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


