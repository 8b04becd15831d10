"""The ``brdfcorr`` command line: a thin layer over the library.

Commands parse arguments, call library functions, print tables and map errors to exit codes
(:data:`EXIT_CODES`): 2 for bad input or an output that cannot be written (any
:class:`brdfcorr.errors.BrdfcorrError`, and click's usage errors), 1 for internal failures (any
other exception), 3 when ``run`` finished but some scenes failed. An error is one line on stderr;
the global ``--debug`` option adds the traceback.
"""

from __future__ import annotations

import functools
import sys
import traceback
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


#: Exit code of a bad input, config, parameter or option, or of an output that cannot be written.
EXIT_BAD_INPUT = 2
#: Exit code of an internal failure (a bug: any exception that is not a BrdfcorrError).
EXIT_INTERNAL = 1
#: Exit code of `brdfcorr run` when the run finished but some scenes failed (see the report).
EXIT_SCENES_FAILED = 3
EXIT_CODES = {0: "success", EXIT_INTERNAL: "internal error (a bug; --debug shows the traceback)",
              EXIT_BAD_INPUT: "bad input, config, parameter or option, or an output that cannot be written",
              EXIT_SCENES_FAILED: "run: the run finished but some scenes failed (see the report)"}


def _debug_enabled() -> bool:
    context = click.get_current_context(silent=True)
    return bool(context is not None and context.find_root().params.get("debug"))


def _fail(error: Exception):
    """One line on stderr (the traceback before it with --debug), then the exit code of the error."""
    if _debug_enabled():
        traceback.print_exception(error, file=sys.stderr)
    # One line: an unattended batch greps its logs line by line.
    text = " ".join(str(error).split("\n")).strip()
    if isinstance(error, BrdfcorrError):
        click.echo(f"brdfcorr: error: {text}", err=True)
        sys.exit(EXIT_BAD_INPUT)
    hint = "" if _debug_enabled() else " (rerun with --debug for the traceback)"
    click.echo(f"brdfcorr: internal error: {type(error).__name__}: {text}{hint}", err=True)
    sys.exit(EXIT_INTERNAL)


def handle_errors(command):
    """Map exceptions to exit codes: :class:`BrdfcorrError` and click's usage errors -> one line
    and 2, any other exception -> one "internal error" line and 1; click's exit and abort pass."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except click.UsageError as error:  # one line like every other error; the usage is in --help
            context = error.ctx or click.get_current_context(silent=True)  # raised in a command
            where = " ".join(context.command_path.split()[1:]) if context is not None else ""
            hint = f" (see --help of {where})" if where else ""
            click.echo(f"brdfcorr: error: {where + ': ' if where else ''}{error.format_message()}{hint}", err=True)
            sys.exit(error.exit_code)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except Exception as error:  # noqa: BLE001 (the one place every failure is turned into an exit code)
            _fail(error)

    return wrapper


class _Group(click.Group):
    """The command group: every command and subgroup runs under :func:`handle_errors`."""

    def invoke(self, ctx):
        return handle_errors(super().invoke)(ctx)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]},
             epilog="Exit codes: 0 success; 2 bad input, config, parameter or option, or an output "
                    "that cannot be written (one line on stderr naming the file, key, band or class); "
                    "1 internal error (a bug; --debug shows the traceback); 3 run: some scenes failed.")
@click.option("--debug", is_flag=True, help="Show the traceback of an error.")
@click.version_option(__version__, prog_name="brdfcorr")
def main(debug):
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
@click.option("--config", "config_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Chain config to run on the demo scene [default: configs/demo.yaml].")
@click.option("--progress/--no-progress", default=None, help="Progress bar [default: on a terminal].")
@handle_errors
def demo_command(output_dir: Path, config_path, progress):
    """Build a demo airborne line, correct it with the demo chain and write a before/after picture.

    Writes OUTPUT_DIR/scene/ (image, angles, classes), OUTPUT_DIR/corrected/ (corrected GeoTIFF,
    QA, before/after quicklook, run report), OUTPUT_DIR/demo.yaml (the chain, rerun with
    `brdfcorr run`) and OUTPUT_DIR/materials_brdf.png.
    """
    from brdfcorr.demo import run_demo

    with _chain_progress(progress, "demo") as callback:
        result = run_demo(output_dir, config_path, progress=callback)
    _echo_run(result.report)
    for figure in result.figures:
        click.echo(f"wrote {figure}")
    if not result.report.ok:
        sys.exit(EXIT_SCENES_FAILED)


# ------------------------------------------------------------------------------------------------
# brdfcorr run / validate: chain configs (library: brdfcorr.config, brdfcorr.pipeline)
# ------------------------------------------------------------------------------------------------

def _overrides(items: tuple[str, ...]) -> dict:
    """``--set KEY=VALUE`` items: dotted config keys, values read as YAML (``engine.workers=2``)."""
    from brdfcorr.config import ConfigError
    from brdfcorr.io_utils import parse_yaml

    parsed = {}
    for item in items:
        key, sign, text = item.partition("=")
        if not sign or not key.strip():
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. engine.workers=2")
        parsed[key.strip()] = parse_yaml(text, f"--set {item!r}", ConfigError)
    return parsed


class _chain_progress:
    """Context manager giving a ``progress(event, info)`` callback that drives an overall tqdm bar
    over the scenes (on a terminal, or when asked)."""

    def __init__(self, enabled, description: str):
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.description = description
        self.bar = None

    def __enter__(self):
        return self.callback

    def callback(self, event: str, info: dict) -> None:
        if not self.enabled:
            return
        from tqdm import tqdm

        if event == "plan":
            self.bar = tqdm(total=info["scenes"], desc=self.description, unit="scene", file=sys.stderr)
        elif event == "fit" and self.bar is not None:
            self.bar.write(f"fit: {len(info.get('classes', []))} classes")
        elif event == "scene" and self.bar is not None:
            self.bar.set_postfix_str(f"{info['scene']}: {info['status']}")
            self.bar.update(1)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
        return False


def _echo_run(report) -> None:
    rows = []
    for result in report.scenes:
        qa = result.get("qa", {})
        rows.append({
            "scene": result["scene"], "status": result["status"],
            "corrected": str(qa.get("corrected", "-")), "limited": str(qa.get("limited", "-")),
            "seconds": f"{result.get('seconds', {}).get('total', 0):.1f}",
            "note": result.get("error") or result.get("reason", ""),
        })
    if rows:
        click.echo(_format_table(rows))
    click.echo(f"{report.n_ok} ok, {report.n_skipped} skipped, {report.n_failed} failed in "
               f"{report.timings.get('total', 0):.1f} s; report: {report.path}")


@main.command("run")
@click.argument("chain", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--dry-run", is_flag=True, help="List the scenes and what would happen to each; write nothing.")
@click.option("--resume", is_flag=True, help="Skip scenes whose complete outputs exist (outputs.existing=skip).")
@click.option("--overwrite", is_flag=True, help="Redo scenes whose outputs exist (outputs.existing=overwrite).")
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE",
              help="Override a config key (dotted, value as YAML), e.g. --set engine.workers=4 (repeatable).")
@click.option("--progress/--no-progress", default=None, help="Progress bar [default: on a terminal].")
@handle_errors
def run_command(chain, dry_run, resume, overwrite, settings, progress):
    """Run the processing chain CHAIN (YAML) over all its scenes and write a run report (JSON).

    Exit codes: 0 every scene corrected or skipped; 3 the run finished but some scenes failed
    (listed, with the reason, in the table and the report); 2 a bad config or input before any
    scene ran (nothing is written); 1 an internal error.
    """
    from brdfcorr.config import load_config
    from brdfcorr.errors import InputError
    from brdfcorr.pipeline import plan_run, run_chain

    if resume and overwrite:
        raise InputError("--resume and --overwrite exclude each other")
    overrides = _overrides(settings)
    if resume or overwrite:
        overrides["outputs.existing"] = "skip" if resume else "overwrite"
    config = load_config(chain, overrides)
    plan = plan_run(config, require_inputs=not dry_run)
    if dry_run:
        _echo_plan(plan)
        return
    with _chain_progress(progress, chain.name) as callback:
        report = run_chain(config, progress=callback, plan=plan)
    _echo_run(report)
    if not report.ok:
        sys.exit(EXIT_SCENES_FAILED)


def _echo_plan(plan) -> None:
    description = plan.describe()
    engine = description["engine"]
    click.echo(f"chain {description['config']}: steps {', '.join(description['steps']) or '(none)'}")
    for source in description["parameters"]:
        click.echo(f"  parameters: {source}")
    if description["reference"]:
        click.echo("  reference: " + " ".join(f"{k}={v}" for k, v in description["reference"].items()))
    click.echo(f"  engine: {engine['scheduler']}, {engine['workers']} workers, chunk {engine['chunk']}"
               + (f", scheduler at {engine['address']}" if engine.get("address") else ""))
    click.echo(f"  outputs: {description['output_directory']} (report {Path(description['report']).name})")
    rows = [{
        "scene": scene["scene"], "action": scene["action"], "image": scene["image"],
        "outputs": ", ".join(Path(p).name for p in scene["outputs"].values()) or "-",
        "reason": scene.get("reason", ""),
    } for scene in description["scenes"]]
    if rows:
        click.echo(_format_table(rows))
    for warning in description["warnings"]:
        click.echo(f"brdfcorr: warning: {warning}", err=True)
    counts = {action: sum(s["action"] == action for s in description["scenes"]) for action in ("run", "skip", "fail")}
    click.echo(f"{len(rows)} scenes: {counts['run']} to run, {counts['skip']} to skip, {counts['fail']} would fail")


@main.command("validate")
@click.argument("chains", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE", help="Override a config key (as for run).")
@handle_errors
def validate_command(chains, settings):
    """Check chain configs without running them: keys, values, names, patterns, parameter table.

    Files that do not exist yet (inputs, tables) are warnings; a malformed config is an error
    naming the key path and the allowed values (exit code 2). A parameter table file (a document
    with `classes` but no `inputs`) is checked as a table.
    """
    from brdfcorr.config import ConfigError, load_config
    from brdfcorr.io_utils import parse_yaml
    from brdfcorr.params import ParameterTable
    from brdfcorr.pipeline import plan_run

    overrides = _overrides(settings)
    for chain in chains:
        try:
            document = parse_yaml(chain.read_text(), str(chain), ConfigError)
        except (OSError, ConfigError):
            document = None  # load_config reports it
        if isinstance(document, dict) and "classes" in document and "inputs" not in document:
            table = ParameterTable.load(chain)
            click.echo(f"{chain}: valid parameter table; classes {', '.join(map(str, table.class_ids))}")
            continue
        plan = plan_run(load_config(chain, overrides), require_inputs=False)
        for warning in plan.warnings:
            click.echo(f"brdfcorr: warning: {chain}: {warning}", err=True)
        missing = [scene for scene in plan.scenes if scene.action == "fail"]
        for scene in missing:
            click.echo(f"brdfcorr: warning: {chain}: scene {scene.name}: {scene.reason}", err=True)
        incomplete = f" ({len(missing)} with missing inputs)" if missing else ""
        click.echo(f"{chain}: valid; {len(plan.scenes)} scenes found{incomplete}, "
                   f"steps {', '.join(plan.steps) or '(none)'}")


def _refuse_overwriting_inputs(outputs: dict[str, Path | None], inputs) -> None:
    """InputError if an output option names one of the command's input files."""
    from brdfcorr.errors import InputError

    given = {Path(path).resolve() for path in inputs if path is not None}
    for option, path in outputs.items():
        if path is not None and Path(path).resolve() in given:
            raise InputError(f"{option} {path} is also an input; inputs are never overwritten")


def _assignments(option: str, items: tuple[str, ...], ranges: bool = False) -> dict:
    """Parse ``NAME=VALUE`` (or ``NAME=LOW:HIGH`` with ``ranges``) command-line items."""
    from brdfcorr.errors import ParameterError

    parsed = {}
    for item in items:
        name, _, text = item.partition("=")
        try:
            value = tuple(float(part) for part in text.split(":")) if ranges else float(text)
            if ranges and len(value) != 2:
                raise ValueError
        except ValueError:
            form = "NAME=LOW:HIGH" if ranges else "NAME=VALUE"
            raise ParameterError(f"{option} {item!r}: expected {form} with numbers") from None
        parsed[name.strip()] = value
    return parsed


def _options(option: str, items: tuple[str, ...]) -> dict[str, object]:
    """Parse ``KEY=VALUE`` items; values are read as YAML scalars (``20`` -> 20, ``B04`` -> "B04")."""
    from brdfcorr.errors import ParameterError
    from brdfcorr.io_utils import parse_yaml

    parsed = {}
    for item in items:
        key, separator, text = item.partition("=")
        if not separator or not key.strip():
            raise ParameterError(f"{option} {item!r}: expected KEY=VALUE")
        try:
            parsed[key.strip()] = parse_yaml(text, option, ParameterError) if text.strip() else ""
        except ParameterError:  # not a YAML scalar: the text itself
            parsed[key.strip()] = text
    return parsed


def _pairs(option: str, items: tuple[str, ...]) -> dict[int, str]:
    """Parse ``ID=TEXT`` command-line items into {id: text}."""
    from brdfcorr.errors import ParameterError

    parsed = {}
    for item in items:
        key, _, text = item.partition("=")
        if not key.strip().isdigit() or not text.strip():
            raise ParameterError(f"{option} {item!r}: expected CLASS_ID=VALUE, e.g. 2=grass")
        parsed[int(key)] = text.strip()
    return parsed


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

    from brdfcorr import io as rio_io
    from brdfcorr.classfit import ClassFitWarning, GuardRails, fit_classes
    from brdfcorr.errors import InputError
    from brdfcorr.io_utils import atomic_path
    from brdfcorr.materials import load_material

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
        image = rio_io.open_image(image_path)
        layers = rio_io.open_angles(angle_path)
        class_map = rio_io.open_classes(class_path)
        rio_io.check_same_grid({"image": image, "classes": class_map, **layers})
        rio_io.check_angles(layers)
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
        from brdfcorr.plotting import plot_class_fit

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

    from brdfcorr.fit import FitWarning, fit_measurements, spectral_table_entry
    from brdfcorr.io_utils import atomic_path
    from brdfcorr.measurements import filter_measurements, read_measurements, selection_mask
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
        from brdfcorr.fit_plots import plot_azimuth, plot_principal_plane

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


def _reference_sza(value: str | None):
    """--ref-sza: a zenith [deg] or 'mean' / 'observed' (validated by ReferenceGeometry)."""
    if value is None or value in ("mean", "observed"):
        return value
    try:
        return float(value)
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a number, 'mean' or 'observed'") from None


@main.command("correct")
@click.argument("image", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--angles", type=click.Path(dir_okay=False, path_type=Path),
              help="4-band raster of sza, saa, vza, vaa [deg] on the image grid.")
@click.option("--angles-kind", type=click.Choice(["geotiff", "envi_obs", "sentinel2", "landsat", "solar"]),
              default="geotiff", show_default=True,
              help="What --angles is: a 4-band GeoTIFF, an ENVI obs file (AVIRIS-NG/-3), a Sentinel-2 "
                   "MTD_TL.xml, a Landsat C2 angle band (…_SZA.TIF) or, for 'solar', a UTC time.")
@click.option("--angle-option", "angle_option", multiple=True, metavar="KEY=VALUE",
              help="Option of the angle reader (repeatable), e.g. band=B04, resolution=20, "
                   "ang=LC08_..._ANG.txt.")
@click.option("--sza", type=click.Path(dir_okay=False, path_type=Path), help="Solar zenith raster [deg].")
@click.option("--saa", type=click.Path(dir_okay=False, path_type=Path), help="Solar azimuth raster [deg].")
@click.option("--vza", type=click.Path(dir_okay=False, path_type=Path), help="View zenith raster [deg].")
@click.option("--vaa", type=click.Path(dir_okay=False, path_type=Path), help="View azimuth raster [deg].")
@click.option("--classes", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Class map raster (ids of the parameter table; 0 = no class).")
@click.option("--params", "params_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Parameter table (YAML).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Output GeoTIFF.")
@click.option("--ref-sza", help="Reference sun zenith [deg], 'mean' or 'observed' [default: table, else observed].")
@click.option("--ref-vza", type=float, help="Reference view zenith [deg] [default: table, else 0].")
@click.option("--ref-raa", type=float, help="Reference relative azimuth [deg] [default: table, else 0].")
@click.option("--limits", nargs=2, type=float, default=(0.2, 5.0), show_default=True,
              help="Lower and upper limit of the correction factor.")
@click.option("--no-limits", is_flag=True, help="Do not limit the correction factor.")
@click.option("--unknown", type=click.Choice(["keep", "nan"]), default="keep", show_default=True,
              help="Pixels of class 0 or of classes not in the table: keep unchanged, or set to NaN.")
@click.option("--wavelengths", help="Band centres [nm], comma-separated (overrides the image's).")
@click.option("--extrapolate", is_flag=True, help="Allow band centres outside a class's table wavelengths.")
@click.option("--flip-view-azimuth", is_flag=True,
              help="View azimuths are stored as seen from the sensor: add 180 deg.")
@click.option("--qa", "qa_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write the QA flags (uint8) to this GeoTIFF.")
@click.option("--compress", default="deflate", show_default=True, help="GDAL compression.")
@click.option("--cog", is_flag=True, help="Write Cloud-Optimized GeoTIFFs.")
@click.option("--chunk", type=int, help="Chunk and tile size [pixels] [default: 512, less for many bands].")
@click.option("--progress/--no-progress", default=None, help="Progress bar [default: on a terminal].")
@click.option("--overwrite", is_flag=True, help="Replace existing outputs (-o, --qa) [default: refuse].")
@handle_errors
def correct_command(image, angles, angles_kind, angle_option, sza, saa, vza, vaa, classes, params_path, output, ref_sza, ref_vza,
                    ref_raa, limits, no_limits, unknown, wavelengths, extrapolate, flip_view_azimuth,
                    qa_path, compress, cog, chunk, progress, overwrite):
    """Normalize IMAGE to a reference sun/view geometry with per-class BRDF models.

    Outputs are written to temporary names beside them and renamed when complete; an existing
    output is replaced only with --overwrite, and an input never.
    """
    import time

    from brdfcorr.correct import correct_files
    from brdfcorr.params import ParameterTable

    table = ParameterTable.load(params_path)
    reference = table.reference.model_dump() if table.reference else {}
    for key, value in (("sza", _reference_sza(ref_sza)), ("vza", ref_vza), ("raa", ref_raa)):
        if value is not None:
            reference[key] = value
    if wavelengths is not None:
        try:
            wavelengths = [float(value) for value in wavelengths.split(",")]
        except ValueError:
            raise click.BadParameter(f"{wavelengths!r} is not a comma-separated list of numbers",
                                     param_hint="--wavelengths") from None
    if progress is None:
        progress = sys.stderr.isatty()
    callbacks = []
    if progress:
        from tqdm.dask import TqdmCallback

        callbacks.append(TqdmCallback(desc="correct", leave=False))
    start = time.perf_counter()
    summary = correct_files(
        image, output, params=table, angles=angles, sza=sza, saa=saa, vza=vza, vaa=vaa,
        classes=classes, reference=reference, qa_output=qa_path, wavelengths=wavelengths,
        extrapolate=extrapolate, limits=None if no_limits else limits, unknown=unknown,
        flip_view_azimuth=flip_view_azimuth, chunks=chunk, compress=compress, cog=cog,
        callbacks=callbacks, table_source=str(params_path), angles_kind=angles_kind,
        angle_options=_options("--angle-option", angle_option), overwrite=overwrite,
    )
    click.echo(
        f"wrote {output}: {summary['corrected']} pixels corrected, {summary['limited']} limited, "
        f"{summary['unknown_class']} unknown class, {summary['no_class']} no class, "
        f"{summary['nodata']} nodata ({summary['reference'].describe()}) in "
        f"{time.perf_counter() - start:.1f} s"
    )


# ------------------------------------------------------------------------------------------------
# brdfcorr analyze: the papers' own analyses (library: brdfcorr.analysis, brdfcorr.simulate)
# ------------------------------------------------------------------------------------------------


def _zenith_list(value: str) -> list[float]:
    try:
        return [float(item) for item in value.split(",") if item.strip()]
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a comma-separated list of angles [deg]") from None


def _save_figure(figure, target: Path) -> None:
    from brdfcorr.io_utils import atomic_path

    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(target) as temporary:
        figure.savefig(temporary, dpi=110, format=target.suffix.lstrip(".") or "png")
    click.echo(f"wrote {target}")


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
    from brdfcorr.analysis import PAPER_SHADOWING_TEXT, WORST_CASE_PARAMS, shadowing_impact
    from brdfcorr.materials import load_material, material_names

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
    from brdfcorr.analysis import width_reduction
    from brdfcorr.materials import load_material, material_names

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
        from brdfcorr.analysis_plots import plot_azimuthal_widths

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
    import math
    import warnings

    from brdfcorr.analysis import albedo, specular_albedo_bound
    from brdfcorr.materials import load_material

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

    from brdfcorr.analysis_plots import plot_figure2

    if not view_step > 0:
        raise click.BadParameter("must be > 0", param_hint="--view-step")
    view = np.arange(0.0, 85.0 + 1e-9, view_step)
    _save_figure(plot_figure2(view, step_fraction=step_fraction), output)


@analyze_group.command("polar")
@click.argument("name")
@click.option("--sza", "zeniths", default="30,50,65", show_default=True, help="Illumination zeniths [deg].")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Output image [default: polar_NAME.png].")
@handle_errors
def analyze_polar_command(name, zeniths, output):
    """Polar plots of a material's BRDF over the view hemisphere."""
    from brdfcorr.analysis_plots import plot_polar
    from brdfcorr.materials import load_material

    material = load_material(name)
    _save_figure(plot_polar(material, _zenith_list(zeniths)), output or Path(f"polar_{material.name}.png"))
