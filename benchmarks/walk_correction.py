"""Structure benchmark: the walk of one GeoTIFF correction through brdfcorr's modules (run by hand).

Follows ``brdfcorr correct`` on a small synthetic scene from
:func:`brdfcorr.workflow.correction.correct_files` to the numbers (the dask scheduler synchronous,
so every block function runs in this thread) and records, as a reader following the code would,
each brdfcorr function at its first call (a loop over classes or bands is read once) and the module
it belongs to. Consecutive functions in one module are one *stay*; a *climb* is a move
from a module to one of a higher layer (the layers of the import-linter contract in
``pyproject.toml``, top first) that is not the return from a call (a callback of a lower layer into a
higher one, or a layer calling back up). Goal (issue 23): at most 15 stays and 2 climbs.

Usage::

    python benchmarks/walk_correction.py            # the counts and the walk, one stay a line
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import dask

from brdfcorr.io.scene import SceneSources
from brdfcorr.testing import example_table, synthetic_scene, write_scene
from brdfcorr.workflow.correction import correct_files
from brdfcorr.workflow.request import CorrectionRequest, Engine, OutputFiles

#: The layers, top first (pyproject.toml, [tool.importlinter]); modules outside them have none.
LAYERS = ["brdfcorr.cli", "brdfcorr.workflow", "brdfcorr.plot", "brdfcorr.analysis", "brdfcorr.fit",
          "brdfcorr.correction", "brdfcorr.params", "brdfcorr.params_bands", "brdfcorr.models",
          "brdfcorr.geometry", "brdfcorr.io"]


def layer(module: str) -> int | None:
    """Rank of a module's layer (0 = top), or None."""
    for rank, prefix in enumerate(LAYERS):
        if module == prefix or module.startswith(prefix + ".") or module.startswith(prefix + "_"):
            return rank
    return None


def walk(run) -> list[tuple[str, int]]:
    """The stays of ``run()``: the brdfcorr functions it calls, each at its first call, with
    consecutive ones of one module collapsed, as (module, depth of the stack on entry)."""
    stays: list[tuple[str, int]] = []
    seen: set = set()
    depth = 0

    def profile(frame, event, arg):
        nonlocal depth
        if event == "call":
            depth += 1
            module = frame.f_globals.get("__name__", "")
            if not module.startswith("brdfcorr") or frame.f_code in seen:
                return
            seen.add(frame.f_code)
            if not stays or stays[-1][0] != module:
                stays.append((module, depth))
        elif event == "return":
            depth -= 1

    sys.setprofile(profile)
    try:
        run()
    finally:
        sys.setprofile(None)
    return stays


def climbs(stays: list[tuple[str, int]]) -> list[tuple[str, str]]:
    """Moves to a higher layer made by a call (deeper in the stack), not by a return."""
    found = []
    for (before, _), (after, depth_after) in zip(stays, stays[1:]):
        rank_before, rank_after = layer(before), layer(after)
        deeper = depth_after > min(d for m, d in stays if m == before)
        if rank_before is not None and rank_after is not None and rank_after < rank_before and deeper:
            found.append((before, after))
    return found


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
            stays = walk(run_once)
    modules = {module for module, _ in stays}
    up = climbs(stays)
    print(f"by module: {len(stays)} stays in {len(modules)} modules, {len(up)} climbs back up")
    packages = [LAYERS[rank] if (rank := layer(module)) is not None else module for module, _ in stays]
    package_stays = [name for index, name in enumerate(packages) if index == 0 or packages[index - 1] != name]
    print(f"by layer: {len(package_stays)} stays in {len(set(packages))} layers")
    for module, depth in stays:
        print(f"  {'  ' * min(depth, 30)}{module}")
    for before, after in up:
        print(f"climb: {before} -> {after}")


if __name__ == "__main__":
    main()
