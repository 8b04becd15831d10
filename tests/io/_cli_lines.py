"""Command lines and the one-line error check shared by the tests of outputs, product metadata and
scratch folders (imported as ``from _cli_lines import ...``: pytest puts this folder on the path)."""

import re


def _one_line(stderr: str, pattern: str) -> str:
    """stderr is exactly one ``brdfcorr: error:`` line (no libtiff or GDAL line) matching ``pattern``,
    after brdfcorr's own warnings (a fit's guard rails) if any."""
    lines = [line for line in stderr.splitlines() if not line.startswith("brdfcorr: warning: ")]
    assert len(lines) == 1, stderr
    assert lines[0].startswith("brdfcorr: error: ") and re.search(pattern, lines[0]), lines[0]
    return lines[0]


def _correct_args(scene, output, *extra) -> list[str]:
    """``brdfcorr correct`` of a ``scene`` fixture into ``output``, in chunks of 16 pixels."""
    return ["correct", str(scene["image"]), "--angles", str(scene["angles"]), "--classes", str(scene["classes"]),
            "--params", str(scene["params"]), "-o", str(output), "--chunk", "16", "--no-progress", *map(str, extra)]


def _nbar(safe) -> list:
    """``brdfcorr nbar`` of a ``safe`` fixture's SAFE folder into its ``out/``."""
    return ["nbar", safe["safe"], "-o", safe["out"] / "nbar.tif", "--no-progress"]
