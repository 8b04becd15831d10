"""Product folders as the scenes of a chain run: their bands stacked for the run only.

A chain whose ``inputs.images`` are products (Sentinel-2 L2A SAFE folders, Landsat Collection-2
L2 folders, Sentinel-2 STAC item files with local assets) runs them as ``brdfcorr fit-classes``
and ``brdfcorr correct`` do: every product is one scene whose product the plan finds once
(:func:`brdfcorr.chain.scenes.plan_scenes`: its metadata read, its angle source and files taken
from it; the files are the scene's inputs, so the output guard and the resume fingerprint cover
them), and whose bands :func:`stacked_scenes` stacks from that product for the run as virtual
rasters in one scratch folder (:func:`brdfcorr.tasks.series.product_sources`, nothing copied and
nothing identified again), removed when the run ends,
however it ends. The steps then read the stack with the product's scaling
(:attr:`~brdfcorr.chain.scenes.Scene.raster`, ``scale``, ``offset``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import tempfile
from collections.abc import Iterator
from pathlib import Path

from brdfcorr.chain.scenes import Scene
from brdfcorr.errors import BrdfcorrError
from brdfcorr.tasks.series import product_sources

__all__ = ["SCRATCH_PREFIX", "stacked_scenes"]

#: The name of a run's scratch folder starts with this (in the system's temporary directory).
SCRATCH_PREFIX = "brdfcorr-chain-products-"


@contextlib.contextmanager
def stacked_scenes(scenes: tuple[Scene, ...], *, chunks: int | None = None) -> Iterator[tuple[Scene, ...]]:
    """The scenes with each product scene's bands stacked (``stack``, ``scale``, ``offset``), for
    the ``with`` block (the run) only.

    Parameters
    ----------
    scenes : tuple of Scene
        The planned scenes; those of image files, and those failing already, are given back as
        they are.
    chunks : int, optional
        Block size [pixels] of the stacks' mask files (:func:`brdfcorr.tasks.series.product_sources`).

    Yields
    ------
    tuple of Scene
        The scenes in the same order; a product that cannot be stacked turns its scene to
        ``fail`` with the reason (the others go on). No scratch folder is made without a product.
    """
    if not any(scene.product is not None and scene.action != "fail" for scene in scenes):
        yield scenes
        return
    with tempfile.TemporaryDirectory(prefix=SCRATCH_PREFIX) as scratch:
        yield tuple(_stacked(scene, Path(scratch), chunks) for scene in scenes)


def _stacked(scene: Scene, scratch: Path, chunks: int | None) -> Scene:
    """One scene with its product's stack in ``scratch`` (or turned to ``fail``)."""
    if scene.product is None or scene.action == "fail":
        return scene
    try:
        found = product_sources(scene.product, scratch, **({"chunks": chunks} if chunks else {}))
    except (BrdfcorrError, OSError) as error:
        return dataclasses.replace(scene, action="fail", reason=f"stacking product {scene.image}: {error}")
    return dataclasses.replace(scene, stack=Path(found["image"]), scale=found.get("scale"),
                               offset=found.get("offset"))
