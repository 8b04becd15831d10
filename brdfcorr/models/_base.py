"""Model and parameter descriptions: the single source of truth for names, units and bounds."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from brdfcorr._arrays import apply_labelled, is_lazy
from brdfcorr.errors import ParameterError
from brdfcorr.geometry import ScatteringGeometry

#: Upper bound of every BRDF intensity parameter [sr^-1] (t0, t1, a, f_iso, f_vol, f_geo, rho0):
#: a white Lambertian surface is 1/pi = 0.32 sr^-1, so 1e3 is far above any surface the models
#: describe. It keeps every registered model finite on the whole angle domain [0, 90) deg: their
#: geometric terms are at most of the order of 1 / (cos ti cos tr) <= 1.6e31 (the cosine of the
#: largest float below 90 deg is 2.5e-16), so an intensity of 1e3 gives at most ~1e35, within
#: float32 (3.4e38) where the correction combines the terms. An unbounded one (1e308) overflows:
#: every pixel of the class NaN, or an internal error.
MAX_INTENSITY = 1e3


@dataclass(frozen=True)
class Parameter:
    """One model parameter.

    Attributes
    ----------
    name : str
        Name as used in function signatures, parameter tables and configs.
    units : str
        Units in a plain-text form (``"sr^-1"``, ``"deg^-1"``, ``"1"`` for dimensionless).
    default : float
        A typical value, used as the starting point of fits and as documentation.
    lower, upper : float
        Physical bounds. Values must be finite and within them.
    lower_open : bool
        If True the lower bound itself is excluded (``w > 0`` rather than ``w >= 0``).
    description : str
        One line for tables and docs.
    """

    name: str
    units: str
    default: float
    lower: float
    upper: float = math.inf
    lower_open: bool = False
    description: str = ""

    @property
    def bounds(self) -> tuple[float, float]:
        """(lower, upper) physical bounds."""
        return self.lower, self.upper

    @property
    def range_text(self) -> str:
        """The allowed range as text, e.g. ``"> 0"`` or ``">= 0"``, or ``"finite"``."""
        lower = "" if math.isinf(self.lower) else f"{'>' if self.lower_open else '>='} {self.lower:g}"
        upper = "" if math.isinf(self.upper) else f"<= {self.upper:g}"
        return " and ".join(part for part in (lower, upper) if part) or "finite"

    def _holds(self, number: float) -> bool:
        """Whether one number is finite and within the bounds (the condition of :meth:`check`)."""
        try:
            number = float(number)
        except OverflowError:  # an integer beyond float's range: check says so
            return False
        return (math.isfinite(number) and self.lower <= number <= self.upper
                and not (self.lower_open and number == self.lower))

    def check(self, value, model: str) -> None:
        """Raise :class:`ParameterError` if any element of ``value`` is invalid.

        Lazy (dask) values are not inspected: that would compute them. Parameter tables validate
        their values when they are loaded, before anything lazy is built.
        """
        if type(value) is np.ndarray and value.ndim == 0 and value.dtype.kind in "fiu":
            value = value.item()  # a table's number (0-d, as entries hold it): checked without numpy
        if type(value) in (float, int) and self._holds(value):
            return  # ~1 us instead of ~25 (a table of 20 000 classes has 100 000 of them)
        if is_lazy(value):
            return
        try:
            values = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(
                f"{model}: parameter {self.name} must be a number, got {value!r}"
            ) from None
        invalid = ~np.isfinite(values) | (values < self.lower) | (values > self.upper)
        if self.lower_open:
            invalid |= values == self.lower
        if np.any(invalid):
            bad = values[invalid].flat[0]
            raise ParameterError(
                f"{model}: parameter {self.name} = {bad:g} is invalid; it must be finite and "
                f"{self.range_text} [{self.units}] ({self.description})"
            )


@dataclass(frozen=True)
class Model:
    """A BRDF model: its parameters and its kernel on a :class:`ScatteringGeometry`.

    Attributes
    ----------
    name : str
        Registry name (``"torrance_sparrow"``).
    description : str
        One line for tables and docs.
    reference : str
        The paper and equation the model implements.
    parameters : tuple of Parameter
        In the order of the model function's signature.
    kernel : callable
        ``kernel(geometry, **params)`` on numpy or dask arrays, without validation.
    linear : tuple of str
        Names of the parameters in which the model is linear, ``f = sum_j p_j B_j(geometry;
        shape)`` with the other (shape) parameters fixed: ``("t0", "t1")`` for Torrance-Sparrow
        (B = 1 and the specular term), ``("f_iso", "f_vol", "f_geo")`` for a kernel-driven model
        (B = 1, K_vol, K_geo). Read off the model equation. The correction shares the basis between
        bands that differ only in them; the fits solve them by linear least squares.
    basis : callable or None
        ``basis(geometry, **shape) -> tuple`` of the basis functions B_j, one per name in
        ``linear`` (a Python scalar where a basis is constant, e.g. ``1.0``).
    """

    name: str
    description: str
    reference: str
    parameters: tuple[Parameter, ...]
    kernel: Callable
    linear: tuple[str, ...] = ()
    basis: Callable | None = None

    def __post_init__(self):
        if bool(self.linear) != (self.basis is not None):
            raise ValueError(f"model {self.name}: 'linear' and 'basis' go together")
        unknown = set(self.linear) - set(self.parameter_names)
        if unknown:
            raise ValueError(f"model {self.name}: linear parameters {sorted(unknown)} are not parameters")

    @property
    def shape_names(self) -> tuple[str, ...]:
        """The parameters that are not linear (the basis functions depend on them)."""
        return tuple(name for name in self.parameter_names if name not in self.linear)

    def terms(self, geometry: ScatteringGeometry, shape: Mapping[str, object]) -> tuple:
        """The basis functions B_j at a geometry and shape parameters (no validation).

        ``f = sum_j p_j B_j`` over the parameters in :attr:`linear`; models without linear
        parameters have no terms.
        """
        if self.basis is None:
            return ()
        return tuple(self.basis(geometry, **{name: shape[name] for name in self.shape_names}))

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(parameter.name for parameter in self.parameters)

    @property
    def defaults(self) -> dict[str, float]:
        return {parameter.name: parameter.default for parameter in self.parameters}

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        return {parameter.name: parameter.bounds for parameter in self.parameters}

    def parameter(self, name: str) -> Parameter:
        """The :class:`Parameter` called ``name``."""
        for parameter in self.parameters:
            if parameter.name == name:
                return parameter
        raise ParameterError(
            f"{self.name}: unknown parameter {name!r}; "
            f"its parameters are {', '.join(self.parameter_names)}"
        )

    def validate(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """Check a complete set of parameters; return them in signature order.

        Raises :class:`ParameterError` naming the model and the parameter for unknown, missing,
        NaN or out-of-range values.
        """
        for name in params:
            self.parameter(name)
        missing = [name for name in self.parameter_names if name not in params]
        if missing:
            raise ParameterError(f"{self.name}: missing parameter(s) {', '.join(missing)}")
        for parameter in self.parameters:
            parameter.check(params[parameter.name], self.name)
        return {name: params[name] for name in self.parameter_names}

    def evaluate(self, geometry: ScatteringGeometry, **params):
        """BRDF [sr^-1] at a precomputed geometry (shared by many bands or classes)."""
        return self.kernel(geometry, **self.validate(params))

    def __call__(self, theta_i, theta_r, phi, **params):
        """BRDF [sr^-1] at zenith angles ``theta_i``, ``theta_r`` and relative azimuth ``phi`` [deg].

        Accepts numpy, dask and xarray inputs (angles and parameters) and returns the same kind.
        """

        def kernel(theta_i, theta_r, phi, **params):
            return self.evaluate(ScatteringGeometry(theta_i, theta_r, phi), **params)

        arguments = {"theta_i": theta_i, "theta_r": theta_r, "phi": phi, **params}
        return apply_labelled(kernel, arguments, "brdf", "sr^-1", f"BRDF ({self.name})")
