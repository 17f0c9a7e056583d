"""FlightWatch on a real Zenoh bus: each Detections message reaches the callback with its frame's Truth and first
CameraPose (what the demo's live verdicts are judged with)."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from bus import codec, keys
from bus.pipeline import FlightWatch
from bus.session import open_session

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import peer_config  # noqa: E402

pytestmark = pytest.mark.e2e

UAV = "uav1"
WARM_UP_STAMP_NS = 1


def pose(x_m: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = x_m
    return T


def detections_message(frame: int, stamp: int) -> dict:
    return {
        "stamp_ns": stamp,
        "seq": frame,
        "version": 1,
        "cloud_seq": frame,
        "frame_seqs": [frame],
        "source": "sfm-gftt",
        "detections": [],
    }


def test_flight_watch_pairs_detections_with_truth_and_first_camera_pose(hub: str) -> None:
    scenes: dict[int, tuple] = {}  # by stamp: a Detections message may be sent more than once
    routed, answered = threading.Event(), threading.Event()

    def on_scene(truth, detections, camera_pose) -> None:
        if detections["stamp_ns"] == WARM_UP_STAMP_NS:
            routed.set()
        elif truth is not None and camera_pose is not None:
            # keys are not ordered against each other: the truth and the pose may come later
            scenes[detections["stamp_ns"]] = (truth, detections, camera_pose)
            answered.set()

    watching = open_session(peer_config(hub))
    publishing = open_session(peer_config(hub))
    watch = FlightWatch(watching, UAV, on_scene)
    try:
        # warm up: a Detections message is repeated until the watcher has seen one (routes are in place)
        warm_up = detections_message(frame=0, stamp=WARM_UP_STAMP_NS)
        for _ in range(100):
            publishing.put(keys.detections(UAV), codec.encode("Detections", warm_up))
            if routed.wait(0.05):
                break
        assert routed.is_set(), "the watcher never saw a Detections message"
        for frame, stamp in enumerate((1_000, 2_000)):
            truth = {
                "stamp_ns": stamp,
                "seq": frame,
                "version": 1,
                "frame_seq": frame,
                "T_world_cam": pose(10.0 * frame),
                "scenario": 1,
                "run": 1,
                "targets": [],
            }
            first = {
                "stamp_ns": stamp,
                "seq": 2 * frame,
                "version": 1,
                "frame_seq": frame,
                "T_world_cam": pose(frame + 0.5),
            }
            second = first | {"seq": 2 * frame + 1, "T_world_cam": pose(99.0)}
            detections = detections_message(frame, stamp)
            publishing.put(keys.truth(UAV), codec.encode("Truth", truth))
            publishing.put(keys.camera_pose(UAV), codec.encode("CameraPose", first))
            publishing.put(keys.camera_pose(UAV), codec.encode("CameraPose", second))
            for _ in range(100):
                answered.clear()
                publishing.put(keys.detections(UAV), codec.encode("Detections", detections))
                if answered.wait(0.05):
                    break
            assert len(scenes) == frame + 1, (
                f"frame {frame} was never paired with its truth and pose"
            )
    finally:
        watch.close()
        publishing.close()
        watching.close()

    for frame, (truth, detections, camera_pose) in enumerate(scenes.values()):
        assert truth["frame_seq"] == detections["cloud_seq"] == frame
        assert np.array_equal(truth["T_world_cam"], pose(10.0 * frame))
        # the frame's first camera pose, not the later one
        assert np.array_equal(camera_pose["T_world_cam"], pose(frame + 0.5))
