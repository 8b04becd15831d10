"""A package's public face imported at first use (PEP 562), as SPEC 1's ``lazy_loader.attach``
makes it: importing the package loads none of its modules, so that a command pays only for what
it runs."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping


def attach(package: str, public: Mapping[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` (its ``__name__``) whose names ``public``
    maps to the modules that define them (``{"fit_brdf": "goniometer"}``): a name is imported from
    ``package.module`` at its first use and kept in the package's namespace."""
    namespace = vars(importlib.import_module(package))

    def __getattr__(name: str) -> object:
        if name not in public:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{public[name]}"), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *public})

    return __getattr__, __dir__
