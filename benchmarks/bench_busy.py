"""Benchmark: brdfcorr against its baselines on a quiet machine and with one busy process beside
both (run by hand; not part of the test suite; issue 41).

A shared machine runs other work: a tool that keeps its share of the cores keeps its time. Each
run here is a fresh process, taken in turn with its baseline, ``--repeat`` times, first quiet and
then with one busy-loop process (``while True: pass``, one core's worth) running beside both;
printed are the medians and the ratios to the baseline's median of the same condition.

``correct`` (``--job correct``): ``correct_files`` of the 64-band float32 cube of
``benchmarks/bench_scaling.py`` (``--size`` pixels square, three classes, deflate output, as
``brdfcorr correct`` runs it) against GDAL's multithreaded copy of the same cube
(``rasterio.shutil.copy``, brdfcorr's tiles, deflate with the floating-point predictor,
``NUM_THREADS=ALL_CPUS``), and brdfcorr's peak RSS against the goal 0.6 x cube + 250 MiB.
Goal: <= 1.15 x the copy on 2 cores, quiet and busy.

``nbar`` (``--job nbar``): ``nbar`` of a Sentinel-2 L2A SAFE folder (``--s2-size`` 20 m pixels
square, the real T23LLF ``MTD_TL.xml``, as ``benchmarks/bench_sen2nbar.py`` builds and runs it:
the 10 m and the 20 m bands, observed sun, the factor at every pixel) against sen2nbar's
``nbar_SAFE`` (a separate environment: ``python3 -m venv /tmp/venv-s2n && /tmp/venv-s2n/bin/pip
install sen2nbar``; ``--sen2nbar-python``): brdfcorr uncompressed against sen2nbar (which writes
uncompressed), and brdfcorr with deflate against sen2nbar followed by GDAL's deflate copy of its
outputs (``NUM_THREADS=ALL_CPUS``, predictor 3). Goal: <= 1.0 x in both.

Measured (issue 41, 2 cores; medians of three):

* ``--job nbar --s2-size 2048`` (load average 1.5 before the quiet rounds, two light jobs beside):
  quiet, sen2nbar 7.70 s, brdfcorr uncompressed 6.83 s (0.89 x), sen2nbar + GDAL deflate copy
  14.53 s, brdfcorr deflate 9.26 s (0.64 x); busy, 8.73 s, 6.31 s (0.72 x), 19.60 s, 11.49 s
  (0.59 x). With 8 subdivisions of a grid cell instead of 16 (``correction.subgrid``) it was
  1.02 x and 0.66 x quiet.
* ``--job correct --size 2048`` on a quiet machine (load average 2.2 before the quiet rounds):
  quiet, GDAL copy 20.2 s, brdfcorr 22.7 s (1.12 x), peak RSS 800 MiB (goal 864 MiB); busy,
  25.6 s and 28.4 s (1.11 x), peak RSS 782 MiB. With three other jobs on the machine (load
  average 7.0) the same run gave 1.31 x quiet and 0.81 x busy: the ratio swings by a third.

``docs/scaling.md`` ("Under load") and ``docs/sensors.md`` ("Side by side with sen2nbar").

Usage::

    python benchmarks/bench_busy.py --job correct [--size 2048] [--repeat 3]
    python benchmarks/bench_busy.py --job nbar [--s2-size 2048] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import rasterio
import rasterio.shutil

sys.path.insert(0, str(Path(__file__).parent))
from bench_scaling import prepare, run_child  # noqa: E402
from bench_sen2nbar import (  # noqa: E402
    BANDS,
    DEFAULT_PYTHON,
    run_brdfcorr_process,
    run_sen2nbar,
    sen2nbar_available,
)

from brdfcorr.testing import write_sentinel2_safe  # noqa: E402

MTD = Path(__file__).resolve().parents[1] / "tests" / "data" / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"
BUSY = "while True: pass"


class Busy:
    """One busy-loop process while the ``with`` block runs (none when ``on`` is false)."""

    def __init__(self, on: bool):
        self.on, self.process = on, None

    def __enter__(self):
        if self.on:
            self.process = subprocess.Popen([sys.executable, "-c", BUSY])
            time.sleep(0.5)  # scheduled and spinning before the timed run starts
        return self

    def __exit__(self, *exc):
        if self.process is not None:
            self.process.kill()
            self.process.wait()


def medians(jobs: dict[str, Callable[[], float]], repeat: int, busy: bool) -> dict[str, float]:
    """The median seconds of each job over ``repeat`` rounds, the jobs taken in turn each round."""
    seconds: dict[str, list[float]] = {name: [] for name in jobs}
    with Busy(busy):
        for _ in range(repeat):
            for name, job in jobs.items():
                seconds[name].append(job())
    return {name: statistics.median(values) for name, values in seconds.items()}


def correct_jobs(directory: Path, peaks: list[float]) -> dict[str, Callable[[], float]]:
    """GDAL's copy and brdfcorr's correct in fresh processes (bench_scaling's children); brdfcorr's
    peak RSS [MiB] appended to ``peaks``."""
    def ours() -> float:
        result = run_child(directory, "brdfcorr", None, 1)
        peaks.append(result["peak_mib"])
        return result["seconds"]
    return {"GDAL copy": lambda: run_child(directory, "gdal", None, 1)["seconds"], "brdfcorr correct": ours}


def gdal_deflate_copies(folder: Path) -> None:
    """GDAL's multithreaded deflate copy of every GeoTIFF sen2nbar wrote in ``folder``."""
    for path in sorted(folder.glob("*.tif")):
        rasterio.shutil.copy(path, path.with_suffix(".deflate.tiff"), driver="GTiff", tiled=True, compress="deflate",
                             predictor=3, num_threads="ALL_CPUS")


def nbar_jobs(python: str, safe: Path, scratch: Path) -> dict[str, Callable[[], float]]:
    """sen2nbar, sen2nbar with GDAL's deflate copy of its outputs, and brdfcorr uncompressed and
    deflate (fresh processes, imports excluded)."""
    def sen2nbar_deflate() -> float:
        seconds = run_sen2nbar(python, safe)[0]
        start = time.perf_counter()
        gdal_deflate_copies(safe / "NBAR")
        return seconds + time.perf_counter() - start
    return {"sen2nbar": lambda: run_sen2nbar(python, safe)[0], "sen2nbar + GDAL deflate copy": sen2nbar_deflate,
            "brdfcorr uncompressed": lambda: run_brdfcorr_process(safe, scratch, "none", "pixels")[0],
            "brdfcorr deflate": lambda: run_brdfcorr_process(safe, scratch, "deflate", "pixels")[0]}


def report(found: dict[str, float], pairs: list[tuple[str, str, float]], condition: str) -> None:
    print(f"{condition} (load average before: {os.getloadavg()[0]:.2f}):")
    for name, seconds in found.items():
        print(f"  {name}: median {seconds:.2f} s")
    for ours, theirs, goal in pairs:
        ratio = found[ours] / found[theirs]
        print(f"  {ours} / {theirs}: {ratio:.2f} (goal <= {goal})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--job", choices=("correct", "nbar"), required=True)
    parser.add_argument("--size", type=int, default=2048, help="correct: cube side [pixels] (64 bands)")
    parser.add_argument("--s2-size", type=int, default=2048, help="nbar: window side in 20 m pixels")
    parser.add_argument("--repeat", type=int, default=3, help="rounds per condition [default: 3]")
    parser.add_argument("--sen2nbar-python", default=DEFAULT_PYTHON)
    args = parser.parse_args()
    uptime = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"{os.cpu_count()} cores; uptime: {uptime}")
    with tempfile.TemporaryDirectory() as directory:
        scratch = Path(directory)
        if args.job == "correct":
            prepare(scratch, args.size, 64)
            cube_mib = args.size * args.size * 64 * 4 / 2**20
            for busy in (False, True):
                peaks: list[float] = []
                found = medians(correct_jobs(scratch, peaks), args.repeat, busy)
                report(found, [("brdfcorr correct", "GDAL copy", 1.15)], "busy" if busy else "quiet")
                print(f"  brdfcorr peak RSS: median {statistics.median(peaks):.0f} MiB, max {max(peaks):.0f} MiB "
                      f"(goal <= {0.6 * cube_mib + 250:.0f} MiB for the {cube_mib:.0f} MiB cube)")
        else:
            if not sen2nbar_available(args.sen2nbar_python):
                print(f"skipped: sen2nbar is not importable by {args.sen2nbar_python} (see the module docstring)")
                return
            safe = write_sentinel2_safe(scratch / "in", MTD, size=args.s2_size)
            print(f"SAFE: {args.s2_size}^2 pixels at 20 m ({len(BANDS[20])} bands), {2 * args.s2_size}^2 at 10 m "
                  f"({len(BANDS[10])} bands)")
            for busy in (False, True):
                found = medians(nbar_jobs(args.sen2nbar_python, safe, scratch), args.repeat, busy)
                report(found, [("brdfcorr uncompressed", "sen2nbar", 1.0),
                               ("brdfcorr deflate", "sen2nbar + GDAL deflate copy", 1.0)], "busy" if busy else "quiet")


if __name__ == "__main__":
    main()
