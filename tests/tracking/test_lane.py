"""The whole-search lane's worker process: started once, and gone with the process that started it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from atr.errors import InputError
from atr.recognition import RecognitionConfig
from atr.tracking.lane import WORKER_NICENESS, InPlaceLane, ProcessLane, WholeSearch


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie is gone for our purpose (its parent, killed, cannot reap it; init will)
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_a_killed_matcher_s_worker_does_not_outlive_it() -> None:
    """A matcher killed by SIGKILL cannot stop its worker: the worker sees its parent gone and exits."""
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import time; from atr.tracking.lane import ProcessLane; "
            "print(ProcessLane().warm().result(), flush=True); time.sleep(120)",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        worker = int(child.stdout.readline())
        assert _alive(worker)
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    deadline = time.monotonic() + 20
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _alive(worker), f"the worker {worker} outlived its killed parent"


def test_the_worker_runs_below_the_service_s_priority() -> None:
    """A guided scene must not wait for the cores a whole search holds."""
    with ProcessLane() as lane:
        worker = lane.warm().result()
        ours, its = os.getpriority(os.PRIO_PROCESS, 0), os.getpriority(os.PRIO_PROCESS, worker)
    assert its == min(19, ours + WORKER_NICENESS)  # 19: the lowest priority there is


def test_a_closed_lane_stops_its_worker() -> None:
    with ProcessLane() as lane:
        worker = lane.warm(RecognitionConfig()).result()
        assert worker != os.getpid() and _alive(worker)
    deadline = time.monotonic() + 20
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _alive(worker)


@pytest.mark.parametrize("lane", [InPlaceLane(), ProcessLane()], ids=["in place", "process"])
def test_a_bad_cloud_s_error_comes_back_through_the_future(lane) -> None:
    future = lane.submit(WholeSearch([], RecognitionConfig(), np.array([[1.0, 2.0]]), {"seed": 0}))
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        future.result(timeout=120)
    lane.close()
