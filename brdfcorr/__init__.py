"""brdfcorr: specular BRDF models and BRDF normalization of reflectance imagery."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("brdfcorr")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

from brdfcorr import geometry, models  # noqa: E402
from brdfcorr.errors import BrdfcorrError, ParameterError, UnknownNameError  # noqa: E402

__all__ = ["__version__", "geometry", "models", "BrdfcorrError", "ParameterError", "UnknownNameError"]
