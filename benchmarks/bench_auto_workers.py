"""Benchmark: the model choice of ``brdfcorr fit --model auto`` in one process and in a pool of
worker processes (``--workers N``), on the README's roof-tile measurements.

The choice fits every candidate (:data:`brdfcorr.fit.selection.GONIOMETER_CANDIDATES`, six
models) on five folds: thirty independent least-squares fits, which ``choose_model`` hands to a
:class:`concurrent.futures.ProcessPoolExecutor`: the command's pool (:mod:`brdfcorr.tasks.pool`,
workers forked from a fork server that imports the fits once) and, for comparison, a pool of
spawned processes, each of which imports the fits first.
The table is the paper-003 roof tile at the EGO geometries with 4 % noise (``python
examples/make_goniometer_csv.py roof_tile``), phi >= 90 deg as the README fits it. Prints the
wall time of each, its ratio to the one-process choice measured in the same run, and whether the
choice (every fold's held-out error) is the same. The fork server starts with the first pool of the
run and is counted in its time.

    python benchmarks/bench_auto_workers.py [--workers 2,4]

Measured (this 2-core machine, three runs): one process 2.4-2.8 s; two workers of the command's
pool 1.7-2.0 s (0.70-0.81 x), two spawned workers 2.0-2.3 s (0.83-0.84 x); the same choice and
fold errors every time. (At commit 615b3d0 it was 21.1 s alone and 0.56 x with two spawned workers;
the choice has since become about eight times faster, so a worker's start weighs more beside it.)
"""

from __future__ import annotations

import argparse
import concurrent.futures
import multiprocessing
import time

from brdfcorr.defaults import available_cores
from brdfcorr.fit.measurements import filter_measurements
from brdfcorr.fit.selection import choose_model
from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
from brdfcorr.models.materials import load_material
from brdfcorr.tasks.pool import worker_processes


def measurements():
    """The roof tile's synthetic goniometer table (examples/make_goniometer_csv.py), phi >= 90 deg."""
    material = load_material("roof_tile")
    data = synthesize_measurements(material.model, material.params, *goniometer_angles(), relative_noise=0.04,
                                   seed=0, source=material.label)
    return filter_measurements(data, min_phi=90.0)


def timed_choice(data, workers: int, spawned: bool = False):
    """The choice and its wall time [s] with ``workers`` processes (1: in this process) of the
    command's pool, or spawned ones."""
    start = time.perf_counter()
    if workers == 1:
        choice = choose_model(data)
    else:
        pool = (concurrent.futures.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
                if spawned else worker_processes(workers, ("brdfcorr.fit.selection",)))
        with pool:
            choice = choose_model(data, executor=pool)
    return choice, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", default=str(available_cores()),
                        help="worker counts to time, comma-separated [default: this machine's cores]")
    args = parser.parse_args()
    data = measurements()
    alone, baseline = timed_choice(data, 1)
    print(f"{len(data.brdf)} measurements; one process: {baseline:.1f} s, chose {alone.chosen}")
    for workers in (int(text) for text in args.workers.split(",")):
        for spawned, kind in ((False, "the command's pool"), (True, "spawned")):
            choice, seconds = timed_choice(data, workers, spawned)
            print(f"{workers} workers, {kind}: {seconds:.1f} s ({seconds / baseline:.2f} x one process), "
                  f"same choice and fold errors: {choice == alone}")


if __name__ == "__main__":
    main()
