"""Leave one line out: a test of the correction on data its parameters never saw.

For N flight lines, :func:`leave_one_line_out` fits the parameters on N - 1 of them
(:func:`brdfcorr.fit.fit_classes`), corrects the held-out line with them
(:func:`brdfcorr.normalize`) and assesses it (:func:`brdfcorr.analysis.view_angles.assess_view_angles`,
and :func:`brdfcorr.analysis.overlap.assess_overlap` against the lines it overlaps).
:func:`leave_one_line_out_report` turns the results into a plain dict (valid JSON).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import xarray as xr

from brdfcorr.analysis.overlap import _overlaps, assess_overlap, overlap_report
from brdfcorr.analysis.view_angles import assess_view_angles, view_angle_report
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import InputError

__all__ = ["Line", "HeldOutLine", "leave_one_line_out", "leave_one_line_out_report"]


class Line(NamedTuple):
    """One flight line in memory: reflectance (band, y, x) [1], class map (y, x) and the angles
    ``sza``, ``saa``, ``vza``, ``vaa`` (y, x) [deg] on its grid (georeferenced for overlaps)."""

    name: str
    reflectance: xr.DataArray
    classes: xr.DataArray
    angles: Mapping[str, xr.DataArray]


@dataclass
class HeldOutLine:
    """One line of :func:`leave_one_line_out`: assessed after a correction with parameters fitted
    on the other lines.

    Attributes
    ----------
    name : str
    table : ParameterTable
        The parameters fitted without this line.
    view : xarray.Dataset
        :func:`assess_view_angles` of the line before and after.
    overlaps : dict of str to xarray.Dataset
        :func:`assess_overlap` against each overlapping other line (both corrected with ``table``).
    fit_report : list of dict
        The fit's per-class report (:meth:`brdfcorr.fit.ClassFitResult.report`).
    """

    name: str
    table: Any
    view: xr.Dataset
    overlaps: dict[str, xr.Dataset] = field(default_factory=dict)
    fit_report: list = field(default_factory=list)


def leave_one_line_out(
    lines: Sequence[Line], model: str = "torrance_sparrow", *, class_models: Mapping[int, str] | None = None,
    names: Mapping[int, str] | None = None, fixed: Mapping[str, float] | None = None,
    reference: Mapping[str, object] | None = None, limits: tuple[float, float] | None = DEFAULT_LIMITS,
    max_samples: int = 50_000, seed: int = 0, by: Literal["sun", "track"] = "sun",
    heading: float | None = None, bin_width: float = 2.0, overlap: bool = True,
    flip_view_azimuth: bool = False,
) -> list[HeldOutLine]:
    """Fit on N − 1 lines, correct the held-out one, assess it: for each of N lines.

    Parameters
    ----------
    lines : sequence of Line
        At least 2 lines (angles by name ``sza``, ``saa``, ``vza``, ``vaa`` [deg]).
    model, class_models, names, fixed, max_samples, seed :
        The imagery fit, as for :func:`brdfcorr.fit.fit_classes` (its default guard rails; a
        class that fails them is left uncorrected).
    reference : mapping, optional
        Reference geometry of the correction (:func:`brdfcorr.normalize`; default: the scene-mean
        sun zenith, nadir view).
    limits : (float, float) or None
        Limits of the correction factor.
    by, heading, bin_width :
        As for :func:`assess_view_angles`.
    overlap : bool, default True
        Also compare the held-out line with every other line it overlaps (both corrected with the
        parameters fitted without it), :func:`assess_overlap`.
    flip_view_azimuth : bool, default False
        ``vaa`` is stored as seen from the sensor.

    Returns
    -------
    list of HeldOutLine
        One per line, in order.
    """
    from brdfcorr.correction import normalize
    from brdfcorr.fit import fit_classes

    if len(lines) < 2:
        raise InputError(f"leave-one-line-out needs at least 2 lines, got {len(lines)}")
    reference = dict(reference) if reference is not None else {"sza": "mean", "vza": 0.0}
    results = []
    for held, line in enumerate(lines):
        training = [other for index, other in enumerate(lines) if index != held]
        fitted = fit_classes([t.reflectance for t in training], [t.classes for t in training],
                             [xr.Dataset(dict(t.angles)) for t in training], model, class_models=class_models,
                             names=names, fixed=fixed, max_samples=max_samples, seed=seed)

        def corrected(target: Line, table=fitted.table) -> xr.DataArray:
            angles = target.angles
            return normalize(target.reflectance, target.classes, angles["sza"], angles["saa"], angles["vza"],
                             angles["vaa"], table, reference, limits=limits,
                             flip_view_azimuth=flip_view_azimuth).reflectance

        after = corrected(line)
        view = assess_view_angles(line.reflectance, after, line.classes, line.angles["vza"], line.angles["vaa"],
                                  line.angles["saa"], by=by, heading=heading, class_names=names,
                                  bin_width=bin_width, flip_view_azimuth=flip_view_azimuth)
        overlaps = {}
        if overlap:
            for other in training:
                if _overlaps(line.reflectance, other.reflectance):
                    overlaps[other.name] = assess_overlap(line.reflectance, after, other.reflectance,
                                                          corrected(other))
        results.append(HeldOutLine(line.name, fitted.table, view, overlaps, fitted.report()))
    return results


def leave_one_line_out_report(results: Sequence[HeldOutLine]) -> dict[str, object]:
    """:func:`leave_one_line_out` as a JSON-serialisable dict: per held-out line its view-angle
    report, its overlap reports by other line, and the fit without it."""
    return {
        "kind": "leave-one-line-out",
        "lines": [{"held_out": result.name, "view_angles": view_angle_report(result.view),
                   "overlaps": {name: overlap_report(data) for name, data in result.overlaps.items()},
                   "fit": result.fit_report} for result in results],
    }
