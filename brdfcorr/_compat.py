"""Old module paths of brdfcorr 0.1, kept importable for one release with a DeprecationWarning.

0.2 moved the flat modules into folders by layer (``brdfcorr.pipeline`` is now
``brdfcorr.workflow.chain``, ...). ``import brdfcorr.pipeline`` still works: a meta-path finder
answers for the old name with the module at its new place (the same object, so monkeypatching
either name patches both).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings

#: Old module path -> new module path (submodules follow their package: ``brdfcorr.sensors.envi``).
MOVED = {
    "brdfcorr.materials": "brdfcorr.models.materials",
    "brdfcorr.measurements": "brdfcorr.fit.measurements",
    "brdfcorr.classfit": "brdfcorr.fit.classes",
    "brdfcorr.simulate": "brdfcorr.analysis.simulate",
    "brdfcorr.io_utils": "brdfcorr.io.files",
    "brdfcorr.sensors": "brdfcorr.io.sensors",
    "brdfcorr.config": "brdfcorr.workflow.config",
    "brdfcorr.pipeline": "brdfcorr.workflow.chain",
    "brdfcorr.demo": "brdfcorr.workflow.demo",
    "brdfcorr.plotting": "brdfcorr.plot.materials",
    "brdfcorr.fit_plots": "brdfcorr.plot.fits",
    "brdfcorr.analysis_plots": "brdfcorr.plot.analysis",
}


def new_name(old: str) -> str | None:
    """The current path of a module known by its 0.1 path, or None."""
    for prefix, target in MOVED.items():
        if old == prefix or old.startswith(prefix + "."):
            return target + old[len(prefix):]
    return None


class _Alias(importlib.abc.Loader):
    def __init__(self, target: str):
        self.target = target

    def create_module(self, spec):
        return importlib.import_module(self.target)

    def exec_module(self, module):
        pass


class _MovedModules(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        current = new_name(fullname)
        if current is None:
            return None
        warnings.warn(
            f"{fullname} moved to {current} in brdfcorr 0.2; the old path goes away in 0.3",
            DeprecationWarning,
            stacklevel=2,
        )
        return importlib.machinery.ModuleSpec(fullname, _Alias(current))


def install() -> None:
    """Put the finder on :data:`sys.meta_path` (once)."""
    if not any(isinstance(finder, _MovedModules) for finder in sys.meta_path):
        sys.meta_path.insert(0, _MovedModules())
