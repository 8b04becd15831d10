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
    fixed = dict(fixed or {})
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

    lower, upper, given = [], [], {}  # given: the user's bounds as given
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
            low, high, given[name] = max(low, user_low), min(high, user_high), (user_low, user_high)
            if not low < high:
                below_floor = parameter.lower_open and user_low <= parameter.lower < user_high
                floor = (f" above {low:g}, the least value a fit takes (its open bound plus {OPEN_BOUND_FLOOR:g} "
                         "times its default)" if below_floor else "")
                raise ParameterError(
                    f"{model.name}: bounds of {name} ({user_low:g}, {user_high:g}) leave no room{floor} "
                    f"within its physical range {name} {parameter.range_text} [{parameter.units}]"
                )
        lower.append(low)
        upper.append(high)
    for name, value in initial.items():
        index, parameter = free.index(name), model.parameter(name)
        value = _scalar(value, f"{model.name}: starting value of {name}")
        try:
            parameter.check(value, model.name)
        except ParameterError:  # the physical range (w > 0), not the optimizer's floor above it
            raise ParameterError(f"{model.name}: starting value {name} = {value:g} is outside its physical range "
                                 f"{name} {parameter.range_text} [{parameter.units}]") from None
        user_low, user_high = given.get(name, (-math.inf, math.inf))
        if not user_low <= value <= user_high:
            raise ParameterError(f"{model.name}: starting value {name} = {value:g} is outside its bounds "
                                 f"[{user_low:g}, {user_high:g}]")
        # Above an open bound but below the floor (0 < w < 1e-6 of its default): the start is the floor.
        initial[name] = max(value, lower[index])
    return fixed, free, np.array(lower), np.array(upper), initial
