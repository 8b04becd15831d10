"""Benchmark: what identifying a product once per run saves per date (issue 42: "a product is
identified once"; run by hand, not part of the test suite).

A chain over product folders (and ``correct`` / ``fit-classes`` of them) identifies each product
(:func:`brdfcorr.tasks.series.find_products`: ``MTD_MSIL2A.xml`` read, the band, mask and granule
metadata files found) when it plans, then stacks its bands from the product found
(:func:`brdfcorr.tasks.series.product_sources`). Before issue 42 the stacking identified the folder
again from its path, so each date paid the identification twice. The SAFE folder is the tests'
(:func:`brdfcorr.testing.write_sentinel2_safe`: a real granule's ``MTD_TL.xml``, synthetic bands,
``--size`` squared 20 m pixels). Printed, as medians of ``--repeat`` rounds measured in the same
run: the identification (mean of ``--number`` calls), the stacking from the product (mean of 5
stacks), the saving per date (one identification) as a share of a date's plan and stack before
issue 42 (identify, identify, stack; computed from the two measured parts: the saving is far below
the noise of a single timed stack) and, for scale, the reading of the granule's angle grids
(``MTD_TL.xml``), which the run does once either way.

    python benchmarks/bench_product_once.py                 # 512 x 512 pixels, 7 rounds
    python benchmarks/bench_product_once.py --size 64 --repeat 21
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from brdfcorr.io.sensors import read_angles
from brdfcorr.io.sensors.folders import open_stack
from brdfcorr.tasks.series import find_products, product_sources
from brdfcorr.testing import write_sentinel2_safe


def seconds(work: Callable[[], object], number: int) -> float:
    """The mean time [s] of ``number`` calls of ``work``."""
    start = time.perf_counter()
    for _ in range(number):
        work()
    return (time.perf_counter() - start) / number


def one_round(safe: Path, scratch: Path, number: int) -> dict[str, float]:
    """One round of every measurement [s per date]; each stack goes to a fresh scratch folder."""
    product = find_products([safe])[0]
    stack = open_stack(product)

    def folder() -> Path:
        return Path(tempfile.mkdtemp(dir=scratch))

    return {
        "identify": seconds(lambda: find_products([safe]), number),
        "stack": seconds(lambda: product_sources(product, folder()), 5),
        "angles": seconds(lambda: read_angles(product.angles_kind, product.angles, like=stack,
                                              **product.angle_options), 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=int, default=512, help="window size in 20 m pixels [default: 512]")
    parser.add_argument("--repeat", type=int, default=7, help="rounds; medians are printed [default: 7]")
    parser.add_argument("--number", type=int, default=20, help="identifications timed per round [default: 20]")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-product-once-") as directory:
        safe = write_sentinel2_safe(Path(directory) / "in", size=args.size)
        scratch = Path(directory) / "scratch"
        scratch.mkdir()
        rounds = [one_round(safe, scratch, args.number) for _ in range(args.repeat)]
    median = {key: statistics.median(found[key] for found in rounds) for key in rounds[0]}
    print(f"SAFE {args.size} x {args.size} pixels at 20 m; medians of {args.repeat} rounds [ms per date]")
    print(f"identify the product (find_products): {median['identify'] * 1e3:.2f}")
    print(f"stack its bands from the product (product_sources): {median['stack'] * 1e3:.1f}")
    old, new = 2 * median["identify"] + median["stack"], median["identify"] + median["stack"]
    print(f"plan and stack: identified twice (before issue 42) {old * 1e3:.1f}, once {new * 1e3:.1f}: ratio "
          f"new/old {new / old:.3f}, saved {median['identify'] * 1e3:.2f} ms per date")
    print(f"for scale: the granule's angle grids read (MTD_TL.xml, once either way): {median['angles'] * 1e3:.1f}")


if __name__ == "__main__":
    main()
