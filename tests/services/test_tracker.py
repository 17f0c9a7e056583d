"""services/tracker on a real Zenoh bus: Detections in, one Tracks per scene out, bad scenes reported."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "schemas"))
from conftest import REPO, bus_env, peer_config, stop_process  # noqa: E402
from test_codec import assert_same  # noqa: E402

from atr.tracking import Tracker, TrackInput  # noqa: E402
from bus.node import Node  # noqa: E402
from services.tracker.main import track_message  # noqa: E402

pytestmark = pytest.mark.e2e
STEP_NS = 500_000_000


def _pose(x: float, yaw: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    T[:3, 3] = [x, 5.0, 0.0]
    return T


def _detections(k: int, poses: list[np.ndarray]) -> dict:
    return {
        "stamp_ns": 1_000_000_000 + k * STEP_NS,
        "cloud_seq": k,
        "frame_seqs": [k, k + 1],
        "source": "sfm-gftt",
        "detections": [
            {
                "target": "t72",
                "descriptor": "shot",
                "T_world_target": T,
                "score": 0.6,
                "overlap": 0.7,
                "inliers": 9,
            }
            for T in poses
        ],
    }


def _collect(node: Node, want: int, timeout_s: float = 20.0) -> dict[str, list]:
    got: dict[str, list] = {}
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and sum(map(len, got.values())) < want:
        for message in node.events(timeout_s=0.2):
            got.setdefault(message.key, []).append(message.data)
    return got


def _wait_running(node: Node, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for message in node.events(timeout_s=0.2):
            if message.key.endswith("/status") and message.data["state"] == "running":
                return
    raise TimeoutError("tracker not running")


def test_tracks_per_scene_same_as_the_library_and_bad_scenes_reported(hub):
    proc = subprocess.Popen(
        [sys.executable, "-m", "cli.main", "service", "tracker", "--uav", "uav1"],
        env=bus_env(hub),
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    inputs = ["atr/uav1/tracks", "atr/uav1/tracker/errors", "atr/uav2/tracks"]
    try:
        with Node(
            "driver",
            "uav1",
            [*inputs, "atr/uav1/tracker/status"],
            zenoh_config=peer_config(hub),
            heartbeat_s=60,
        ) as node:
            _wait_running(node)
            time.sleep(0.5)  # let gossip link the peers
            rng = np.random.default_rng(3)
            scenes = [
                [_pose(10 + rng.normal(0, 0.3), 0.4 + rng.normal(0, 0.05)), _pose(60.0 * k, 2.0)]
                for k in range(5)
            ]
            for k, poses in enumerate(scenes):
                node.publish("atr/uav1/detections", _detections(k, poses))
            # a second UAV's detections are not this tracker's; an old stamp is refused, reported
            node.publish("atr/uav2/detections", _detections(9, scenes[0]))
            node.publish("atr/uav1/detections", _detections(2, scenes[0]))
            # the first scene of a new flight (its clock starts again) gets a new tracker
            new_flight = _detections(0, scenes[1]) | {"stamp_ns": 1_000_000_000 - STEP_NS}
            node.publish("atr/uav1/detections", new_flight)
            got = _collect(node, want=7)
    finally:
        assert stop_process(proc) == 0, proc.stdout.read().decode(errors="replace")

    tracks = [m for m in got.get("atr/uav1/tracks", []) if m["seq"] is not None]
    *tracks, restarted = tracks
    assert [m["stamp_ns"] for m in tracks] == [1_000_000_000 + k * STEP_NS for k in range(5)]
    assert restarted["stamp_ns"] == 1_000_000_000 - STEP_NS
    assert [t["hits"] for t in restarted["tracks"]] == [1, 1]  # nothing of the first flight
    assert "atr/uav2/tracks" not in got
    (error,) = got["atr/uav1/tracker/errors"]
    assert error["error_type"] == "InputError" and "not after" in error["reason"]
    assert error["input_stamp_ns"] == 1_000_000_000 + 2 * STEP_NS
    # the service's tracks are the library's, field for field and bit for bit
    tracker = Tracker()
    for k, poses in enumerate(scenes):
        expected = [
            track_message(t)
            for t in tracker.update(
                [TrackInput.from_pose("t72", T) for T in poses], 1_000_000_000 + k * STEP_NS
            )
        ]
        assert_same(expected, tracks[k]["tracks"])
    final = {t["id"]: t for t in tracks[-1]["tracks"]}
    assert final[1]["state"] == "confirmed" and final[1]["hits"] == 5
    assert all(t["state"] == "tentative" or t["hits"] == 1 for i, t in final.items() if i != 1)
    assert sum(t["state"] == "confirmed" for t in final.values()) == 1
