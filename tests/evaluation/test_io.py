"""Result files: keyed by every parameter and the code version, written atomically, reused only when current."""

from __future__ import annotations

import json
import math

from atr.evaluation.io import code_version, jsonable, load_run, run_key, save_run
from atr.evaluation.runner import Arm, Flight, SceneRecord


def test_key_changes_with_any_parameter():
    flight, arm = Flight(1, 3, 4), Arm("gftt-sfm", "shot")
    base = run_key(flight, arm, {"a": 1}, "v1")
    assert base == run_key(Flight(1, 3, 4), Arm("gftt-sfm", "shot"), {"a": 1}, "v1")
    others = {
        run_key(Flight(1, 3, 5), arm, {"a": 1}, "v1"),
        run_key(Flight(1, 3, 4, seed=1), arm, {"a": 1}, "v1"),
        run_key(flight, Arm("lidar", "shot"), {"a": 1}, "v1"),
        run_key(flight, arm, {"a": 2}, "v1"),
        run_key(flight, arm, {"a": 1}, "v2"),
        run_key(Flight(1, 3, 4, noise="shot"), arm, {"a": 1}, "v1"),
    }
    assert base not in others and len(others) == 6


def test_save_load_round_trip_and_stale_key(tmp_path):
    records = [
        SceneRecord(
            1,
            2,
            [{"name": "t72", "position_m": [1.0, 2.0, 0.0], "visible_fraction": 0.5}],
            [{"target": "t72", "position_m": [1.5, 2.0, 0.0], "score": 3.0}],
            float("nan"),
            {"icp": 1.0},
            10,
            None,
        )
    ]
    path = tmp_path / "r.json"
    save_run(path, Flight(1, 3), Arm("lidar", "fpfh"), "k1", records)
    json.loads(path.read_text())  # valid JSON: NaN written as null
    back = load_run(path, "k1")
    assert back is not None and back[0].detections == records[0].detections
    assert math.isnan(back[0].time_ms)
    assert load_run(path, "k2") is None
    assert load_run(tmp_path / "missing.json", "k1") is None


def test_code_version_tracks_sources(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\n")
    first = code_version(tmp_path)
    (tmp_path / "a.py").write_text("x = 2\n")
    assert code_version(tmp_path) != first


def test_jsonable_maps_nan_to_null():
    assert jsonable({"x": float("nan"), "y": (1, 2.5)}) == {"x": None, "y": [1, 2.5]}
