"""BRDF models as pure, vectorized array functions, and the registry that describes them.

All functions take angles in degrees, broadcast numpy, dask and xarray inputs, and return the same
kind (dask stays lazy; xarray keeps dims and coords).
"""

from brdfcorr.models._base import Model, Parameter
from brdfcorr.models.empirical import empirical, lambertian, specular_peak
from brdfcorr.models.kernels import (
    GEOMETRIC_KERNELS,
    VOLUME_KERNELS,
    kernel_driven,
    li_dense,
    li_sparse,
    ross_thick,
    ross_thin,
)
from brdfcorr.models.materials import Material, load_material, material_names
from brdfcorr.models.registry import REGISTRY, SURFACE_MODELS, get_model, parameter_table_rows
from brdfcorr.models.rpv import rpv
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
    "kernel_driven",
    "ross_thick",
    "ross_thin",
    "li_sparse",
    "li_dense",
    "VOLUME_KERNELS",
    "GEOMETRIC_KERNELS",
    "rpv",
    "Material",
    "load_material",
    "material_names",
]
