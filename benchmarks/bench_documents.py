"""Benchmark: how fast bad YAML documents are refused and big good ones read (run by hand; not
part of the test suite, which never reads the clock).

Goal (issue 22): ``brdfcorr validate`` refuses a malformed document of up to the 10 MB limit
(:data:`brdfcorr.io.files.MAX_DOCUMENT_BYTES`) with exit code 2 and one line in under 1 s. Syntax
errors and too deep nesting anywhere in the text are found by libyaml in C before any Python object
is built; a document whose only fault is in its content (a tag, an alias bomb) after megabytes of
good YAML is found only once those are built, as slowly as a good document of that size. Each
case runs the command line in a fresh process; the time is the median of ``--repeat`` runs and is
also given as a ratio to the start-up of the same command line (``brdfcorr validate`` of a
one-line table), measured in the same run, so that the figure means the same on a slower machine.

In-process, a valid table of 20 000 classes (about 2 MB) is loaded with brdfcorr's bounded parser
and compared with PyYAML's own libyaml loader (``yaml.CSafeLoader``, no bounds, no validation).
Measured (stop 49, ``--size 2e6``, 19 842 classes, 2.2 MB): 1.00 x the libyaml loader before,
0.71 x after a parameter's bounds check took a table's single numbers without numpy
(:meth:`brdfcorr.models.Parameter.check`: the table's validation 2.6 s -> 0.9 s, a merge 1.6 s -> 0.4 s).

Usage::

    python benchmarks/bench_documents.py             # 10 MB cases, 3 runs each
    python benchmarks/bench_documents.py --size 2e6  # smaller documents, quicker
"""

from __future__ import annotations

import argparse
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from brdfcorr.io.files import MAX_DOCUMENT_BYTES
from brdfcorr.params import ParameterTable

CLASS_LINE = ("  - {{id: {i}, name: c{i}, model: torrance_sparrow, "
              "params: {{t0: 0.02, t1: 0.2, w: 0.036, n: 1.77, k: 0.25}}}}")


def _table(size: int) -> str:
    lines, total, i = ["classes:"], 9, 0
    while total < size:
        i += 1
        lines.append(CLASS_LINE.format(i=i))
        total += len(lines[-1]) + 1
    return "\n".join(lines) + "\n"


def malformed_documents(size: int) -> dict[str, str]:
    """Documents of about ``size`` bytes, each refused by the parser."""
    rng = random.Random(0)
    table = _table(size - 1000)
    bomb = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}' if i else '0.1'] * 9)}]\n" for i in range(10))
    return {
        "nested brackets": "[" * (size // 2) + "]" * (size // 2),
        "nested block lists": "- " * (size // 2 - 2) + "1\n",
        "random punctuation": "".join(rng.choice("abc{}[]:- ,\n'\"&*!|>%@`") for _ in range(size)),
        "error on line 2": "a: [\n b: c\n" + table,
        "error at the end": table + "  - {id: 1, name: ]]\n",
        "alias bomb at the end": table + bomb + "t0: *l9\n",
        "python tag at the end": table + "  - !!python/object/apply:os.system ['true']\n",
    }


def _validate(path: Path, repeat: int) -> tuple[float, int, list[str]]:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        result = subprocess.run([sys.executable, "-c", "from brdfcorr.cli import main; main()", "validate", str(path)],
                                capture_output=True, text=True)
        times.append(time.perf_counter() - start)
    return statistics.median(times), result.returncode, result.stderr.splitlines()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=MAX_DOCUMENT_BYTES - 50_000, help="bytes per document")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    size = int(args.size)
    with tempfile.TemporaryDirectory() as scratch:
        directory = Path(scratch)
        small = directory / "small.yaml"
        small.write_text("classes: [{id: 1, name: flat, model: lambertian, params: {t0: 0.1}}]\n")
        startup, code, _ = _validate(small, args.repeat)
        assert code == 0
        print(f"start-up (validate a one-line table): {startup:.2f} s\n")
        print(f"{'malformed document':<24} {'MB':>5} {'seconds':>8} {'/ start-up':>10} {'exit':>5} "
              f"{'lines':>5}  goal < 1 s")
        for name, text in malformed_documents(size).items():
            path = directory / "bad.yaml"
            path.write_text(text)
            seconds, code, lines = _validate(path, args.repeat)
            verdict = "ok" if seconds < 1.0 and code == 2 and len(lines) == 1 else "MISSED"
            print(f"{name:<24} {len(text) / 1e6:5.1f} {seconds:8.2f} {seconds / startup:10.2f} {code:5d} "
                  f"{len(lines):5d}  {verdict}")
            print(f"    {lines[0][:150] if lines else ''}")

    text = _table(2_200_000)
    start = time.perf_counter()
    yaml.load(text, Loader=yaml.CSafeLoader)
    baseline = time.perf_counter() - start
    start = time.perf_counter()
    table = ParameterTable.from_yaml_text(text, source="big.yaml")
    ours = time.perf_counter() - start
    print(f"\nvalid table of {len(table)} classes ({len(text) / 1e6:.1f} MB): yaml.CSafeLoader {baseline:.2f} s, "
          f"ParameterTable (bounded parse + validation) {ours:.2f} s = {ours / baseline:.2f} x")


if __name__ == "__main__":
    main()
