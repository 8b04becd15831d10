"""The ``.brdf`` accessor (:mod:`brdfcorr.accessor`) registered with xarray without importing it.

``import brdfcorr`` registers the accessor. Importing xarray for it would cost every start of the
command line 0.3-0.6 s (xarray, then pandas), where ``brdfcorr --help`` needs none of it. So the
accessor is registered now if xarray is loaded already, else as soon as it is: a finder ahead of
the others answers for ``xarray`` once, with the spec the other finders give, and has its loader
import the accessor right after running xarray's ``__init__`` (the loader itself is kept, so
xarray's resources and its ``__spec__`` stay as they are).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
from types import ModuleType

ACCESSOR = "brdfcorr.accessor"


class _AfterXarray(importlib.abc.MetaPathFinder):
    """Registers the accessor after xarray's import; removes itself at its first use."""

    def find_spec(self, name, path=None, target=None):
        if name != "xarray":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader

        def exec_module(module: ModuleType) -> None:
            del loader.exec_module  # the loader's own method again (a reload runs xarray only)
            loader.exec_module(module)
            importlib.import_module(ACCESSOR)

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def register_accessor() -> None:
    """Register the ``.brdf`` accessor now if xarray is imported, else when it is."""
    if "xarray" in sys.modules:
        importlib.import_module(ACCESSOR)
    elif not any(isinstance(finder, _AfterXarray) for finder in sys.meta_path):
        sys.meta_path.insert(0, _AfterXarray())
