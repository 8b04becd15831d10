"""The model registry: every BRDF model brdfcorr knows, by name.

Fitting, parameter tables, config validation, the CLI (``brdfcorr models``) and the docs all read
their parameter names, units, defaults and bounds from here.
"""

from __future__ import annotations

from brdfcorr.defaults import SURFACE_MODEL_NAMES
from brdfcorr.errors import UnknownNameError
from brdfcorr.models._base import Model
from brdfcorr.models.empirical import EMPIRICAL, LAMBERTIAN, SPECULAR_PEAK
from brdfcorr.models.kernels import (
    ROSS_THICK_LI_DENSE,
    ROSS_THICK_LI_SPARSE,
    ROSS_THIN_LI_DENSE,
    ROSS_THIN_LI_SPARSE,
)
from brdfcorr.models.rpv import RPV
from brdfcorr.models.torrance_sparrow import TORRANCE_SPARROW, TORRANCE_SPARROW_SIMPLIFIED
from brdfcorr.models.two_lobe import ROSS_LI_PEAK, ROSS_LI_TS, RPV_PEAK

REGISTRY: dict[str, Model] = {
    model.name: model
    for model in (
        TORRANCE_SPARROW,
        TORRANCE_SPARROW_SIMPLIFIED,
        EMPIRICAL,
        LAMBERTIAN,
        SPECULAR_PEAK,
        ROSS_THICK_LI_SPARSE,
        ROSS_THIN_LI_SPARSE,
        ROSS_THICK_LI_DENSE,
        ROSS_THIN_LI_DENSE,
        RPV,
        ROSS_LI_TS,
        ROSS_LI_PEAK,
        RPV_PEAK,
    )
}

#: Models that describe a whole surface (diffuse + specular) and so may be paired with a class in
#: a parameter table; ``specular_peak`` is a facet BRDF used by the V-cavity simulation. Written
#: once in :mod:`brdfcorr.defaults` (which imports nothing), so the command line lists them fast.
SURFACE_MODELS: tuple[str, ...] = SURFACE_MODEL_NAMES


def get_model(name: str | Model) -> Model:
    """The registered :class:`Model` called ``name`` (a Model is returned unchanged)."""
    if isinstance(name, Model):
        return name
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise UnknownNameError(
            f"unknown BRDF model {name!r}; known models: {', '.join(REGISTRY)}"
        ) from None


def parameter_table_rows() -> list[dict[str, str]]:
    """One row per (model, parameter) for tables and docs: name, units, default, range, meaning."""
    return [
        {
            "model": model.name,
            "parameter": parameter.name,
            "units": parameter.units,
            "default": f"{parameter.default:g}",
            "range": parameter.range_text,
            "description": parameter.description,
        }
        for model in REGISTRY.values()
        for parameter in model.parameters
    ]
