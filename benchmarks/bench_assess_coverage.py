"""Benchmark: coverage of the ``assess`` slopes' +-2 sigma on simulated scenes whose errors are
shared by pixels, when the user follows the tool's advice (run by hand; not part of the suite).

Each scene is one class and one band, ``--size`` pixels square, seen by a push-broom line (view
zenith 0-30 deg across the columns, sun due east: the signed view zenith is linear in the column),
with no view-angle signal: reflectance 0.3 plus white noise (1-sigma 0.01) plus shared errors
(:mod:`brdfcorr.testing.noise`), so the true slope is 0 and a slope is "covered" when it lies
within 2 of its reported 1-sigma. Three kinds of scene:

* ``independent``: white noise only;
* ``patches``: an offset (1-sigma 0.02) per square patch of ``--patch`` pixels (the acquisition
  days of a composite, fields);
* ``stripes``: an offset (1-sigma 0.02) per stripe of ``--stripe`` columns along the whole track
  (a detector's calibration: every stripe at one view angle).

Per kind, over ``--scenes`` seeds: the spread of the slopes themselves (the true 1-sigma) against
the median reported 1-sigma, the coverage and how often the warnings of
:func:`brdfcorr.analysis.view_angles.error_growth_warning` (``warned``) and
:func:`brdfcorr.analysis.view_stripes.stripe_warning` (``striped``) fire, for four ways to run
``assess``:

* ``blocks``: the starting point, ``--block-size`` (8);
* ``doubling``: what the growth warning says, a larger block: the block size doubled until it is
  silent (at most to a quarter of the scene, 4 blocks);
* ``cluster layer``: the other advice, the units that share errors given as ``--clusters`` (the
  patch or stripe ids; for independent pixels, the blocks);
* ``advice``: what a user who follows the tool does, scene by scene: where the stripe warning
  fires, the detector ids as ``--clusters`` (the stripe ids; a column's own id where the scene has
  no stripes); else where the growth warning fires, the block size doubled until it is silent;
  else the blocks of 8.

Goal (issue 40): coverage 0.9-0.98 when the advice is followed.

Usage::

    python benchmarks/bench_assess_coverage.py [--scenes 300] [--size 128] [--block-size 8] [--patch 16] [--stripe 2]
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import dataclass

import numpy as np

from brdfcorr.analysis.view_angles import ViewAngleOptions, assess_view_angles, error_growth_warning
from brdfcorr.analysis.view_stripes import stripe_warning
from brdfcorr.testing import synthetic_angles
from brdfcorr.testing.noise import patch_noise, strip_noise

KINDS = ("independent", "patches", "stripes")


@dataclass(frozen=True)
class Outcome:
    """One assessment of one scene: the relative slope and its 1-sigma [%/10 deg], whether it warned."""

    slope: float
    sigma: float
    warned: bool
    striped: bool = False
    stripe_ratio: float = float("nan")


def scene(kind: str, size: int, patch: int, stripe: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(reflectance (y, x), cluster ids (y, x)) of one simulated scene (module docstring)."""
    shape = (size, size)
    if kind == "patches":
        shared, ids = patch_noise(shape, patch, 0.02, rng)
    elif kind == "stripes":
        shared, ids = strip_noise(shape, stripe, 0.02, rng)
    else:
        shared, ids = np.zeros(shape), None
    return 0.3 + shared + rng.normal(0.0, 0.01, shape), ids


def assess(values: np.ndarray, angles: dict, block_size: int, clusters=None) -> Outcome:
    """``assess`` of one scene (before = after) with square blocks or a cluster layer."""
    cube = values[None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = assess_view_angles(cube, cube, np.ones(values.shape, np.int64), angles["vza"], angles["vaa"],
                                    angles["saa"], clusters=clusters, options=ViewAngleOptions(block_size=block_size))
    return Outcome(float(result["relative_slope"].values[1, 0, 0]),
                   float(result["relative_slope_error"].values[1, 0, 0]), error_growth_warning(result) is not None,
                   stripe_warning(result) is not None, float(result["stripe_ratio"].values[1, 0, 0]))


def doubling(values: np.ndarray, angles: dict, block_size: int) -> tuple[Outcome, int]:
    """The block size doubled from ``block_size`` while the warning fires, up to a quarter of the
    scene's side; the last outcome and its block size."""
    outcome = assess(values, angles, block_size)
    while outcome.warned and 2 * block_size <= values.shape[0] // 2:
        block_size *= 2
        outcome = assess(values, angles, block_size)
    return outcome, block_size


def advice(values: np.ndarray, angles: dict, block_size: int, detectors: np.ndarray) -> tuple[Outcome, str]:
    """What a user who follows the tool's warnings gets (module docstring), and which advice was
    followed: ``stripes`` (the ``detectors`` ids as the cluster layer), ``doubling`` or ``none``."""
    outcome = assess(values, angles, block_size)
    if outcome.striped:
        return assess(values, angles, block_size, detectors), "stripes"
    if outcome.warned:
        return doubling(values, angles, block_size)[0], "doubling"
    return outcome, "none"


def coverage(outcomes: list[Outcome]) -> float:
    """Share of the slopes within 2 reported sigma of 0 (the true slope)."""
    return float(np.mean([abs(o.slope) <= 2.0 * o.sigma for o in outcomes]))


def summary(name: str, outcomes: list[Outcome]) -> str:
    sigmas = np.array([o.sigma for o in outcomes])
    return (f"  {name:<14} median 1-sigma {np.median(sigmas):.4f}, coverage of +-2 sigma "
            f"{coverage(outcomes):.3f}, warned {np.mean([o.warned for o in outcomes]):.3f}, "
            f"striped {np.mean([o.striped for o in outcomes]):.3f}")


def run(kind: str, args, angles: dict) -> None:
    """Print the numbers of one kind of scene (module docstring)."""
    blocks, doubled, layered, sizes, advised, followed = [], [], [], [], [], []
    columns = np.ascontiguousarray(np.broadcast_to(np.arange(args.size), (args.size, args.size)))
    for seed in range(args.scenes):
        values, ids = scene(kind, args.size, args.patch, args.stripe, np.random.default_rng(seed))
        blocks.append(assess(values, angles, args.block_size))
        outcome, size = doubling(values, angles, args.block_size)
        doubled.append(outcome)
        sizes.append(size)
        layered.append(assess(values, angles, args.block_size, ids) if ids is not None else blocks[-1])
        outcome, which = advice(values, angles, args.block_size, ids if kind == "stripes" else columns)
        advised.append(outcome)
        followed.append(which)
    truth = np.std([o.slope for o in blocks])
    print(f"{kind}: the slopes' own spread (true 1-sigma) {truth:.4f} %/10deg over {args.scenes} scenes")
    ratios = np.percentile([o.stripe_ratio for o in blocks], [5, 50, 95])
    print(summary(f"blocks of {args.block_size}", blocks)
          + "; stripe ratio 5/50/95th percentile {:.2f}/{:.2f}/{:.2f}".format(*ratios))
    counts = {size: sizes.count(size) for size in sorted(set(sizes))}
    print(summary("doubling", doubled) + f"; final block sizes {counts}")
    print(summary("cluster layer", layered))
    paths = {name: followed.count(name) for name in ("none", "doubling", "stripes") if name in followed}
    print(summary("advice", advised) + f"; advice followed {paths}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=300, help="seeds per kind [default: 300]")
    parser.add_argument("--size", type=int, default=128, help="scene side [pixels; default: 128]")
    parser.add_argument("--block-size", type=int, default=8, help="the starting block size [default: 8]")
    parser.add_argument("--patch", type=int, default=16, help="patch side [pixels; default: 16]")
    parser.add_argument("--stripe", type=int, default=2, help="stripe width [columns; default: 2]")
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    args = parser.parse_args()
    angles = synthetic_angles(args.size, args.size, vza_max=30.0, saa=90.0, dtype=np.float64)
    print(f"{args.size} x {args.size} pixels, one class, true slope 0; coverage of |slope| <= 2 sigma")
    for kind in args.kinds:
        run(kind, args, angles)


if __name__ == "__main__":
    main()
