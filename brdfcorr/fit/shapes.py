"""Which shape parameters of an imagery fit are free, and where they are searched.

The surface models fitted to imagery are linear in their intensity terms (:func:`intensity_terms`)
once their shape parameters are fixed; this module holds the defaults of the shape parameters held
fixed (:data:`DEFAULT_FIXED`), the search ranges of the free ones (:data:`SEARCH_RANGES`,
:data:`MODEL_SEARCH_RANGES`, :func:`search_range`), the models that can be fitted to imagery at all
(:func:`imagery_models`) and the check of a caller's model and fixed values (:func:`_resolve`).
The solver itself is :mod:`brdfcorr.fit.solver`.
"""

from __future__ import annotations

from collections.abc import Mapping

from brdfcorr.errors import ParameterError
from brdfcorr.models import SURFACE_MODELS, Model, get_model

__all__ = [
    "DEFAULT_FIXED",
    "EDGE_FRACTION",
    "MODEL_SEARCH_RANGES",
    "SEARCH_RANGES",
    "imagery_models",
    "intensity_terms",
    "search_range",
]

#: Shape parameters held fixed unless the caller frees them (paper 003 fixes k = 0.25: n, k and t1
#: cannot be retrieved together from reflectance alone).
DEFAULT_FIXED: dict[str, dict[str, float]] = {
    "torrance_sparrow": {"k": 0.25},
    "torrance_sparrow_simplified": {"k": 0.25},
    "ross_li_ts": {"k": 0.25},
}

#: Search ranges of the shape parameters (a subset of the physical bounds where BRDFs of natural
#: and man-made surfaces lie; Table 1 of paper 003 spans w = 0.032-0.153 deg^-1, n = 1.48-1.77),
#: and whether the grid is logarithmic.
SEARCH_RANGES: dict[str, tuple[float, float, bool]] = {
    "w": (0.005, 0.5, True),
    "n": (1.05, 4.0, False),
    "k": (0.0, 3.0, False),
    "b": (-3.0, 6.0, False),
    "c": (0.005, 0.5, True),
}

#: Search ranges of the shape parameters of one model where they differ from :data:`SEARCH_RANGES`
#: (RPV's k is a Minnaert exponent, not Torrance-Sparrow's absorption index; |theta| = 1 is the
#: degenerate limit of the Henyey-Greenstein term).
MODEL_SEARCH_RANGES: dict[str, dict[str, tuple[float, float, bool]]] = {
    "rpv": {"k": (0.2, 2.0, False), "theta": (-0.9, 0.9, False), "rho_c": (0.0, 1.0, False)},
    "rpv_peak": {"k": (0.2, 2.0, False), "theta": (-0.9, 0.9, False), "rho_c": (0.0, 1.0, False)},
}

#: A shape parameter within this fraction of its search range (of log range for w, c) from either
#: end is "at the edge": the optimum probably lies outside, or the data do not constrain it. An end
#: that is a closed physical bound of the parameter (RPV's rho_c = 1: no hot spot) does not count.
EDGE_FRACTION = 1e-3


def intensity_terms(model: Model) -> tuple[str, ...]:
    """The intensity terms of a model (its linear parameters, :attr:`Model.linear`): ``("t0", "t1")``
    for Torrance-Sparrow, ``("a", "t0")`` for the empirical model, ``("t0",)`` for Lambertian,
    ``("f_iso", "f_vol", "f_geo")`` for the kernel-driven models."""
    return model.linear


def _free_shape(model: Model, fixed: Mapping[str, float]) -> list[str]:
    return [name for name in model.shape_names if name not in fixed]


def search_range(model: Model, name: str) -> tuple[float, float, bool] | None:
    """(low, high, logarithmic) search range of a shape parameter of a model, or None if it has
    none (:data:`MODEL_SEARCH_RANGES`, else :data:`SEARCH_RANGES`)."""
    return {**SEARCH_RANGES, **MODEL_SEARCH_RANGES.get(model.name, {})}.get(name)


def imagery_models() -> tuple[str, ...]:
    """Surface models that can be fitted to imagery: with intensity terms, and a search range for
    every shape parameter not held fixed by default."""
    fittable = []
    for name in SURFACE_MODELS:
        model = get_model(name)
        free = _free_shape(model, DEFAULT_FIXED.get(name, {}))
        if model.linear and all(search_range(model, shape) for shape in free):
            fittable.append(name)
    return tuple(fittable)


def _check_model(model: Model, fixed: Mapping[str, float] | None) -> dict[str, float]:
    """The shape parameters held fixed (defaults and the caller's), validated."""
    terms = intensity_terms(model)
    if not terms:
        raise ParameterError(
            f"model {model.name!r} cannot be fitted to imagery; use one of {', '.join(imagery_models())}"
        )
    fixed = {**DEFAULT_FIXED.get(model.name, {}), **dict(fixed or {})}
    for name in fixed:
        if name in terms:
            raise ParameterError(f"{model.name}: the intensity term {name} cannot be fixed")
        model.parameter(name).check(fixed[name], model.name)
    missing = [name for name in _free_shape(model, fixed) if search_range(model, name) is None]
    if missing:
        raise ParameterError(
            f"{model.name}: no search range for the shape parameter(s) {', '.join(missing)}; fix them"
        )
    return fixed


def _resolve(model: str | Model, fixed: Mapping[str, float] | None) -> tuple[Model, dict[str, float], list[str]]:
    """The registry model, its fixed shape parameters (the defaults and the caller's, validated by
    :func:`_check_model`) and its free ones."""
    model = get_model(model)
    fixed = _check_model(model, fixed)
    return model, fixed, _free_shape(model, fixed)
