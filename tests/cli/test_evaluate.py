"""`atr eval`'s details: what each false positive sits on, from the flight's world rebuilt without rendering."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from atr.config import AtrConfig
from atr.evaluation.runner import Flight, SceneRecord
from atr.evaluation.scoring import summarise
from atr.evaluation.tables import NOT_ON_A_VEHICLE, false_positives_on, flight_vehicles, rows
from cli.evaluate import execute, plan
from cli.main import build_parser

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "evaluation"))
from _small_flight import SMALL_FLIGHT  # noqa: E402


def _record(detections: list[tuple[str, np.ndarray, float]], target_m: np.ndarray) -> SceneRecord:
    return SceneRecord(
        frame=1,
        stamp_ns=0,
        truth=[{"name": "t72", "position_m": target_m.tolist(), "visible_fraction": 1.0}],
        detections=[
            {"target": name, "position_m": p.tolist(), "score": score}
            for name, p, score in detections
        ],
        time_ms=1.0,
    )


def test_false_positives_are_counted_by_the_vehicle_under_the_best_hypothesis():
    flight = Flight(scenario=2, run=1)
    names, positions, radii = vehicles = flight_vehicles(flight, AtrConfig().sim)
    ifv = positions[names.index("ifv")]
    truck = positions[names.index("truck6x6")]
    target = np.array([0.0, 0.0, 0.0])
    far = target + np.array([200.0, 200.0, 0.0])  # bare ground or a building, no vehicle
    records = [
        _record([("t72", target + 0.5, 10.0)], target),  # TP
        _record([("t72", ifv + 0.5, 9.0), ("t72", target, 5.0)], target),  # the IFV ranks first
        _record([("t72", truck, 9.0), ("ifv", ifv, 20.0)], target),  # only T-72 hypotheses count
        _record([("t72", far, 3.0)], target),
        _record([], target),  # FN
    ]
    outcomes = summarise(records, "t72", 0.1).outcomes
    assert outcomes == ("tp", "fp", "fp", "fp", "fn")
    assert vehicles[2].shape == (len(names),) and np.all(radii > 0)
    assert false_positives_on(records, outcomes, "t72", vehicles) == {
        "ifv": 1,
        "truck6x6": 1,
        NOT_ON_A_VEHICLE: 1,
    }


def test_an_invocation_whose_results_are_all_current_keeps_their_storage_and_reference_time(
    tmp_path,
):
    def details() -> dict:
        args = [*SMALL_FLIGHT, "--frames", "3", "--results", str(tmp_path)]
        p = plan(build_parser().parse_args(args))
        return rows(p, execute(p))[1][0]

    first = details()  # computes the run, builds its templates, times the reference workload
    again = details()  # reuses the run file: no template is built, nothing is timed
    assert first["template_storage_kb"] > 0
    assert again["template_storage_kb"] == first["template_storage_kb"]
    assert first["reference_ms"] > 0
    assert again["reference_ms"] == first["reference_ms"]
    assert again["outcomes"] == first["outcomes"]


def test_each_worker_gets_its_share_of_the_cores():
    # in a fresh interpreter, as a worker process starts
    code = (
        "import cv2, numba\n"
        "from atr.evaluation.experiment import _share_the_cores\n"
        "_share_the_cores(2)\n"
        "print(numba.get_num_threads(), cv2.getNumThreads(), numba.config.NUMBA_NUM_THREADS)\n"
    )
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True
    )
    numba_threads, cv2_threads, numba_most = map(int, out.stdout.split())
    share = max(1, (os.cpu_count() or 1) // 2)
    assert cv2_threads == share
    assert numba_threads == min(share, numba_most)
