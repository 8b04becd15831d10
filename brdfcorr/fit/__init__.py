"""Fitting model parameters: to goniometer measurements and, class by class, to imagery.

- :mod:`brdfcorr.fit.measurements`: goniometer measurement tables (CSV), selection, synthesis.
- :mod:`brdfcorr.fit.goniometer`: weighted non-linear least squares as in paper 003 (``fit_brdf``,
  with its ``ErrorAnalysis`` options; ``fit_from`` one start).
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

from brdfcorr._lazy import attach

#: The public face of the package, imported on first use (PEP 562): name -> module. A chain
#: config's settings (:mod:`.settings`, :mod:`.prior`) are then read without scipy's optimizers.
_PUBLIC = {
    **dict.fromkeys(["AlbedoWarning", "ErrorAnalysis", "FitResult", "FitWarning", "NonIdentifiableWarning", "fit_brdf",
                     "fit_from", "fit_measurements", "fit_wavelengths", "spectral_table_entry",
                     "format_with_error"], "goniometer"),
    **dict.fromkeys(["fit_classes", "ClassFitResult"], "classes"),
    **dict.fromkeys(["ClassModels", "Sampling", "GuardRails"], "settings"),
    **dict.fromkeys(["Measurements", "read_measurements"], "measurements"),
}
__all__ = list(_PUBLIC)


__getattr__, __dir__ = attach(__name__, _PUBLIC)
