"""No two modules of a package import each other in a circle, and no import points up a layer,
type-only imports included.

import-linter's ``acyclic_siblings`` and ``layers`` contracts (``pyproject.toml``) check the same;
this test builds the import graph with grimp itself, with the imports under ``if TYPE_CHECKING:``
counted, so that neither can hide as a type annotation whatever the linter's settings. Siblings
are the children of one package, each standing for itself and everything below it (as the
contract squashes them). The children of ``brdfcorr.tasks`` and ``brdfcorr.chain`` are left to
the linter's contract.
"""

from __future__ import annotations

import functools
import tomllib
from pathlib import Path

import grimp
import pytest

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"

#: Packages whose own children this test does not check (the linter's contract does).
LEFT_TO_THE_LINTER = ("brdfcorr.tasks", "brdfcorr.chain")


@functools.cache
def _graph() -> grimp.ImportGraph:
    return grimp.build_graph("brdfcorr", include_external_packages=False, exclude_type_checking_imports=False,
                             cache_dir=None)


def _packages(graph: grimp.ImportGraph) -> list[str]:
    return sorted(module for module in graph.modules if graph.find_children(module))


def _sibling_imports(graph: grimp.ImportGraph, package: str) -> dict[str, set[str]]:
    """For each child of ``package``, the siblings that it or a module below it imports (or a module below them)."""
    children = sorted(graph.find_children(package))
    owner = {}
    for child in children:
        for module in {child, *graph.find_descendants(child)}:
            owner[module] = child
    edges: dict[str, set[str]] = {child: set() for child in children}
    for module, child in owner.items():
        for imported in graph.find_modules_directly_imported_by(module):
            target = owner.get(imported)
            if target is not None and target != child:
                edges[child].add(target)
    return edges


def _cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One circle of the directed graph ``edges`` (its nodes in order, the first repeated last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(edges[node]):
            if state.get(target) == 1:
                return path[path.index(target):] + [target]
            if target not in state and (found := visit(target)) is not None:
                return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(edges):
        if node not in state and (found := visit(node)) is not None:
            return found
    return None


def test_cycle_finder_finds_a_circle_and_only_a_circle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_graph_counts_type_only_imports():
    # brdfcorr.fit.sandwich imports the profile it annotates with only under TYPE_CHECKING.
    assert "brdfcorr.fit.profile" in _graph().find_modules_directly_imported_by("brdfcorr.fit.sandwich")


@pytest.mark.parametrize("package", [
    package for package in _packages(_graph())
    if not any(package == left or package.startswith(left + ".") for left in LEFT_TO_THE_LINTER)
])
def test_no_circle_among_the_modules_of(package):
    assert _cycle(_sibling_imports(_graph(), package)) is None


def _layers() -> list[set[str]]:
    """The layers of the linter's ``layers`` contract, top first (``a | b``: independent siblings)."""
    contracts = tomllib.loads(PYPROJECT.read_text())["tool"]["importlinter"]["contracts"]
    (layers,) = [contract["layers"] for contract in contracts if contract["type"] == "layers"]
    return [{name.strip() for name in layer.split("|")} for layer in layers]


def test_no_import_points_up_a_layer():
    illegal = _graph().find_illegal_dependencies_for_layers(_layers())
    assert not illegal, sorted(f"{dependency.importer} -> {dependency.imported}" for dependency in illegal)
