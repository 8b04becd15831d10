"""``brdfcorr run``'s progress starts with each scene's first pass (issue 28), as ``correct``'s does:
every dask pass of a scene (the angle and scale checks before the write, the write, the
assessment) is reported as it starts, with counts that only grow until the scene's event."""

from __future__ import annotations

from click.testing import CliRunner
from dask.callbacks import Callback

from brdfcorr.chain.config import load_config
from brdfcorr.chain.run import run_chain
from brdfcorr.cli import main


class _PassStarts(Callback):
    """Puts a ``("pass", {})`` marker into ``events`` when a dask computation starts (before the
    progress callback hears of it: entered first, called first)."""

    def __init__(self, events: list):
        super().__init__()
        self.events = events

    def _start(self, dsk):
        self.events.append(("pass", {}))


def test_every_pass_of_a_scene_is_reported_from_the_first(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=1)
    chain = write_chain(tmp_path, steps={"correct": {"limits": None}, "assess": {}})
    events: list = []
    with _PassStarts(events):
        report = run_chain(load_config(chain), progress=lambda event, info: events.append((event, dict(info))))
    assert report.ok
    first = next(index for index, (event, _) in enumerate(events) if event == "scene")
    passes = [index for index, (event, _) in enumerate(events[:first]) if event == "pass"]
    assert len(passes) >= 3  # checks before the write, the write, the assessment
    # Each pass, the first included, is reported at its start: a chunks event before the next pass.
    for start, end in zip(passes, passes[1:] + [first]):
        assert any(event == "chunks" for event, _ in events[start:end]), events[start:end]
    chunks = [info for event, info in events[:first] if event == "chunks"]
    done, totals = [info["done"] for info in chunks], [info["total"] for info in chunks]
    assert done == sorted(done) and totals == sorted(totals) and done[0] == 0
    assert done[-1] == totals[-1] > totals[0]  # the last pass ends the scene's count; later passes add tasks


def test_run_shows_one_task_bar_per_scene(tmp_path, make_scenes, write_chain):
    make_scenes(tmp_path, count=2)
    result = CliRunner().invoke(main, ["run", str(write_chain(tmp_path)), "--progress"])
    assert result.exit_code == 0, result.output
    assert "2/2" in result.stderr  # the scenes' bar
    for scene in ("line0_image", "line1_image"):
        assert f"{scene}:" in result.stderr  # the bar of each scene's tasks
