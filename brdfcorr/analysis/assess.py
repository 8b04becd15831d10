"""Did the BRDF correction work? Standard measures of the view-angle signal left in a scene.

A BRDF correction should take the view-angle dependence out of each class: the same roof, lawn or
field should have the same reflectance at either edge of a flight line, and two overlapping lines
should agree where they overlap. This module measures that, before and after a correction, per
class and band:

- :func:`assess_view_angles`: the least-squares slope of reflectance against the *signed* view
  zenith (:func:`signed_view_zenith`), absolute [1/deg] and relative [%/10 deg]; the ratio of the
  mean reflectance on the positive side of nadir to that on the negative side (forward/backward
  scattering, or right/left of the flight direction); and the across-track profile, the mean
  reflectance in bins of signed view zenith. One chunk-wise pass over the before and after cubes
  (dask: per-block sums, added in a tree, one compute); how it measures (sign convention, classes,
  bins): :class:`ViewAngleOptions`.
- :func:`assess_overlap`: for two overlapping lines, the difference in the overlap (other line minus
  this one, on this line's grid via rioxarray's ``reproject_match``): RMSE, mean absolute
  difference and bias per band, before and after, with a histogram and a small map of the
  difference.
- :func:`leave_one_line_out`: for N lines, fit the parameters on N - 1 of them
  (:func:`brdfcorr.fit.fit_classes`), correct the held-out line with them
  (:func:`brdfcorr.normalize`) and assess it: a test of the correction on data its parameters
  never saw (the fit and the correction: :class:`HoldoutFit`).

This module gathers them; they live in :mod:`brdfcorr.analysis.view_angles`,
:mod:`brdfcorr.analysis.overlap` and :mod:`brdfcorr.analysis.holdout` (leave one line out), with
the dataset and report conventions they share in :mod:`brdfcorr.analysis._assess_common`.

The files' versions (``brdfcorr assess``, ``brdfcorr assess-lines``, the chains' assess step) are
in :mod:`brdfcorr.tasks.assess`.

The results are :class:`xarray.Dataset` objects with labelled dims (``stage``: before/after,
``band``, ``class``, ``vza_bin``) and units in their attrs; :func:`view_angle_report` and
:func:`overlap_report` turn them into plain dicts (NaN as ``None``, valid JSON). The figures are in
:mod:`brdfcorr.plot.assess`.
"""

from brdfcorr.analysis._assess_common import STAGES  # noqa: F401  (importable from here as before the split)
from brdfcorr.analysis.holdout import HeldOutLine, HoldoutFit, Line, leave_one_line_out, leave_one_line_out_report
from brdfcorr.analysis.overlap import assess_overlap, overlap_report
from brdfcorr.analysis.signed_view import SIGN_CONVENTIONS, signed_view_zenith
from brdfcorr.analysis.view_angles import ViewAngleOptions, assess_view_angles, view_angle_report

__all__ = [
    "SIGN_CONVENTIONS",
    "signed_view_zenith",
    "ViewAngleOptions",
    "assess_view_angles",
    "view_angle_report",
    "assess_overlap",
    "overlap_report",
    "Line",
    "HeldOutLine",
    "HoldoutFit",
    "leave_one_line_out",
    "leave_one_line_out_report",
]

