"""The bounded problem of a goniometer fit from a user's settings: :func:`_free_parameters` splits a
model's parameters into fixed values and free ones within closed bounds, the registry's physical
range (open lower bounds such as w > 0 raised by :data:`OPEN_BOUND_FLOOR`) intersected with the
user's, and checks the user's starting values (:func:`brdfcorr.fit.goniometer.fit_brdf`).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from brdfcorr.errors import FitError, ParameterError
from brdfcorr.models import Model

__all__ = ["OPEN_BOUND_FLOOR"]

#: Open lower bounds (w > 0, n > 0) become ``lower + OPEN_BOUND_FLOOR * default`` for the optimizer,
#: which needs closed bounds; 1e-6 of a typical value is far below any meaningful fit.
OPEN_BOUND_FLOOR = 1e-6


def _scalar(value, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{what} must be a single number, got {value!r}") from None
    if not math.isfinite(number):
        raise ParameterError(f"{what} must be finite, got {number!r}")
    return number


def _free_parameters(model: Model, fixed, initial, bounds):
    """Split the model's parameters into fixed values and bounded free ones.

    Returns ``(fixed, free, lower, upper, start)``: fixed values (validated), free names in
    signature order, the optimizer's closed bounds and the user's starting values (a dict).
    """
    fixed = {name: value for name, value in dict(fixed or {}).items()}
    initial = dict(initial or {})
    bounds = dict(bounds or {})
    for name in itertools.chain(fixed, initial, bounds):
        model.parameter(name)  # unknown name -> ParameterError naming the model's parameters
    for name, value in fixed.items():
        model.parameter(name).check(value, f"{model.name} (fixed)")
        fixed[name] = _scalar(value, f"{model.name}: fixed value of {name}")
    both = sorted(set(fixed) & (set(initial) | set(bounds)))
    if both:
        raise ParameterError(
            f"{model.name}: parameter(s) {', '.join(both)} are fixed and cannot also have a "
            "starting value or bounds"
        )
    free = tuple(name for name in model.parameter_names if name not in fixed)
    if not free:
        raise FitError(f"{model.name}: every parameter is fixed; nothing to fit")

    lower, upper = [], []
    for name in free:
        parameter = model.parameter(name)
        low, high = parameter.lower, parameter.upper
        if parameter.lower_open:
            low = low + OPEN_BOUND_FLOOR * max(abs(parameter.default), 1e-3)
        if name in bounds:
            try:
                user_low, user_high = (float(value) for value in bounds[name])
            except (TypeError, ValueError):
                raise ParameterError(
                    f"{model.name}: bounds of {name} must be a pair (lower, upper), got {bounds[name]!r}"
                ) from None
            if math.isnan(user_low) or math.isnan(user_high):
                raise ParameterError(f"{model.name}: bounds of {name} must be numbers or +-inf, got "
                                     f"({user_low:g}, {user_high:g})")
            low, high = max(low, user_low), min(high, user_high)
            if not low < high:
                raise ParameterError(
                    f"{model.name}: bounds of {name} ({user_low:g}, {user_high:g}) leave no room "
                    f"within its physical range {parameter.range_text} [{parameter.units}]"
                )
        lower.append(low)
        upper.append(high)
    for name, value in initial.items():
        index = free.index(name)
        value = _scalar(value, f"{model.name}: starting value of {name}")
        if not lower[index] <= value <= upper[index]:
            raise ParameterError(
                f"{model.name}: starting value {name} = {value:g} is outside its bounds "
                f"[{lower[index]:g}, {upper[index]:g}]"
            )
        initial[name] = value
    return fixed, free, np.array(lower), np.array(upper), initial
