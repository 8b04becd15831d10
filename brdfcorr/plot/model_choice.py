"""The figure of a choice of model by held-out error (``--model auto``): one bar per candidate."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from brdfcorr.fit.selection import ModelChoice

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["plot_model_choice"]


def plot_model_choice(choice: ModelChoice, title: str = "") -> Figure:
    """Each candidate's mean held-out error over the folds with its 1-sigma spread (left) and its
    held-out R^2 (right), the chosen model's bars filled, the others outlined; a candidate that
    could not be fitted is named with a cross.

    Parameters
    ----------
    choice : ModelChoice
        :func:`brdfcorr.fit.selection.choose_model` or
        :func:`~brdfcorr.fit.selection.choose_class_model`'s result.
    title : str, optional
        What was fitted (the sample, the class); the rule and folds follow it.
    """
    rows = choice.rows()
    names = [f"{row['model']} ({row['n_free']})" for row in rows]
    position = np.arange(len(rows))
    error = np.array([np.nan if row["mean_error"] is None else row["mean_error"] for row in rows], float)
    spread = np.array([row["fold_sd"] or 0.0 for row in rows], float)
    r2 = np.array([np.nan if row["heldout_r2"] is None else row["heldout_r2"] for row in rows], float)
    chosen = np.array([row["chosen"] for row in rows])
    from matplotlib.figure import Figure  # at first use: a run that draws nothing imports no matplotlib
    figure = Figure(figsize=(9.0, 0.5 * len(rows) + 2.0), layout="constrained")
    left, right = figure.subplots(1, 2, sharey=True)
    for axis, values, label in ((left, error, "held-out mean squared error (weighted)"),
                                (right, r2, "held-out R$^2$")):
        axis.barh(position, np.nan_to_num(values), color=np.where(chosen, "C0", "none"), edgecolor="C0",
                  xerr=spread if axis is left else None, capsize=3)
        axis.set_xlabel(label)
        for index in np.flatnonzero(~np.isfinite(values)):
            axis.plot(0, index, "x", color="C3")
    left.set_yticks(position, names)
    left.invert_yaxis()
    left.set_xscale("log" if np.nanmin(error) > 0 and np.nanmax(error) > 20 * np.nanmin(error) else "linear")
    right.set_xlim(min(0.0, float(np.nanmin(r2)) if np.isfinite(r2).any() else 0.0), 1.0)
    heading = f"{title}: " if title else ""
    figure.suptitle(f"{heading}{choice.chosen} chosen (one-standard-error rule, {choice.folds} folds over "
                    f"{choice.grouping}); free parameters in brackets", fontsize="medium")
    return figure
