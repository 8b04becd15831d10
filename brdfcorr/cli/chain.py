"""``brdfcorr demo``, ``run`` and ``validate``: processing chains (library: brdfcorr.chain.run)."""

from __future__ import annotations

import sys
from pathlib import Path

import click
from tqdm import tqdm

from brdfcorr.cli._base import (
    EXIT_BAD_INPUT,
    EXIT_SCENES_FAILED,
    _format_table,
    handle_errors,
    main,
)
from brdfcorr.errors import ConfigError, InputError
from brdfcorr.io.files import parse_yaml, read_document

# The library (dask, rasterio, scipy, matplotlib) is imported when a command runs, not when its
# options are parsed: --help and argument errors answer at once.


@main.command("demo")
@click.option(
    "-o", "--output-dir", type=click.Path(file_okay=False, path_type=Path), default="demo_output",
    show_default=True, help="Directory for the demo outputs.",
)
@click.option("--config", "config_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Chain config to run on the demo scene [default: the demo chain, configs/demo.yaml].")
@click.option("--progress/--no-progress", default=None, help="Progress bar [default: on a terminal].")
@handle_errors
def demo_command(output_dir: Path, config_path, progress):
    """Build a demo airborne line, correct it with the demo chain and write a before/after picture.

    Writes OUTPUT_DIR/scene/ (image, angles, classes), OUTPUT_DIR/corrected/ (corrected GeoTIFF,
    QA, assessment report and profile figure, before/after quicklook, run report),
    OUTPUT_DIR/demo.yaml (the chain, rerun with `brdfcorr run`) and OUTPUT_DIR/materials_brdf.png.
    """
    from brdfcorr.chain.demo import run_demo

    with _chain_progress(progress, "demo") as callback:
        result = run_demo(output_dir, config_path, progress=callback)
    _echo_run(result.report)
    for figure in result.figures:
        click.echo(f"wrote {figure}")
    if not result.report.ok:
        sys.exit(EXIT_SCENES_FAILED)


# ------------------------------------------------------------------------------------------------
# brdfcorr run / validate: chain configs (library: brdfcorr.chain.config, brdfcorr.chain.run)
# ------------------------------------------------------------------------------------------------

def _overrides(items: tuple[str, ...]) -> dict:
    """``--set KEY=VALUE`` items: dotted config keys, values read as YAML (``engine.workers=2``)."""
    parsed = {}
    for item in items:
        key, sign, text = item.partition("=")
        if not sign or not key.strip():
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. engine.workers=2")
        parsed[key.strip()] = parse_yaml(text, f"--set {item!r}", ConfigError)
    return parsed


class _chain_progress:
    """Context manager giving a ``progress(event, info)`` callback that drives an overall tqdm bar
    over the scenes and, below it, a bar over the dask tasks of the scene being processed, from
    its first pass (the ``chunks`` events of the threads and synchronous engines: counts that grow
    pass by pass), on a terminal or when asked."""

    def __init__(self, enabled, description: str):
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.description = description
        self.bar = None
        self.chunks = None
        self.scene = None

    def __enter__(self):
        return self.callback

    def callback(self, event: str, info: dict) -> None:
        if not self.enabled:
            return
        if event == "plan":
            self.bar = tqdm(total=info["scenes"], desc=self.description, unit="scene", file=sys.stderr)
        elif event == "fit" and self.bar is not None:
            self.bar.write(f"fit: {len(info.get('classes', []))} classes")
        elif event == "chunks":
            self._chunks(info)
        elif event == "scene" and self.bar is not None:
            self._close_chunks()
            self.bar.set_postfix_str(f"{info['scene']}: {info['status']}")
            self.bar.update(1)

    def _chunks(self, info: dict) -> None:
        if self.chunks is None or self.scene != info["scene"]:  # the scene's first pass
            self._close_chunks()
            self.scene = info["scene"]
            self.chunks = tqdm(total=info["total"], desc=info["scene"], unit="task", leave=False,
                               position=1, file=sys.stderr)
        elif self.chunks.total != info["total"]:  # its next pass: more tasks
            self.chunks.total = info["total"]
        self.chunks.update(info["done"] - self.chunks.n)

    def _close_chunks(self) -> None:
        if self.chunks is not None:
            self.chunks.close()
            self.chunks = None
        self.scene = None

    def __exit__(self, *exc):
        self._close_chunks()
        if self.bar is not None:
            self.bar.close()
        return False


def _scenes(count: int) -> str:
    """``1 scene``, ``2 scenes``, ``0 scenes``."""
    return f"{count} scene" if count == 1 else f"{count} scenes"


def _number(value, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}g}"


def _echo_fit(fit: dict | None) -> None:
    """The fit step's classes: model, status, samples, median R^2 and, for a class that failed the
    guard rails, why (the run report has the parameters)."""
    classes = (fit or {}).get("classes") or []
    if not classes or not isinstance(classes[0], dict) or "status" not in classes[0]:
        return
    click.echo("fit:")
    click.echo(_format_table([{
        "class": str(entry["class_id"]), "name": str(entry["name"]), "model": str(entry["model"]),
        "status": str(entry["status"]), "samples": str(entry.get("n_samples", "-")),
        "median R2": _number(entry.get("median_r2")), "reasons": "; ".join(entry.get("reasons") or []),
    } for entry in classes]))


def _echo_assessment(report) -> None:
    """Each assessed scene's classes: median |relative slope| [%/10 deg] before and after."""
    rows = []
    for result in report.scenes:
        for entry in result.get("assess") or []:
            medians = entry["median_abs_relative_slope_percent_per_10deg"]
            rows.append({"scene": result["scene"], "class": f"{entry['id']} ({entry['name']})",
                         "pixels": str(entry["pixels"]), "|slope| before": _number(medians["before"]),
                         "|slope| after": _number(medians["after"])})
    if rows:
        click.echo("assessment (median |relative slope| over bands, %/10 deg):")
        click.echo(_format_table(rows))


def _echo_run(report) -> None:
    _echo_fit(report.fit)
    _echo_assessment(report)
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
    from brdfcorr.chain.config import load_config
    from brdfcorr.chain.run import plan_run, run_chain

    if resume and overwrite:
        raise InputError("--resume and --overwrite exclude each other")
    overrides = _overrides(settings)
    if resume or overwrite:
        overrides["outputs.existing"] = "skip" if resume else "overwrite"
    config = load_config(chain, overrides)
    plan = plan_run(config, require_inputs=not dry_run)
    if dry_run:
        if not plan.scenes:  # an empty batch is refused by the run: the dry run says so, with its line and exit code 2
            plan_run(config)  # raises the run's InputError (inputs.images matches no file)
        _echo_plan(plan)
        return
    for warning in plan.warnings:
        click.echo(f"brdfcorr: warning: {warning}", err=True)
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
    click.echo(f"{_scenes(len(rows))}: {counts['run']} to run, {counts['skip']} to skip, {counts['fail']} would fail")


@main.command("validate")
@click.argument("chains", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE", help="Override a config key (as for run).")
@click.option("--strict", is_flag=True,
              help="Inputs that do not exist (images, class maps, angles, table, measurements), and scenes "
                   "that would fail (a product folder without a band), are errors (exit 2), as for run; without "
                   "it a chain checked before its data exist is told apart by its summary line.")
@handle_errors
def validate_command(chains, settings, strict):
    """Check chain configs without running them: keys, values, names, patterns, parameter table.

    The checks are those of `run` (its plan): what `run` refuses is an error here too (exit code
    2), e.g. a malformed config (naming the key path and the allowed values), an image glob
    matching no file in an existing folder, quicklook bands beyond an image's band count. Inputs
    that do not exist yet (a folder not made yet, a class map, a table) and scenes that would fail
    (a product folder without a band) are warnings, and the
    chain's line says it is not ready to run, naming the first missing input, instead of "valid"
    (a template, such as the example chains in configs/); with --strict they are errors (exit 2).
    A parameter table file (a document with `classes` but no `inputs`) is checked as a table.
    """
    overrides = _overrides(settings)
    not_ready = []
    for chain in chains:
        # Parsed before the library is imported: a malformed document is refused at once.
        document = parse_yaml(read_document(chain, "chain config", ConfigError), str(chain), ConfigError)
        if isinstance(document, dict) and "classes" in document and "inputs" not in document:
            from brdfcorr.params import ParameterTable

            table = ParameterTable.from_dict(document, source=str(chain))
            if not table.classes:
                raise InputError(f"{chain}: the parameter table has no classes: nothing would be corrected")
            click.echo(f"{chain}: valid parameter table; classes {', '.join(map(str, table.class_ids))}")
            continue
        from brdfcorr.chain.config import config_from_document
        from brdfcorr.chain.plan import plan_run

        plan = plan_run(config_from_document(document, chain, overrides), require_inputs=False)
        missing = plan.missing_inputs()
        # A scene that would fail for another reason (a product folder without a band) is not ready either.
        missing += [f"scene {scene.name} would fail: {scene.reason}" for scene in plan.scenes
                    if scene.action == "fail" and not any(m.startswith(f"scene {scene.name}:") for m in missing)]
        kind = "error" if strict else "warning"
        for warning in [*missing, *(w for w in plan.warnings if w not in plan.missing)]:
            click.echo(f"brdfcorr: {kind if warning in missing else 'warning'}: {chain}: {warning}", err=True)
        steps = f"steps {', '.join(plan.steps) or '(none)'}"
        if not missing:
            click.echo(f"{chain}: valid; {_scenes(len(plan.scenes))} found, {steps}")
            continue
        more = f" (and {len(missing) - 1} more, above)" if len(missing) > 1 else ""
        click.echo(f"{chain}: not ready to run, an input is missing: {missing[0]}{more}; "
                   f"its keys and values are valid ({_scenes(len(plan.scenes))} found, {steps})")
        not_ready.append(chain)
    if strict and not_ready:
        sys.exit(EXIT_BAD_INPUT)


