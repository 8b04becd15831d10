"""Benchmark: a resumed chain run on an unchanged scene checks its outputs without redoing the work
(issue 39: "resume on an unchanged 1 GiB scene still takes under 2 s"; run by hand, not part of
the test suite).

A chain of one scene (bench_correct.py's synthetic scene: a float32 cube of ``--size`` squared
pixels and ``--bands`` bands, deflate, with its 4-band angles and a class map) is run once, then
again with nothing changed. The rerun plans the scene from the output's recorded fingerprint (each
input's size, modification time and content digest, :func:`brdfcorr.io.files.content_digest`),
reopens the outputs to check them as a fresh write is checked, and skips it. Printed: both times,
their ratio, and the digest of the image alone (its share of the rerun).

    python benchmarks/bench_resume.py --size 2048 --bands 64      # the 1 GiB scene of the issue
    python benchmarks/bench_resume.py --size 512 --bands 16       # a quick run
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import yaml
from bench_correct import make_scene, spectral_table_path

from brdfcorr.chain.run import run_chain
from brdfcorr.io.files import content_digest


def write_chain(directory: Path, paths: dict[str, Path], table: Path) -> Path:
    """A chain config of the one scene in ``directory`` (outputs under ``directory/out``)."""
    config = {
        "name": "resume benchmark",
        "inputs": {"images": [str(paths["image"])], "scene_regex": r"(?P<scene>.+)\.tif$",
                   "angles": {"kind": "geotiff", "path": str(paths["angles"])}, "classes": str(paths["classes"])},
        "parameters": {"table": str(table)},
        "reference": {"sza": "mean", "vza": 0.0, "raa": 0.0},
        "outputs": {"directory": str(directory / "out")},
    }
    path = directory / "chain.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


def timed_run(config: Path) -> tuple[float, dict]:
    start = time.perf_counter()
    report = run_chain(config)
    return time.perf_counter() - start, {scene["scene"]: scene["status"] for scene in report.scenes}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=int, default=512, help="scene side [pixels] (2048 for the 1 GiB scene)")
    parser.add_argument("--bands", type=int, default=16)
    parser.add_argument("--dir", help="working directory (default: a temporary one)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=args.dir) as directory:
        directory = Path(directory)
        paths = make_scene(directory / "scene", args.size, args.bands)
        config = write_chain(directory, paths, spectral_table_path(directory))
        stored, cube = paths["image"].stat().st_size / 2**20, args.size**2 * args.bands * 4 / 2**30
        print(f"scene: {args.size} x {args.size} x {args.bands} float32 ({cube:.2f} GiB in memory, "
              f"{stored:.0f} MiB deflated)")
        first, statuses = timed_run(config)
        print(f"first run: {first:.2f} s {statuses}")
        again, statuses = timed_run(config)
        print(f"resumed run, nothing changed: {again:.2f} s {statuses} "
              f"({again / first:.3f} x the first run; goal < 2 s: {'met' if again < 2.0 else 'MISSED'})")
        start = time.perf_counter()
        content_digest(paths["image"])
        print(f"  of which the image's content digest: {time.perf_counter() - start:.3f} s")


if __name__ == "__main__":
    main()
