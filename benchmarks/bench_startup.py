"""Benchmark: how long the first commands a user runs take, each in a fresh process (run by hand).

``brdfcorr models``, ``materials roof_tile``, ``coefficients roy2016`` (the README's listings) and
``validate configs/params_example.yaml`` (a parameter table) print registries and check YAML: they
need neither xarray nor scipy, which the command line imports only where a command computes.
``validate configs/imagery_fit.yaml`` checks a chain config and its plan (rasterio for the images'
headers), ``fit CSV`` fits the README's roof-tile goniometer table (scipy's optimizers, no raster stack). Each
is timed as a fresh ``python -m brdfcorr`` process, ``--repeat`` times in turn with two baselines
measured in the same run: the bare interpreter (``python -c pass``) and ``python -c "import
xarray"`` (what a command pays for the array stack). Printed: medians [s] and the ratio of each
command to the xarray import. ``brdfcorr --help`` is in the table as the floor of the command line.

Measured (2 cores, quiet, medians of 5; stop 49, the same script on the code before and after):

==============================  ==================  ==================
run                             before [s] (x xr)   after [s] (x xr)
==============================  ==================  ==================
interpreter                     0.06 (0.05)         0.06 (0.05)
import xarray                   1.15 (1.00)         1.29 (1.00)
brdfcorr --help                 0.28 (0.24)         0.26 (0.21)
brdfcorr models                 1.66 (1.45)         0.44 (0.34)
brdfcorr materials roof_tile    1.67 (1.45)         0.46 (0.36)
brdfcorr coefficients roy2016   1.68 (1.45)         0.49 (0.38)
brdfcorr validate TABLE         2.82 (2.45)         0.82 (0.64)
==============================  ==================  ==================

Stop 50 (the same script at e8eabe8 and after, from a directory outside the repository so that
``PYTHONPATH`` picks the old tree): ``validate CHAIN`` 3.50 s (3.13 x xr) -> 0.87 s (0.77; the
fit's and the correction's packages no longer imported for their settings), ``fit CSV`` 3.48 s
(3.11) -> 1.56 s (1.39; the goniometer task apart from the imagery fit); the other rows unchanged.

Stop 57: ``correct LINE``, ``assess LINE`` and ``fit-classes LINE`` correct, assess and fit the
demo's line (``brdfcorr demo``: 382 x 380 pixels, 6 bands; the README's example table). dask looked
for a dask.distributed Client on each pass and imported the module for it; a local pass now names
dask's scheduler function (``brdfcorr.io.writer.local_scheduler``). The rows ``..., distributed
imported`` run the same command after ``import distributed``: what every command paid before.
Measured (2 cores, medians of 3, one run): correct 2.09 s against 2.57 s (0.48 s less), assess
2.11 s against 2.41 s (0.30 s less); fit-classes 8.70 s against 8.32 s, within the noise of an
8 s run (its time is the fit's); the other rows as before.

Usage::

    python benchmarks/bench_startup.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
BASELINES = {"interpreter": ["-c", "pass"], "import xarray": ["-c", "import xarray"]}
#: The goniometer table of ``brdfcorr fit CSV`` (the README's roof tile, phi >= 90 deg fitted).
MEASUREMENTS = Path(tempfile.gettempdir()) / "bench_startup_roof_tile.csv"
#: The demo's line and where its correction goes (``correct LINE``).
DEMO = Path(tempfile.gettempdir()) / "bench_startup_demo"
LINE = DEMO / "scene" / "line01_"
CORRECT = ["correct", f"{LINE}image.tif", "--angles", f"{LINE}angles.tif", "--classes", f"{LINE}classes.tif",
           "--params", str(REPOSITORY / "configs" / "params_example.yaml"), "--ref-sza", "mean", "--ref-vza", "0",
           "-o", str(DEMO / "corrected.tif"), "--qa", str(DEMO / "qa.tif"), "--overwrite"]
LAYERS = ["--angles", f"{LINE}angles.tif", "--classes", f"{LINE}classes.tif"]
FIT_CLASSES = ["fit-classes", f"{LINE}image.tif", *LAYERS, "--model", "torrance_sparrow",
               "-o", str(DEMO / "fitted.yaml"), "--overwrite"]
ASSESS = ["assess", f"{LINE}image.tif", str(DEMO / "corrected.tif"), *LAYERS, "-o", str(DEMO / "assess.json"),
          "--overwrite"]
COMMANDS = {
    "brdfcorr --help": ["--help"],
    "brdfcorr models": ["models"],
    "brdfcorr materials roof_tile": ["materials", "roof_tile"],
    "brdfcorr coefficients roy2016": ["coefficients", "roy2016"],
    "brdfcorr validate TABLE": ["validate", str(REPOSITORY / "configs" / "params_example.yaml")],
    "brdfcorr validate CHAIN": ["validate", str(REPOSITORY / "configs" / "imagery_fit.yaml")],
    "brdfcorr fit CSV": ["fit", str(MEASUREMENTS), "--fix", "k=0.25", "--min-phi", "90"],
    "brdfcorr correct LINE": CORRECT,
    "brdfcorr assess LINE": ASSESS,
    "brdfcorr fit-classes LINE": FIT_CLASSES,
}
#: The same commands as they ran before stop 57 (dask.distributed imported on the first pass).
AS_BEFORE = {f"{words[0]} LINE, distributed imported": [
    "-c", f"import distributed; from brdfcorr.cli import main; main({words!r}, prog_name='brdfcorr')"]
    for words in (CORRECT, ASSESS, FIT_CLASSES)}


def _seconds(arguments: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, *arguments], check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    subprocess.run([sys.executable, str(REPOSITORY / "examples" / "make_goniometer_csv.py"), "roof_tile",
                    str(MEASUREMENTS)], check=True, capture_output=True)
    subprocess.run([sys.executable, "-m", "brdfcorr", "demo", "-o", str(DEMO)], check=True, capture_output=True)
    runs = {**BASELINES, **{name: ["-m", "brdfcorr", *words] for name, words in COMMANDS.items()}, **AS_BEFORE}
    times: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(args.repeat):  # in turn, so that a busy moment touches every row alike
        for name, arguments in runs.items():
            times[name].append(_seconds(arguments))
    medians = {name: statistics.median(values) for name, values in times.items()}
    print(f"fresh processes, median of {args.repeat}")
    print(f"{'run':40s} {'seconds':>8s} {'x import xarray':>16s}")
    for name, seconds in medians.items():
        print(f"{name:40s} {seconds:8.2f} {seconds / medians['import xarray']:16.2f}")


if __name__ == "__main__":
    main()
