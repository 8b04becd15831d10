"""BRDF models as pure, vectorized array functions, and the registry that describes them.

All functions take angles in degrees, broadcast numpy, dask and xarray inputs, and return the same
kind (dask stays lazy; xarray keeps dims and coords).
"""

from brdfcorr.models._base import Model, Parameter
from brdfcorr.models.empirical import empirical, lambertian, specular_peak
from brdfcorr.models.registry import REGISTRY, SURFACE_MODELS, get_model, parameter_table_rows
from brdfcorr.models.torrance_sparrow import (
    fresnel,
    geometric_attenuation,
    mean_facet_inclination,
    torrance_sparrow,
)

__all__ = [
    "Model",
    "Parameter",
    "REGISTRY",
    "SURFACE_MODELS",
    "get_model",
    "parameter_table_rows",
    "fresnel",
    "geometric_attenuation",
    "torrance_sparrow",
    "empirical",
    "specular_peak",
    "lambertian",
    "mean_facet_inclination",
]
