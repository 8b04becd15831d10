"""``brdfcorr assess``: did the correction work? (library: :func:`brdfcorr.tasks.assess.assess_files`);
``brdfcorr assess-lines``: leave-one-line-out over flight lines
(:func:`brdfcorr.tasks.assess.leave_one_line_out_files`)."""

from __future__ import annotations

from pathlib import Path

import click

from brdfcorr.cli._base import (
    _format_table,
    handle_errors,
    main,
    progress_bars,
)
from brdfcorr.cli._inputs import (
    prior_setting,
    reference_sza,
)
from brdfcorr.cli._settings import setting_options
from brdfcorr.io.paths import check_outputs, refuse_existing
from brdfcorr.tasks.options import ASSESS, ASSESS_LINES


def _summary_rows(report: dict) -> list[dict[str, str]]:
    """One row per class: pixels, median |relative slope| over bands ± the median of its 1-sigma,
    and median side ratio."""
    import numpy as np

    rows = []
    for entry in report["view_angles"]["classes"]:
        row = {"class": str(entry["id"]), "name": entry["name"], "pixels": str(entry["pixels"])}
        for stage in ("before", "after"):
            slopes = np.abs(np.array(entry[stage]["relative_slope"], dtype=float))
            errors = np.array(entry[stage]["relative_slope_error"], dtype=float)
            ratios = np.array(entry[stage]["side_ratio"], dtype=float)
            error = f" ± {np.nanmedian(errors):.2f}" if np.isfinite(errors).any() else ""
            row[f"|slope| {stage} [%/10deg]"] = (f"{np.nanmedian(slopes):.2f}{error}" if np.isfinite(slopes).any()
                                                 else "-")
            row[f"ratio {stage}"] = f"{np.nanmedian(ratios):.3f}" if np.isfinite(ratios).any() else "-"
        rows.append(row)
    return rows


def _number(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


@main.command("assess")
@click.argument("before", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("after", type=click.Path(dir_okay=False, path_type=Path))
@setting_options(ASSESS)
@handle_errors
def assess_command(before, after, classes, align_classes, class_lookup, angles, angles_kind, angle_option, scale,
                   offset, overlap, class_names, sign_by, heading, bin_width, min_vza, flip_view_azimuth,
                   block_size, cluster_layer, cluster_band, resampling, output, figures_dir, chunk, overwrite,
                   progress):
    """Did the BRDF correction work? View-angle slopes, side ratios, profiles and overlaps, before and after.

    Measures the view-angle signal in BEFORE (the input) and AFTER (the corrected image), per
    class and band: the slope of reflectance against the signed view zenith [%/10 deg] with its
    1-sigma, the ratio of the two sides of nadir (forward/backward scattering) and the across-track
    profiles, before and after; with --overlap, the RMSE, mean absolute difference and bias of two lines where they
    overlap. Writes a JSON report (-o) and PNG figures (--figures).
    """
    from brdfcorr.analysis.assess import ViewAngleOptions
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.plot.assess import figure_paths, write_assessment_figures
    from brdfcorr.tasks.assess import assess_files, write_json
    from brdfcorr.tasks.classmaps import read_lookup
    from brdfcorr.tasks.request import Engine

    if sign_by == "track" and heading is None:
        raise click.UsageError("--sign-by track needs --heading (the flight direction in degrees from north)")
    figures = figure_paths(figures_dir, overlap=bool(overlap)) if figures_dir is not None else []
    inputs = {"BEFORE": before, "AFTER": after, "--classes": classes, "--class-lookup": class_lookup,
              "--angles": None if angles_kind == "solar" else angles, "--clusters": cluster_layer}
    if overlap:
        inputs.update({"OTHER_BEFORE": overlap[0], "OTHER_AFTER": overlap[1]})
    check_outputs({"-o": output, **{f"figure {path}": path for path in figures}}, inputs)
    if not overwrite:
        refuse_existing([output, *figures])
    with progress_bars(progress, "assess"):  # every pass, from the first (the angle check)
        assessment = assess_files(
            SceneSources(before, classes, angles, angles_kind=angles_kind,
                         angle_options=dict(angle_option), scale=scale, offset=offset),
            after, overlap=tuple(overlap) if overlap else None, resampling=resampling,
            clusters=None if cluster_layer is None else (cluster_layer, cluster_band),
            view_options=ViewAngleOptions(by=sign_by, heading=heading,
                                          class_names=dict(class_names), bin_width=bin_width,
                                          min_vza=min_vza, flip_view_azimuth=flip_view_azimuth,
                                          block_size=block_size),
            align_classes=align_classes, class_lookup=read_lookup(class_lookup) if class_lookup else None,
            engine=Engine(chunks=chunk),
        )
    report = assessment.report()
    # The figures first, the report last: a figure that fails leaves no report that looks complete,
    # and a report that fails takes the figures of this run with it.
    written = (write_assessment_figures(assessment, figures_dir, title=Path(before).stem)
               if figures_dir is not None else [])
    try:
        write_json(report, output)
    except BaseException:
        for path in written:
            Path(path).unlink(missing_ok=True)
        raise
    click.echo(_format_table(_summary_rows(report)))
    within = report["view_angles"]["summary"]["slopes_within_2_sigma"]
    click.echo(f"slopes within 2 sigma of 0 (class x band): {within['before']} of {within['of']} before, "
               f"{within['after']} of {within['of']} after")
    if report["overlap"] is not None:
        summary = report["overlap"]["summary"]
        before_rmse, after_rmse = (summary[f"median_relative_rmse_percent_{stage}"] for stage in ("before", "after"))
        click.echo(f"overlap ({report['overlap']['pixels']} pixels): median relative RMSE "
                   f"{_number(before_rmse)} % before, {_number(after_rmse)} % after")
    click.echo(f"wrote {output}")
    for path in written:
        click.echo(f"wrote {path}")


def _held_out_rows(line: dict) -> list[dict[str, str]]:
    """One held-out line of the leave-one-line-out report as rows: the largest |relative slope|
    over classes and bands and how many slopes lie within 2 sigma of 0, then the median relative
    overlap RMSE over bands with each neighbour."""
    slope = line["view_angles"]["summary"]["abs_relative_slope_percent_per_10deg"]
    within = line["view_angles"]["summary"]["slopes_within_2_sigma"]
    rows = [{"measure": "largest |relative slope| [%/10deg]", "before": _number(slope["before"]["max"]),
             "after": _number(slope["after"]["max"])},
            {"measure": f"slopes within 2 sigma of 0 (of {within['of']})",
             **{stage: str(within[stage]) for stage in ("before", "after")}}]
    for neighbour, overlap in line["overlaps"].items():
        summary = overlap["summary"]
        rows.append({"measure": f"overlap with {neighbour} ({overlap['pixels']} px): relative RMSE [%]",
                     **{stage: _number(summary[f"median_relative_rmse_percent_{stage}"])
                        for stage in ("before", "after")}})
    return rows


def _reference_line(reference: dict) -> str:
    """The reference geometry of the leave-one-line-out report (``reference`` of a line) in words."""
    sza, source = reference["sza"], reference["sza_from"]
    sun = {"observed": "each pixel's own sun zenith", "hls": "each line's HLS sun zenith"}.get(
        source, f"sun zenith {sza:.4g} deg ({'the mean of the lines' if source == 'mean of the lines' else 'fixed'})")
    return f"held-out lines and their overlaps corrected to {sun}, view zenith {reference.get('vza', 0.0):g} deg"


@main.command("assess-lines")
@click.argument("images", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@setting_options(ASSESS_LINES)
@handle_errors
def assess_lines_command(images, classes, align_classes, class_lookup, angles, angles_kind, angle_option, scale,
                         offset, model_name, class_model, class_names, fix, prior, prior_spread, max_samples, seed,
                         ref_sza, sign_by, heading, flip_view_azimuth, block_size, cluster_layers, cluster_band, output,
                         chunk, overwrite):
    """Leave-one-line-out: fit on the other flight lines, correct and assess each held-out line.

    For each of IMAGES (at least 2 flight lines, each with its --classes and --angles, in the same
    order), fits per-class parameters on the other lines (as `brdfcorr fit-classes`), corrects the
    held-out line with them and measures its view-angle slopes and its overlaps with the other
    lines, before and after (as `brdfcorr assess`): a test of the correction on data its
    parameters never saw. Prints a table per held-out line and writes a JSON report (-o).
    """
    from brdfcorr.analysis.assess import HoldoutFit, ViewAngleOptions
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.assess import check_line_files, leave_one_line_out_files, write_json
    from brdfcorr.tasks.classmaps import read_lookup

    if sign_by == "track" and heading is None:
        raise click.UsageError("--sign-by track needs --heading (the flight direction in degrees from north)")
    shape_prior = prior_setting(prior, prior_spread)
    check_line_files(images, classes, angles)
    check_outputs({"-o": output}, [*(("IMAGES", path) for path in images), *(("--classes", path) for path in classes),
                                   *(("--angles", path) for path in angles if angles_kind != "solar"),
                                   *(("--clusters", path) for path in cluster_layers),
                                   ("--class-lookup", class_lookup)])
    if not overwrite:
        refuse_existing([output])
    sza = reference_sza(ref_sza)
    options = dict(angle_option)
    assessment = leave_one_line_out_files(
        [SceneSources(image, class_map, angle_source, angles_kind=angles_kind, angle_options=options, scale=scale,
                      offset=offset) for image, class_map, angle_source in zip(images, classes, angles)],
        HoldoutFit(model_name, class_models=dict(class_model),
                   fixed=dict(fix) or None, max_samples=max_samples, seed=seed,
                   reference={"sza": "mean" if sza is None else sza, "vza": 0.0}, prior=shape_prior),
        view_options=ViewAngleOptions(by=sign_by, heading=heading, class_names=dict(class_names),
                                      flip_view_azimuth=flip_view_azimuth, block_size=block_size),
        align_classes=align_classes, class_lookup=read_lookup(class_lookup) if class_lookup else None, chunks=chunk,
        clusters=[(path, cluster_band) for path in cluster_layers] or None,
    )
    report = assessment.report()
    write_json(report, output)
    click.echo(_reference_line(report["lines"][0]["reference"]))
    click.echo()
    for line in report["lines"]:
        training = ", ".join(entry["name"] for entry in report["inputs"] if entry["name"] != line["held_out"])
        click.echo(f"{line['held_out']} (parameters fitted on {training})")
        click.echo(_format_table(_held_out_rows(line)))
        click.echo()
    click.echo(f"wrote {output}")
