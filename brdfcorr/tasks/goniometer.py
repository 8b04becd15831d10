"""The fit of a goniometer table on file that the CLI and chains share: :func:`fit_measurement_file`
(``brdfcorr fit``, a chain's goniometer fit), one fit per wavelength, of a named model or of the one
chosen by held-out error (``"auto"``).

It reads the file but prints nothing: the CLI shows its result (:class:`MeasurementFit`), chains
report it. Warnings of the fits are collected into the result (``warnings``), one line each. It
needs scipy's optimizers only, not the raster stack of the imagery fit (:mod:`brdfcorr.tasks.fit`).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdfcorr.defaults import AUTO_MODEL
from brdfcorr.errors import ParameterError
from brdfcorr.fit.goniometer import FitResult, FitWarning, fit_measurements, spectral_table_entry
from brdfcorr.fit.measurements import (
    Measurements,
    MeasurementSelection,
    filter_measurements,
    read_measurements,
    selection_mask,
)
from brdfcorr.fit.selection import GONIOMETER_CANDIDATES, ModelChoice, choose_model, fixed_for, settings_for
from brdfcorr.models import get_model
from brdfcorr.tasks.pool import process_pool

__all__ = ["fit_measurement_file", "MeasurementFit"]


@dataclass(frozen=True)
class MeasurementFit:
    """The fit of one goniometer table (:func:`fit_measurement_file`).

    Attributes
    ----------
    path : Path
        The measurement file.
    everything, fitted : Measurements
        All measurements (of the chosen wavelength) and those selected for the fit.
    keep : ndarray of bool
        Which of ``everything`` were fitted.
    selection : str
        The selection in words ("phi >= 90 deg"), empty when every measurement is fitted.
    results : dict of float or None to FitResult
        One fit per wavelength (key None for a table without wavelengths).
    warnings : list of str
        Identifiability and convergence warnings, prefixed with the wavelength where there are
        several.
    choices : dict of float or None to ModelChoice
        With ``model="auto"``: each wavelength's choice by held-out error (empty otherwise).
    """

    path: Path
    everything: Measurements
    fitted: Measurements
    keep: np.ndarray
    selection: str
    results: dict[float | None, FitResult]
    warnings: list[str] = field(default_factory=list)
    choices: dict[float | None, ModelChoice] = field(default_factory=dict)

    @property
    def source(self) -> str:
        """What was fitted, for the table's ``fit:`` block: ``"brdfcorr fit tiles.csv (torrance_sparrow;
        fixed k=0.25; phi >= 90)"``."""
        first = next(iter(self.results.values()))
        details = [first.model.name]
        if self.choices:
            choice = next(iter(self.choices.values()))
            details[0] += f" chosen by {choice.folds}-fold cross-validation over {choice.grouping}"
        if first.fixed:
            details.append("fixed " + ", ".join(f"{key}={value:g}" for key, value in first.fixed.items()))
        if self.selection:
            details.append(self.selection)
        return f"brdfcorr fit {self.path.name} ({'; '.join(details)})"

    def table_entry(self, class_id: int, name: str) -> dict:
        """The fit as a class of a parameter table (spectral where there are several wavelengths),
        with its ``fit:`` provenance block (:meth:`brdfcorr.fit.FitResult.fit_record`)."""
        if len(self.results) > 1:
            return spectral_table_entry(self.results, class_id, name, self.source)
        return next(iter(self.results.values())).table_entry(class_id, name, self.source)

    def report(self) -> list[dict]:
        """JSON-friendly fits per wavelength: params, errors, reduced chi^2."""
        return [
            {"wavelength": wavelength, "params": dict(result.params),
             "errors": {k: float(v) for k, v in result.errors.items()}, "reduced_chi2": float(result.reduced_chi2)}
            for wavelength, result in self.results.items()
        ]


def _check_candidate_settings(fixed: Mapping[str, float] | None, initial: Mapping[str, float] | None,
                              bounds: Mapping[str, tuple[float, float]] | None) -> None:
    """Before the cross-validation of ``"auto"``: every name of ``fixed``, ``initial`` and
    ``bounds`` is a parameter of a candidate model (else a :class:`~brdfcorr.errors.ParameterError`,
    not one after all the folds' fits: a misspelt ``--fix`` was dropped without a word);
    :func:`~brdfcorr.fit.selection.choose_model` checks that it is the same parameter in each
    candidate that has it."""
    for what, settings in (("fixed value of", fixed), ("starting value of", initial), ("bound of", bounds)):
        for key in dict(settings or {}):
            if not any(key in get_model(name).parameter_names for name in GONIOMETER_CANDIDATES):
                raise ParameterError(f"the {what} {key} is a parameter of none of the models --model auto tries "
                                     f"({', '.join(GONIOMETER_CANDIDATES)})")


def _common_choice(choices: Mapping[float | None, ModelChoice]) -> str:
    """The model of a table's wavelengths: the one most of them chose; among as many, the one with
    the lowest held-out error summed over the wavelengths (not the first: a 1-1 tie went to the
    first wavelength's choice, whatever the other's errors)."""
    chosen = [choice.chosen for choice in choices.values()]
    most = max(map(chosen.count, chosen))

    def summed_error(name: str) -> float:
        errors = [choice.score_of(name).mean_error for choice in choices.values()]
        return math.fsum(errors) if all(math.isfinite(error) for error in errors) else math.inf

    return min(sorted({name for name in chosen if chosen.count(name) == most}), key=summed_error)


def fit_measurement_file(
    path: str | os.PathLike, model: str, *, fixed: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None, bounds: Mapping[str, tuple[float, float]] | None = None,
    select: MeasurementSelection = MeasurementSelection(), progress: Callable[[str], object] | None = None,
    workers: int = 1,
) -> MeasurementFit:
    """Fit a registry model to a goniometer measurement table, one fit per wavelength.

    Parameters
    ----------
    path : path-like
        CSV with columns ``theta_i, theta_r, phi, brdf[, sigma, wavelength]`` [deg, sr^-1]
        (:func:`brdfcorr.fit.measurements.read_measurements`).
    model : str
        Registered surface model, or ``"auto"``: the candidate with the lowest held-out error
        (:func:`brdfcorr.fit.selection.choose_model`, each wavelength; where the wavelengths choose
        differently, the model most of them chose, among as many the one with the lowest summed
        held-out error, fitted at every wavelength, with a note for each wavelength that chose another).
    fixed, initial, bounds :
        As for :func:`brdfcorr.fit.fit_brdf` (paper 003 fixes k = 0.25); with ``"auto"`` each
        applies to the candidates that have the parameter, in the cross-validation and in the fit
        of the chosen model (a name no candidate has is refused before the choice).
    select : MeasurementSelection, optional
        Fit only these measurements: a geometric selection [deg] (paper 003:
        ``MeasurementSelection(min_phi=90)``) and one wavelength [nm] of a table with several.
    progress : callable, optional
        Called as ``progress(model)`` after each fit of a wavelength and, with ``"auto"``, after
        each candidate's cross-validation (a progress bar's update).
    workers : int, default 1
        Processes that fit the candidates' folds of ``"auto"`` side by side (a process pool; the
        choice is the same as with one). Each starts by importing the fits (about a second).
    """
    everything = read_measurements(path)
    if select.wavelength is not None:
        everything = everything.at_wavelength(select.wavelength)
    fitted = filter_measurements(everything, **select.geometry)
    keep, selection = selection_mask(everything, **select.geometry)
    options = {"fixed": fixed or None, "initial": initial or None, "bounds": bounds or None}
    bands = fitted.wavelengths or [None]
    results, notes, choices = {}, [], {}
    if model == AUTO_MODEL:
        _check_candidate_settings(fixed, initial, bounds)
        with process_pool(workers, ("brdfcorr.fit.selection",)) as executor:
            for band in bands:
                subset = fitted if band is None else fitted.at_wavelength(band)
                choices[band] = choose_model(subset, fixed=fixed, initial=initial, bounds=bounds, progress=progress,
                                             executor=executor)
        model = _common_choice(choices)
        notes += [f"{band:.10g} nm: --model auto chose {choice.chosen} here; {model}, the choice over the "
                  "wavelengths, is fitted at every wavelength" for band, choice in choices.items()
                  if choice.chosen != model]
        options = {"fixed": fixed_for(model, fixed) or None, "initial": settings_for(model, initial) or None,
                   "bounds": settings_for(model, bounds) or None}
    for band in bands:
        subset = fitted if band is None else fitted.at_wavelength(band)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FitWarning)
            results[band] = fit_measurements(model, subset, **options)
        if progress is not None:
            progress(model)
        where = "" if band is None or len(bands) == 1 else f"{band:.10g} nm: "
        notes += [f"{where}{w.message}" for w in caught if issubclass(w.category, FitWarning)]
    return MeasurementFit(Path(path), everything, fitted, keep, selection, results, notes, choices)
