"""``brdfcorr models`` and ``brdfcorr materials``: the registry and the material library."""

from __future__ import annotations

import click

from brdfcorr import models
from brdfcorr.cli._base import (
    _format_table,
    handle_errors,
    main,
)
from brdfcorr.models.materials import load_material, material_names


@main.command("models")
def models_command():
    """List the BRDF models and their parameters (units, defaults, physical range)."""

    for model in models.REGISTRY.values():
        click.echo(f"{model.name}: {model.description} [{model.reference}]")
    click.echo()
    click.echo(_format_table(models.parameter_table_rows()))


@main.command("materials")
@click.argument("name", required=False)
@handle_errors
def materials_command(name):
    """List the built-in materials, or show one material's parameters with errors."""

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


