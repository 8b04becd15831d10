"""brdfcorr: specular BRDF models and BRDF normalization of reflectance imagery."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("brdfcorr")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

from brdfcorr import (  # noqa: E402
    _compat,
    accessor,  # noqa: E402,F401  (registers the .brdf xarray accessor)
    geometry,
    models,
)
from brdfcorr.correct import normalize  # noqa: E402
from brdfcorr.errors import BrdfcorrError, ParameterError, UnknownNameError  # noqa: E402

_compat.install()

__all__ = [
    "__version__", "geometry", "models", "normalize", "BrdfcorrError", "ParameterError", "UnknownNameError",
]
