"""One progress bar per command (issue 38): ``nbar --progress`` restarted its bar at every dask pass
(tqdm's dask callback makes a bar per computation); now one bar counts the tasks of every pass,
its total growing as each pass starts."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.testing import write_sentinel2_safe

MTD = Path(__file__).resolve().parents[1] / "data" / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"
#: A frame of the bar as tqdm draws it: "nbar:  56%|█████▋    | 9/16 [...]".
FRAME = re.compile(r"^nbar:\s+\d+%\|[^|]*\| (\d+)/(\d+) ")


def _frames(stderr: str) -> list[tuple[int, int]]:
    """(count, total) of every frame drawn, in order (tqdm redraws a bar after a carriage return)."""
    return [(int(match[1]), int(match[2])) for part in stderr.split("\r") if (match := FRAME.match(part))]


@pytest.mark.parametrize("extra", [[], ["--view-band", "each"]])
def test_nbar_shows_one_bar_over_all_its_passes(tmp_path, extra):
    safe = write_sentinel2_safe(tmp_path / "in", MTD, size=16)
    result = CliRunner().invoke(main, ["nbar", str(safe), "-o", str(tmp_path / "out.tif"), "--progress", *extra])
    assert result.exit_code == 0, result.output
    frames = _frames(result.stderr)
    assert frames, result.stderr
    counts = [count for count, _ in frames]
    # One bar: it starts once (count 0) and its count never goes back.
    assert counts.count(0) == 1 and counts == sorted(counts), frames
    # It spans several passes (the checks before the write, the write): the total grew after the
    # first pass's start (tqdm's own callback drew a new bar, from 0, for each).
    assert frames[-1][1] > frames[0][1], frames
