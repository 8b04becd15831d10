"""``brdfcorr analyze``: the papers' own analyses (library: brdfcorr.analysis.papers, brdfcorr.analysis.simulate)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import click

from brdfcorr.cli._base import (
    _format_table,
    _save_figure,
    handle_errors,
    main,
)

# The analyses (scipy) and figures (matplotlib) are imported when a command runs, not when its
# options are parsed: --help and argument errors answer at once.


def _zenith_list(value: str) -> list[float]:
    try:
        return [float(item) for item in value.split(",") if item.strip()]
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a comma-separated list of angles [deg]") from None


@main.group("analyze")
def analyze_group():
    """The papers' analyses: shadowing impact, azimuthal width, albedo, paper figures."""


@analyze_group.command("shadowing")
@click.option("--max-zenith", type=float, default=70.0, show_default=True, help="Largest theta_i and theta_r [deg].")
@click.option("--phi-range", nargs=2, type=float, default=(0.0, 180.0), show_default=True,
              help="Range of relative azimuth [deg].")
@click.option("--step", type=float, default=0.5, show_default=True, help="Grid step [deg].")
@handle_errors
def analyze_shadowing_command(max_zenith, phi_range, step):
    """Simplified (G = 1) vs full TS model for the material library (paper 003, section 5)."""
    from brdfcorr.analysis.papers import PAPER_SHADOWING_TEXT, WORST_CASE_PARAMS, shadowing_impact
    from brdfcorr.models.materials import load_material, material_names

    cases = [("worst case (roof-tile peak, albedo 0.01)", WORST_CASE_PARAMS, None)]
    cases += [(name, load_material(name).params, PAPER_SHADOWING_TEXT.get(name)) for name in material_names()]
    rows = []
    for label, params, paper in cases:
        impact = shadowing_impact(params, max_zenith=max_zenith, phi_range=tuple(phi_range), step=step)
        rows.append({
            "material": label,
            "max rel. diff": f"{100 * impact.max_relative:.2f} %",
            "at (ti, tr, phi)": "({:g}, {:g}, {:g})".format(*impact.where_relative),
            "max abs. diff [sr^-1]": f"{impact.max_absolute:.2e}",
            "at (ti, tr, phi) ": "({:g}, {:g}, {:g})".format(*impact.where_absolute),
            "paper 003 (<= 70 deg)": paper or "-",
        })
    click.echo(_format_table(rows))
    click.echo(f"\nzeniths 0-{max_zenith:g} deg, phi {phi_range[0]:g}-{phi_range[1]:g} deg, step {step:g} deg; "
               "relative difference = (f(G=1) - f) / f.")


@analyze_group.command("width")
@click.argument("names", nargs=-1)
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the normalized azimuthal cuts (paper 003, fig. 3) to this image.")
@handle_errors
def analyze_width_command(names, output):
    """Azimuthal FWHM of the specular peak at the geometries of paper 003, fig. 3."""
    from brdfcorr.analysis.papers import width_reduction
    from brdfcorr.models.materials import load_material, material_names
    from brdfcorr.plot.analysis import plot_azimuthal_widths

    materials = [load_material(name) for name in (names or material_names())]
    rows = []
    for material in materials:
        result = width_reduction(material.model, material.params)
        row = {"material": material.name}
        row.update({f"FWHM {ti:g}/{tr:g} [deg]": f"{width:.1f}" for (ti, tr), width in result["widths"].items()})
        row.update({f"reduction {ti:g}/{tr:g}": f"{100 * value:.0f} %"
                    for (ti, tr), value in list(result["reductions"].items())[1:]})
        rows.append(row)
    click.echo(_format_table(rows))
    click.echo("\npaper 003: about 50 % from 30 to 50 deg, about 75 % from 30 to 65 deg.")
    if output:
        _save_figure(plot_azimuthal_widths(materials), output)


@analyze_group.command("albedo")
@click.argument("name")
@click.option("--sza", "zeniths", default="0,30,45,60,70,80,85", show_default=True,
              help="Illumination zeniths [deg], comma-separated.")
@click.option("--simplified", is_flag=True, help="Use the simplified model (G = 1); paper 003 advises against it.")
@click.option("--resolution", type=float, default=2.0, show_default=True, help="Quadrature panel width [deg].")
@handle_errors
def analyze_albedo_command(name, zeniths, simplified, resolution):
    """Directional-hemispherical reflectance of a material at several sun zeniths."""
    from brdfcorr.analysis.papers import albedo, specular_albedo_bound
    from brdfcorr.models.materials import load_material

    material = load_material(name)
    model = "torrance_sparrow_simplified" if simplified else material.model.name
    angles = _zenith_list(zeniths)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        values = albedo(model, angles, material.params, resolution=resolution)
    for warning in caught:
        click.echo(f"brdfcorr: warning: {warning.message}", err=True)
    params = material.params
    bound = math.pi * params.get("t0", 0.0) + specular_albedo_bound(params.get("t1", 0.0), params.get("w", 1.0))
    rows = [{"sza [deg]": f"{angle:g}", "albedo": f"{value:.4f}"} for angle, value in zip(angles, values)]
    click.echo(_format_table(rows))
    click.echo(f"\n{material.label}, {model}. Diffuse part pi t0 = {math.pi * params.get('t0', 0.0):.4f}; "
               f"energy bound of the full model with F <= 1: {bound:.4f}.")


@analyze_group.command("figure2")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              default="figure2.png", show_default=True, help="Output image.")
@click.option("--view-step", type=float, default=5.0, show_default=True,
              help="View-zenith step of the simulated points [deg].")
@click.option("--step-fraction", type=float, default=0.5, show_default=True,
              help="Facet-normal grid step of the simulation, as a fraction of sigma.")
@handle_errors
def analyze_figure2_command(output, view_step, step_fraction):
    """Figure 2 of paper 000: TS model, V-cavity simulation and empirical model, normalized."""
    import numpy as np

    from brdfcorr.analysis.simulate import FacetGrid
    from brdfcorr.plot.analysis import plot_figure2

    if not view_step > 0:
        raise click.BadParameter("must be > 0", param_hint="--view-step")
    view = np.arange(0.0, 85.0 + 1e-9, view_step)
    _save_figure(plot_figure2(view, grid=FacetGrid(step_fraction=step_fraction)), output)


@analyze_group.command("polar")
@click.argument("name")
@click.option("--sza", "zeniths", default="30,50,65", show_default=True, help="Illumination zeniths [deg].")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Output image [default: polar_NAME.png].")
@handle_errors
def analyze_polar_command(name, zeniths, output):
    """Polar plots of a material's BRDF over the view hemisphere."""
    from brdfcorr.models.materials import load_material
    from brdfcorr.plot.analysis import plot_polar

    material = load_material(name)
    _save_figure(plot_polar(material, _zenith_list(zeniths)), output or Path(f"polar_{material.name}.png"))
