"""Structure benchmark: the walk of one GeoTIFF correction through brdfcorr's modules (run by hand).

Follows ``brdfcorr correct`` on a small synthetic scene from
:func:`brdfcorr.tasks.correct.correct_files` to the numbers (the dask scheduler synchronous,
so every block function runs in this thread) and records, as a reader following the code would,
each brdfcorr function at its first call (a loop over classes or bands is read once) and the module
it belongs to. Consecutive functions in one module are one *stay*; a *climb* is a call from a
function of one layer into a function of a higher layer (the layers of the import-linter contract
in ``pyproject.toml``, top first), found from the caller's frame, not from the order of first
calls (a return is no climb): a callback, or dask computing a graph of higher-layer functions from
a lower layer; each pair of modules counts once. Goal (issue 23): at most 15 stays and 2 climbs.

The stays are printed three ways: by module (every function a reader opens, helpers included),
by layer (the same walk, a stay per layer), and along the path to the numbers (the deepest chain
of calls, from ``correct_files`` to the model's arithmetic: the modules a reader passes through to
see how a pixel's number is made).

Measured (issue 23, second pass): by module 111 stays in 32 modules, by layer 55, path to the
numbers 6 stays (tasks.correct -> io.writer -> correction.normalization -> models._base ->
models.torrance_sparrow -> geometry); 2 climbs, both dask computing the correction's block functions
from the writer (io) that stores them. The climbs counted before this pass (7) were mostly returns
read as climbs from the order of first calls, and one real callback (``params_bands`` calling the
``ClassEntry.brdf_model`` property of ``params``; it now calls the registry itself).

Measured (issue 42, third pass): before, 122 stays in 37 modules by module, 57 by layer,
``io.rasters`` entered 7 times (the product kind and layout looked up again by each size and
open), 3 climbs (io.writer -> correction.blocks, .checks, .normalization: dask computing the
correction from the writer's pass). After: 110 stays in 38 modules, 50 by layer, ``io.rasters``
3 (image and class map; the scale check after the angle pass), 0 climbs, path to the numbers 5
stays (tasks.correct -> correction.normalization -> models._base -> models.torrance_sparrow ->
geometry). The image is identified once (``io.product``) and carried by the scene
(``io.scene.opened_scene``); the task computes the pass inside ``io.writer.writing``, which only
writes. What remains is mostly the correction's own reading order (params -> models -> geometry
while the table is resolved and the reference checked) and comprehensions, which the profiler sees
as functions. Later (the scale check moved to ``io.scale_check``): 113 stays in 39 modules, 52 by
layer, ``io.rasters`` entered twice (the image opened, then scaled after its band centres are read).
Stop 58 ended at 122 stays in 40 modules, 56 by layer, ``io.rasters`` entered 3 times: the image
opened, then scaled and checked for fill after its band centres are read, and the fill check's
chunk function computed by the scale check's sample. Stop 59 moved the scaling and the fill floor
into ``io.reflectance`` (with the unpacking of arrays given in memory, which ``io.scale_check``
held): 123 stays in 41 modules, 56 by layer, ``io.rasters`` entered twice (the image opened; the
class map). The Python API's switches checked (``brdfcorr._validation.check_flags``) and the class
map's nodata read by ``io.reflectance.declared_nodata`` then made it 124 stays, 58 by layer.

Usage::

    python benchmarks/walk_correction.py            # the counts and the walk, one stay a line
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import dask

from brdfcorr.io.scene import SceneSources
from brdfcorr.tasks.correct import correct_files
from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles
from brdfcorr.testing import example_table, synthetic_scene, write_scene

#: The layers, top first (pyproject.toml, [tool.importlinter]); modules outside them have none.
LAYERS = [["brdfcorr.cli"], ["brdfcorr.chain"], ["brdfcorr.tasks"], ["brdfcorr.plot"], ["brdfcorr.analysis"],
          ["brdfcorr.fit"], ["brdfcorr.correction"], ["brdfcorr.params"], ["brdfcorr.models"],
          ["brdfcorr.geometry"], ["brdfcorr.io"]]


def layer(module: str) -> int | None:
    """Rank of a module's layer (0 = top), or None."""
    for rank, packages in enumerate(LAYERS):
        if any(module == package or module.startswith(package + ".") for package in packages):
            return rank
    return None


def _stack(frame) -> list[str]:
    """The modules of the brdfcorr functions on the stack from ``frame`` down (through dask's and
    other libraries' frames), innermost first."""
    modules = []
    while frame is not None:
        module = frame.f_globals.get("__name__", "")
        if module.startswith("brdfcorr"):
            modules.append(module)
        frame = frame.f_back
    return modules


def collapse(modules: list[str]) -> list[str]:
    """Consecutive equal modules as one stay."""
    return [module for index, module in enumerate(modules) if index == 0 or modules[index - 1] != module]


def walk(run) -> tuple[list[str], set[tuple[str, str]], list[str]]:
    """The stays of ``run()`` (the modules of the brdfcorr functions it calls, each function at
    its first call, consecutive ones of one module as one stay), its climbs (every (caller,
    callee) pair of modules where a function calls one of a higher layer: a callback) and the
    path to the numbers (the stays of the deepest chain of brdfcorr calls, outermost first)."""
    stays: list[str] = []
    up: set[tuple[str, str]] = set()
    seen: set = set()
    deepest: list[str] = []

    def profile(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if not module.startswith("brdfcorr"):
            return
        stack = _stack(frame)
        if len(stack) > len(deepest):
            deepest[:] = stack
        caller = stack[1] if len(stack) > 1 else None
        rank, caller_rank = layer(module), layer(caller or "")
        if rank is not None and caller_rank is not None and rank < caller_rank:
            up.add((caller, module))
        if frame.f_code not in seen:
            seen.add(frame.f_code)
            if not stays or stays[-1] != module:
                stays.append(module)

    sys.setprofile(profile)
    try:
        run()
    finally:
        sys.setprofile(None)
    return stays, up, collapse(deepest[::-1])


def main() -> None:
    with tempfile.TemporaryDirectory() as scratch:
        directory = Path(scratch)
        paths = write_scene(directory, synthetic_scene(ny=32, nx=40))
        request = CorrectionRequest(
            SceneSources(paths["image"], paths["classes"], paths["angles"]), example_table(),
            OutputFiles(directory / "out.tif", qa=directory / "qa.tif"), reference={"sza": "mean", "vza": 0.0},
            engine=Engine(chunks=16, scheduler="synchronous"),
        )
        def run_once():
            return correct_files(request)

        with dask.config.set(scheduler="synchronous"):
            run_once()  # imports and first-use caches are not part of the walk
            stays, up, path = walk(run_once)
    print(f"by module: {len(stays)} stays in {len(set(stays))} modules, {len(up)} climbs back up")
    ranks = [layer(module) for module in stays]
    packages = ["+".join(LAYERS[rank]) if rank is not None else module for module, rank in zip(stays, ranks)]
    print(f"by layer: {len(collapse(packages))} stays in {len(set(packages))} layers")
    print(f"path to the numbers (the deepest chain of calls): {len(path)} stays: {' -> '.join(path)}")
    for module in stays:
        print(f"  {module}")
    for caller, callee in sorted(up):
        print(f"climb: {caller} -> {callee}")


if __name__ == "__main__":
    main()
