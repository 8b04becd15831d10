"""The papers' analyses: the impact of ignoring masking/shadowing, the azimuthal width of the
specular peak, albedo (:mod:`brdfcorr.analysis.papers`) and the V-cavity simulation of paper 000
(:mod:`brdfcorr.analysis.simulate`)."""

from brdfcorr.analysis.papers import (
    albedo,
    azimuthal_width,
    shadowing_impact,
    specular_albedo_bound,
    width_reduction,
)
from brdfcorr.analysis.simulate import FacetGrid, simulate_vcavity

__all__ = [
    "albedo",
    "azimuthal_width",
    "shadowing_impact",
    "specular_albedo_bound",
    "width_reduction",
    "simulate_vcavity",
    "FacetGrid",
]
