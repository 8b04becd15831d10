"""The ``brdfcorr`` command line: a thin layer over the library.

Commands parse arguments, call library functions, print tables and map errors to exit codes:
2 for bad input (any :class:`brdfcorr.errors.BrdfcorrError`), 1 for internal failures.
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import click

from brdfcorr import __version__
from brdfcorr.errors import BrdfcorrError


def _format_table(rows: list[dict[str, str]]) -> str:
    """Rows of equal keys as a plain aligned text table."""
    columns = list(rows[0])
    widths = {column: max(len(column), *(len(str(row[column])) for row in rows)) for column in columns}
    lines = ["  ".join(column.ljust(widths[column]) for column in columns)]
    lines.append("  ".join("-" * widths[column] for column in columns))
    lines += ["  ".join(str(row[column]).ljust(widths[column]) for column in columns) for row in rows]
    return "\n".join(lines)


def handle_errors(command):
    """Turn library errors into one line on stderr and exit code 2."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except BrdfcorrError as error:
            click.echo(f"brdfcorr: error: {error}", err=True)
            sys.exit(2)

    return wrapper


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="brdfcorr")
def main():
    """Specular BRDF models and BRDF normalization of reflectance imagery."""


@main.command("models")
def models_command():
    """List the BRDF models and their parameters (units, defaults, physical range)."""
    from brdfcorr.models import REGISTRY, parameter_table_rows

    for model in REGISTRY.values():
        click.echo(f"{model.name}: {model.description} [{model.reference}]")
    click.echo()
    click.echo(_format_table(parameter_table_rows()))


@main.command("materials")
@click.argument("name", required=False)
@handle_errors
def materials_command(name):
    """List the built-in materials, or show one material's parameters with errors."""
    from brdfcorr.materials import load_material, material_names

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


@main.command("demo")
@click.option(
    "-o", "--output-dir", type=click.Path(file_okay=False, path_type=Path), default="demo_output",
    show_default=True, help="Directory for the demo outputs.",
)
@handle_errors
def demo_command(output_dir: Path):
    """Evaluate the material library and write a figure of its BRDFs."""
    from brdfcorr.io_utils import atomic_path
    from brdfcorr.materials import load_material, material_names
    from brdfcorr.plotting import plot_materials

    output_dir.mkdir(parents=True, exist_ok=True)
    figure = plot_materials([load_material(name) for name in material_names()])
    target = output_dir / "materials_brdf.png"
    with atomic_path(target) as temporary:
        figure.savefig(temporary, dpi=110, format="png")
    click.echo(f"wrote {target}")
