"""`atr eval` on Dask distributed: flights on a LocalCluster of worker processes (--jobs N) or on the cluster of
--scheduler give, scene by scene, the records the library's `run_flight` gives in this process (times aside);
every arm's bar is told its scenes and reaches them; the run store fills as flights finish, so an interrupted
evaluation resumes from it; an unreachable scheduler is one line and exit 2."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

import pytest

from atr.errors import ConfigError
from atr.evaluation.experiment import _templates_2d, _templates_3d, execute
from atr.evaluation.runner import run_flight
from atr.scaleout import host_slots, task_slots
from cli.evaluate import plan
from cli.main import build_parser

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _small_flight import SMALL_FLIGHT  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
ARGS = [*SMALL_FLIGHT, "--run", "3", "--frames", "3"]  # two flights (runs 4 and 3) of two scenes

pytestmark = pytest.mark.slow


def _plan(results: Path, *extra: str):
    return plan(build_parser().parse_args([*ARGS, *extra, "--results", str(results)]))


def _times_aside(results: dict) -> dict:
    """Every record with its times zeroed: what the scene computed, not how long it took."""
    return {
        run: [replace(r, time_ms=0.0, stages_ms={}) for r in records]
        for run, records in results.items()
    }


class _Bars:
    """An ArmProgress that keeps what it was told."""

    def __init__(self) -> None:
        self.totals: dict = {}
        self.steps: dict = defaultdict(list)

    def start(self, scenes) -> None:
        self.totals = dict(scenes)

    def advance(self, arm, scenes: int) -> None:
        self.steps[arm].append(scenes)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict:
    """Each flight through `run_flight` in this process, as the library runs one: what every engine must give."""
    p = _plan(tmp_path_factory.mktemp("reference"))
    _templates_3d(p)
    _templates_2d(p, print)
    out = {}
    for flight in p.flights:
        records = run_flight(flight, p.arms, p.config, p.templates_3d, p.templates_2d, p.b2d)
        out.update({(flight, arm): r for arm, r in records.items()})
    return out


def _check(out: dict, reference: dict, bars: _Bars, results: Path) -> None:
    assert _times_aside(out) == _times_aside(reference)
    assert any(r.detections for records in out.values() for r in records), "compare detections"
    assert len(list((results / "runs").glob("*.json"))) == len(reference)
    scenes = sum(len(records) for records in reference.values())
    assert sum(bars.totals.values()) == scenes
    assert {arm: sum(steps) for arm, steps in bars.steps.items()} == bars.totals


@pytest.mark.parametrize("jobs", [1, 2])
def test_flights_here_and_on_a_local_cluster_give_run_flights_records(jobs, reference, tmp_path):
    bars = _Bars()
    lines: list[str] = []
    out = execute(_plan(tmp_path), jobs=jobs, bars=bars, progress=lines.append)
    _check(out, reference, bars, tmp_path)
    if jobs == 1:  # in this process the bars move scene by scene
        assert all(step == 1 for steps in bars.steps.values() for step in steps)
    else:
        assert any("Dask LocalCluster: 2 worker processes" in line for line in lines)


def test_flights_on_the_cluster_of_a_scheduler(reference, tmp_path):
    from dask.distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        Client(cluster) as client,
    ):
        # each task divides its host's cores among the two workers there (cpu_count // 2 threads)
        assert client.submit(task_slots, host_slots(client), pure=False).result() == 2
        bars = _Bars()
        out = execute(_plan(tmp_path), scheduler=cluster.scheduler_address, bars=bars)
        # a worker whose sources are not the ones the results are keyed with refuses the flight
        other = _plan(tmp_path / "other")
        other.version = "0" * 16
        with pytest.raises(ConfigError, match="every worker needs the same checkout"):
            execute(other, scheduler=cluster.scheduler_address)
    _check(out, reference, bars, tmp_path)


def _atr(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "cli.main", *args],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, **(env or {})},
    )


def test_an_interrupted_evaluation_resumes_from_the_runs_it_saved(tmp_path):
    args = ["eval", *ARGS[1:], "--run", "2", "--results", str(tmp_path)]  # three flights
    interrupted = _atr(*args, "--jobs", "2")
    runs = tmp_path / "runs"
    deadline = time.monotonic() + 300
    while not list(runs.glob("*.json")) and interrupted.poll() is None:
        assert time.monotonic() < deadline, "no flight finished in 300 s"
        time.sleep(0.2)
    interrupted.send_signal(signal.SIGINT)  # as Ctrl-C: the cluster is shut down on the way out
    _, err = interrupted.communicate(timeout=120)
    assert interrupted.returncode == 130, err
    saved = {path: path.read_bytes() for path in runs.glob("*.json")}
    assert 1 <= len(saved) < 3, "the interrupt must come between flights"

    resumed = _atr(*args)
    _, err = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, err
    assert f"{len(saved)} current results reused" in err
    assert len(list(runs.glob("*.json"))) == 3
    assert all(path.read_bytes() == data for path, data in saved.items())  # reused, not redone


def test_an_unreachable_scheduler_is_one_line_and_exit_2(tmp_path):
    with socket.socket() as sock:  # a port with nobody behind it
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    done = _atr(
        "eval",
        *ARGS[1:],
        "--scheduler",
        address,
        "--results",
        str(tmp_path),
        env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"},
    )
    out, err = done.communicate(timeout=120)
    assert done.returncode == 2, out + err
    assert "Traceback" not in err
    assert (
        err.strip()
        .splitlines()[-1]
        .startswith(f"atr eval: cannot reach the Dask scheduler {address}")
    )
    assert not (tmp_path / "runs").exists()
