"""Progress of a chain run's scenes: :class:`ChunkProgress`, the dask callback that reports a
scene's tasks to the run's ``progress(event, info)`` callback (:mod:`brdfcorr.chain.run`)."""

from __future__ import annotations

import time
from collections.abc import Callable

from dask.callbacks import Callback

__all__ = ["ChunkProgress", "Progress", "CHUNK_EVENT_SECONDS"]

#: Least time between two ``"chunks"`` progress events of a scene [s].
CHUNK_EVENT_SECONDS = 0.2

Progress = Callable[[str, dict], None]


class ChunkProgress(Callback):
    """A dask callback (local schedulers) that reports the tasks of a scene's computations as
    ``progress("chunks", {"scene": name, "done": n, "total": n})``: at the start of each, at most
    every ``interval`` seconds, and when it ends. The computations run while it is active are
    counted together (the tasks of those that ended plus those of the running one), so the counts
    only grow from the scene's first pass to its last."""

    def __init__(self, scene: str, progress: Progress, interval: float = CHUNK_EVENT_SECONDS):
        super().__init__()
        self.scene, self.progress, self.interval = scene, progress, interval
        self._state: dict | None = None
        self._last = 0.0
        self._ended = 0  # tasks of the computations that ended

    def _counts(self) -> tuple[int, int]:
        state = self._state or {}
        done = len(state.get("finished", ()))
        total = done + sum(len(state.get(key, ())) for key in ("ready", "waiting", "running"))
        return self._ended + done, self._ended + total

    def _emit(self) -> None:
        done, total = self._counts()
        self._last = time.monotonic()
        self.progress("chunks", {"scene": self.scene, "done": done, "total": total})

    def _start_state(self, dsk, state) -> None:
        self._state = state
        self._emit()

    def _posttask(self, key, result, dsk, state, worker_id) -> None:
        if time.monotonic() - self._last >= self.interval:
            self._emit()

    def _finish(self, dsk, state, errored) -> None:
        if not errored:
            self._emit()
        self._ended = self._counts()[1]
        self._state = None
