"""Fitting model parameters: to goniometer measurements and, class by class, to imagery.

- :mod:`brdfcorr.fit.measurements`: goniometer measurement tables (CSV), selection, synthesis.
- :mod:`brdfcorr.fit.goniometer`: weighted non-linear least squares as in paper 003 (``fit_brdf``).
- :mod:`brdfcorr.fit.identifiability`: covariance, correlations and identifiability messages of
  those fits.
- :mod:`brdfcorr.fit.sampling`: pooling and sampling each class's pixels from scenes.
- :mod:`brdfcorr.fit.solver`: the variable-projection solver of a class fit (shape shared by the
  bands, intensities per band; one linear pass for models without shape parameters).
- :mod:`brdfcorr.fit.classes`: class-pooled fits from imagery with guard rails (``fit_classes``).
"""

from brdfcorr.fit.classes import ClassFitResult, fit_classes
from brdfcorr.fit.goniometer import (
    FitResult,
    FitWarning,
    NonIdentifiableWarning,
    fit_brdf,
    fit_measurements,
    fit_wavelengths,
    format_with_error,
    spectral_table_entry,
)
from brdfcorr.fit.measurements import Measurements, read_measurements

__all__ = [
    "FitResult",
    "FitWarning",
    "NonIdentifiableWarning",
    "fit_brdf",
    "fit_measurements",
    "fit_wavelengths",
    "format_with_error",
    "spectral_table_entry",
    "fit_classes",
    "ClassFitResult",
    "Measurements",
    "read_measurements",
]
