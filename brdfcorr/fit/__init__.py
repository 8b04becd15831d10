"""Fitting model parameters: to goniometer measurements and, class by class, to imagery.

- :mod:`brdfcorr.fit.measurements`: goniometer measurement tables (CSV), selection, synthesis.
- :mod:`brdfcorr.fit.goniometer`: weighted non-linear least squares as in paper 003 (``fit_brdf``,
  with its ``ErrorAnalysis`` options).
- :mod:`brdfcorr.fit.results`: the result of those fits (``FitResult``) and the parameter-table
  entries and report rows made from it.
- :mod:`brdfcorr.fit.identifiability`: covariance, correlations and identifiability messages of
  those fits.
- :mod:`brdfcorr.fit.sampling`: pooling and sampling each class's pixels from scenes.
- :mod:`brdfcorr.fit.solver`: the variable-projection solver of a class fit (shape shared by the
  bands, intensities per band; one linear pass for models without shape parameters).
- :mod:`brdfcorr.fit.sandwich`: the joint, cluster-robust sandwich covariance of a class fit.
- :mod:`brdfcorr.fit.classes`: class-pooled fits from imagery with guard rails (``fit_classes``, with
  its ``ClassModels``, ``Sampling`` and ``GuardRails`` options).
"""

from brdfcorr.fit import goniometer as _goniometer
from brdfcorr.fit.classes import ClassFitResult, ClassModels, GuardRails, Sampling, fit_classes
from brdfcorr.fit.goniometer import *  # noqa: F403  (the names of goniometer.__all__: fit_brdf, FitResult, ...)
from brdfcorr.fit.measurements import Measurements, read_measurements

__all__ = [
    *_goniometer.__all__, "fit_classes", "ClassModels", "Sampling", "GuardRails", "ClassFitResult", "Measurements",
    "read_measurements",
]
