"""The ``fit:`` provenance block of a parameter-table class (:class:`FitRecord`).

``brdfcorr fit`` and ``brdfcorr fit-classes`` record with each fitted class where its parameters
come from and how well they are known: the source, N, chi^2/dof, R^2, the 1-sigma errors and the
covariance of the fitted parameters. This module holds the record, the field types of its YAML form
and its checks: the covariance's shape, symmetry and diagonal, the errors against
``sqrt(diag(covariance))``, and the agreement with the class's model and parameters
(:meth:`FitRecord.check_entry`). Import it from :mod:`brdfcorr.params`.

The record reads a class through :class:`EntryFields`, the few attributes of
:class:`brdfcorr.params.ClassEntry` it checks, so that this module sits below the table's modules
and imports none of them.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Protocol

import numpy as np
from pydantic import BeforeValidator, Field, model_validator

from brdfcorr._validation import Integer, Number, StrictModel, refuse_boolean, short_repr

if TYPE_CHECKING:
    from brdfcorr.models import Model

__all__ = ["FitRecord", "ERROR_TOLERANCE", "Covariance", "Statistic", "Count", "EntryFields"]


class EntryFields(Protocol):
    """What :meth:`FitRecord.check_entry` reads of a table class (:class:`brdfcorr.params.ClassEntry`)."""

    @property
    def label(self) -> str:
        """``"class 2 (grass)"``, the prefix of every message about the class."""

    @property
    def params(self) -> Mapping[str, float | list[float]]:
        """The parameters, in the model's registry units: a number, or one value per band or wavelength."""

    @property
    def wavelengths(self) -> Sequence[float] | None:
        """Wavelengths [nm] of list-valued parameters, or None."""


#: A covariance as written in a table: one p x p matrix (nested lists) or one per wavelength.
#: A numpy array is taken as its nested lists.
def _nested_lists(value: object) -> object:
    value = refuse_boolean(value)
    return value.tolist() if isinstance(value, np.ndarray) else value


Covariance = Annotated[
    list[list[Number]] | list[list[list[Number]]], BeforeValidator(_nested_lists)
]
#: A fit statistic: one number, or one per wavelength (band) of the entry.
Statistic = Annotated[float | list[Number], BeforeValidator(_nested_lists)]
#: A sample count: one, or one per wavelength (band) of the entry.
Count = Annotated[int | list[Integer], BeforeValidator(_nested_lists)]
#: Relative agreement required between ``errors`` and ``sqrt(diag(covariance))``.
ERROR_TOLERANCE = 1e-6


class FitRecord(StrictModel):
    """Where a class's parameters come from, and how well they are known (the ``fit:`` block).

    ``brdfcorr fit`` and ``brdfcorr fit-classes`` write it; hand-written and library classes have
    none. The covariance is that of the fitted (free) parameters, shape and intensity jointly;
    parameters held fixed in the fit are not listed and have zero variance.

    Attributes
    ----------
    source : str
        What the fit used: the command and its input files.
    parameters : list of str
        The fitted parameters of the class's model, in the order of the covariance's rows and
        columns.
    covariance : list
        One p x p matrix (nested lists, p = ``len(parameters)``) per wavelength of the entry's
        ``wavelengths`` (or per band, for per-band parameter lists), or a single p x p matrix when the
        entry's fitted parameters are band-independent. Units: products of the parameters' registry
        units. Symmetric, finite, with a non-negative diagonal.
    n : int or list of int
        Number of samples (measurements or pixels) fitted; one, or one per matrix.
    chi2_dof : float or list of float
        Reduced chi-square: residual sum of squares over (N - p), in the fit's weights (NaN when N <= p).
    r2 : float or list of float
        Coefficient of determination of the fit.
    errors : dict of str to float or list of float
        1-sigma errors of the fitted parameters, ``sqrt(diag(covariance))`` (checked to a relative
        :data:`ERROR_TOLERANCE`), in registry units; one value per matrix.
    errors_reliable : bool, optional
        Whether the fit judged its errors trustworthy (``fit-classes``: False with few spatial
        blocks, a strongly non-linear fit, a parameter at the edge of its range or at a bound;
        ``brdfcorr fit``: False when it warned; see ``docs/uncertainty.md``); absent where the fit
        did not judge.
    errors_reason : str, optional
        Why they are not.
    """

    source: str = Field(min_length=1)
    parameters: list[str] = Field(min_length=1)
    n: Count
    chi2_dof: Statistic
    r2: Statistic
    errors: dict[str, Statistic]
    covariance: Covariance
    errors_reliable: bool | None = None
    errors_reason: str | None = None

    @property
    def per_wavelength(self) -> bool:
        """True when the record holds one matrix per wavelength (band) of the entry."""
        return bool(self.covariance) and isinstance(self.covariance[0][0], list)

    def matrices(self) -> np.ndarray:
        """The covariance as a float64 array of shape (m, p, p); m = 1 for a single matrix."""
        matrices = np.asarray(self.covariance, dtype=float)
        return matrices if self.per_wavelength else matrices[np.newaxis]

    @model_validator(mode="after")
    def _check(self) -> FitRecord:
        duplicates = sorted(name for name, count in Counter(self.parameters).items() if count > 1)
        if duplicates:
            raise ValueError(f"parameters {', '.join(duplicates)} are listed more than once")
        p = len(self.parameters)
        try:
            matrices = self.matrices()
        except ValueError:  # ragged nested lists
            raise ValueError("covariance: every matrix must have the same shape") from None
        if matrices.ndim != 3 or matrices.shape[1:] != (p, p) or matrices.shape[0] == 0:
            shape = " x ".join(map(str, matrices.shape[1:]))
            raise ValueError(
                f"covariance: expected {p} x {p} matrices (one row and column per fitted parameter "
                f"{', '.join(self.parameters)}), got {shape or 'an empty list'}"
            )
        if not np.all(np.isfinite(matrices)):
            raise ValueError("covariance: values must be finite numbers")
        if not np.allclose(matrices, np.swapaxes(matrices, 1, 2), rtol=1e-9, atol=0.0):
            raise ValueError("covariance: the matrices must be symmetric")
        variances = np.diagonal(matrices, axis1=1, axis2=2)  # (m, p)
        if np.any(variances < 0):
            raise ValueError("covariance: the diagonal (variances) must be >= 0")
        self._check_lengths(matrices.shape[0])
        self._check_errors(np.sqrt(variances))
        return self

    def _check_lengths(self, m: int) -> None:
        for key in ("n", "chi2_dof", "r2"):
            value = getattr(self, key)
            if isinstance(value, list) != self.per_wavelength or (isinstance(value, list) and len(value) != m):
                expected = f"a list of {m} values (one per matrix)" if self.per_wavelength else "one number"
                raise ValueError(f"{key}: expected {expected}, like the covariance")
        counts = np.atleast_1d(np.asarray(self.n))
        if np.any(counts < 1):
            raise ValueError("n: the number of samples must be >= 1")

    def _check_errors(self, sigma: np.ndarray) -> None:
        if set(self.errors) != set(self.parameters):
            raise ValueError(
                f"errors: expected one entry per fitted parameter ({', '.join(self.parameters)}), "
                f"got {', '.join(self.errors) or 'none'}"
            )
        for column, name in enumerate(self.parameters):
            value = self.errors[name]
            if isinstance(value, list) != self.per_wavelength or (
                    isinstance(value, list) and len(value) != sigma.shape[0]):
                expected = f"{sigma.shape[0]} values (one per matrix)" if self.per_wavelength else "one number"
                raise ValueError(f"errors.{name}: expected {expected}, like the covariance")
            given = np.atleast_1d(np.asarray(value, dtype=float))
            expected_sigma = sigma[:, column]
            if not np.all(np.abs(given - expected_sigma) <= ERROR_TOLERANCE * expected_sigma):
                raise ValueError(
                    f"errors.{name} = {short_repr(value)} is not sqrt(diag(covariance)) = "
                    f"{short_repr(expected_sigma.tolist())}"
                )


    def check_entry(self, entry: EntryFields, model: Model) -> None:
        """The record agrees with the class ``entry`` (of surface model ``model``): its parameters
        are the model's, and it has one matrix per wavelength (band) exactly where ``params`` vary."""
        unknown = [name for name in self.parameters if name not in model.parameter_names]
        if unknown:
            raise ValueError(
                f"{entry.label}: fit.parameters: {', '.join(map(short_repr, unknown))} not a parameter of "
                f"{model.name}; its parameters: {', '.join(model.parameter_names)}"
            )
        lengths = {len(v) for v in entry.params.values() if isinstance(v, list)}
        count = len(entry.wavelengths) if entry.wavelengths is not None else next(iter(lengths), None)
        m = self.matrices().shape[0]
        if self.per_wavelength and m != count:
            where = "wavelengths" if entry.wavelengths is not None else "per-band values"
            raise ValueError(
                f"{entry.label}: fit.covariance has {m} matrices but the class has "
                f"{count if count is not None else 'no'} {where}; give one matrix per wavelength, or "
                "a single matrix for band-independent parameters"
            )
        varying = [name for name in self.parameters if isinstance(entry.params.get(name), list)]
        if not self.per_wavelength and varying:
            raise ValueError(
                f"{entry.label}: fit.covariance is a single matrix but {', '.join(varying)} "
                "vary with wavelength; give one matrix per wavelength"
            )
