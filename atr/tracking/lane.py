"""Where a flight's whole searches run when they answer late (``tracking.whole_search_lag_frames``; ours).

A whole search among a family of templates takes 0.25-0.9 s, a guided scene a few tens of
milliseconds. With the lag on, ``GuidedSearch`` answers a scene that falls due a whole search while a
track is held as a guided one and hands the whole search to a lane, whose detections join the scene
``whole_search_lag_frames`` camera frames later. Which scene they join is fixed by frame numbers, not
by when the search ends, so the answers are the same whichever lane ran it:

- ``InPlaceLane`` runs the search when it is handed over, in the caller's process (the evaluation: its
  time counts in the scene that started it, as a whole scene's does without the lag);
- ``ProcessLane`` runs it in a worker process of its own, at a lower scheduling priority (the matcher
  service: guided scenes go on while it runs, and a scene waits for it only when its joining frame
  comes first).

A process, not a thread: much of a whole search is Python (grouping, RANSAC's bookkeeping, ICP calls)
and would hold the interpreter lock the guided scenes need. ``concurrent.futures`` with the ``spawn``
start method: the matcher's process holds Zenoh's threads, which a forked child must not inherit.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from collections.abc import Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from atr.errors import AtrError
from atr.recognition import RecognitionConfig, RecognitionResult, Template, recognize, warm_up


@dataclass(frozen=True)
class WholeSearch:
    """One whole search: ``recognize(scene_points_m, templates, config, **options)``."""

    templates: Sequence[Template]
    config: RecognitionConfig
    scene_points_m: np.ndarray
    options: dict[str, Any]

    def run(self) -> RecognitionResult:
        """Search, here."""
        return recognize(self.scene_points_m, self.templates, self.config, **self.options)


class InPlaceLane:
    """Runs each whole search when it is submitted, in this process."""

    def submit(self, search: WholeSearch) -> Future[RecognitionResult]:
        """Run the search now; the future holds its result or its AtrError."""
        done: Future[RecognitionResult] = Future()
        try:
            done.set_result(search.run())
        except AtrError as error:
            done.set_exception(error)
        return done

    def close(self) -> None:
        """Nothing to stop."""


# the worker process's templates: sent with its first search, kept for the next ones
_lane_templates: Sequence[Template] = ()


def _search_in_worker(search: WholeSearch, templates_sent: bool) -> RecognitionResult:
    global _lane_templates
    if templates_sent:
        _lane_templates = search.templates
    return replace(search, templates=_lane_templates).run()


# The worker's scheduling priority below the services' (Unix nice, 0-19): a whole search has frames
# to spare before its answer is due, a guided scene has none, so the search takes the cores they leave.
WORKER_NICENESS = 10


def _start_worker(parent_pid: int) -> None:
    """The worker's set-up: below the services' priority, and gone when its parent is."""
    os.nice(WORKER_NICENESS)
    _die_with(parent_pid)


def _die_with(parent_pid: int) -> None:
    """Exit when the process that started this worker is gone, however it went (a killed matcher's
    worker would otherwise live on, holding a core's worth of search).
    """

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(0.5)
        os._exit(0)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


class ProcessLane:
    """Runs whole searches one at a time in a worker process of its own.

    The templates cross to the worker with its first search only (a family of eleven is megabytes);
    a worker that died is started again with the next search; the search it had in hand raises
    ``BrokenProcessPool``.
    """

    def __init__(self) -> None:
        self._pool: ProcessPoolExecutor | None = None
        self._sent: Sequence[Template] | None = None  # the templates the worker holds

    def __enter__(self) -> ProcessLane:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def warm(self, config: RecognitionConfig | None = None) -> Future[int]:
        """Start the worker now (importing the matcher takes seconds), not with the first search, and
        with ``config`` load its kernels (``atr.recognition.warm_up``); without waiting. The future
        gives the worker's process id once it is warm.
        """
        pool = self._start()
        if config is not None:
            pool.submit(warm_up, config)
        return pool.submit(os.getpid)

    def submit(self, search: WholeSearch) -> Future[RecognitionResult]:
        """Queue the search in the worker."""
        pool = self._start()
        send = search.templates is not self._sent
        future = pool.submit(
            _search_in_worker, replace(search, templates=()) if not send else search, send
        )
        self._sent = search.templates
        future.add_done_callback(self._forget_if_broken)
        return future

    def close(self) -> None:
        """Stop the worker without waiting for a search in hand."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def _start(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(
                max_workers=1,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_start_worker,
                initargs=(os.getpid(),),
            )
            self._sent = None
        return self._pool

    def _forget_if_broken(self, future: Future[RecognitionResult]) -> None:
        if not future.cancelled() and isinstance(future.exception(), BrokenProcessPool):
            self._pool = None  # the worker died: the next search starts a new one
            self._sent = None


WholeSearchLane = InPlaceLane | ProcessLane
"""Where a whole search runs."""
