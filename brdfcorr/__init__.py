"""brdfcorr: specular BRDF models and BRDF normalization of reflectance imagery."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("brdfcorr")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

import importlib  # noqa: E402

from brdfcorr._accessor_hook import register_accessor  # noqa: E402
from brdfcorr.errors import BrdfcorrError, ParameterError, UnknownNameError  # noqa: E402

register_accessor()  # the .brdf xarray accessor: now, or when xarray is imported (not by this import)

#: Names imported at first use (PEP 562), so that `import brdfcorr` and the command line's
#: `--help` and argument errors do not pay for dask and scipy.
_LAZY = {"geometry": "brdfcorr.geometry", "models": "brdfcorr.models", "normalize": "brdfcorr.correction",
         "ParameterTable": "brdfcorr.params", "run_chain": "brdfcorr.chain.run"}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'brdfcorr' has no attribute {name!r}")
    module = importlib.import_module(_LAZY[name])
    value = module if module.__name__.endswith(name) else getattr(module, name)
    globals()[name] = value
    return value

def __dir__() -> list[str]:
    """The module's names with the lazy ones (:data:`_LAZY`), which ``dir()`` would miss until used."""
    return sorted({*globals(), *_LAZY})


__all__ = [
    "__version__", "geometry", "models", "normalize", "ParameterTable", "run_chain",
    "BrdfcorrError", "ParameterError", "UnknownNameError",
]
