"""The demo's verdicts: judged as `atr eval` judges a scene (relative to the sensor), live and from a recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mcap.writer import Writer

from bus import codec, keys
from bus.pipeline import flight_scenes
from cli.flight_report import scene_line, score, summarise, summarise_tracks, track_line

STAMP_NS = 2_000_000_000
TARGET_M = np.array([50.0, 0.0, 0.0])
DRIFT_M = np.array([6.0, -2.0, 0.5])  # the pose integrator's error at this frame


def pose(position_m: np.ndarray, yaw_deg: float = 0.0) -> np.ndarray:
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = position_m
    return T


T_CAM_TRUE = pose(np.array([0.0, 0.0, 30.0]))
T_CAM_EST = pose(np.array([0.0, 0.0, 30.0]) + DRIFT_M, yaw_deg=3.0)


def messages(source: str, T_world_target: np.ndarray) -> tuple[dict, dict, dict]:
    truth = {
        "stamp_ns": STAMP_NS,
        "seq": 1,
        "version": 1,
        "frame_seq": 1,
        "T_world_cam": T_CAM_TRUE,
        "scenario": 1,
        "run": 1,
        "targets": [{"name": "t72", "T_world_target": pose(TARGET_M), "visible_fraction": 0.9}],
    }
    detections = {
        "stamp_ns": STAMP_NS,
        "seq": 1,
        "version": 1,
        "cloud_seq": 1,
        "frame_seqs": [0, 1],
        "source": source,
        "detections": [
            {
                "target": "t72",
                "descriptor": "shot",
                "T_world_target": T_world_target,
                "score": 80.0,
                "overlap": 0.5,
                "inliers": 30,
            }
        ],
    }
    camera_pose = {
        "stamp_ns": STAMP_NS,
        "seq": 1,
        "version": 1,
        "frame_seq": 1,
        "T_world_cam": T_CAM_EST,
    }
    return truth, detections, camera_pose


def seen_through_the_estimated_pose() -> np.ndarray:
    """Where an SfM cloud placed with the drifted camera pose puts a target the camera sees exactly."""
    return T_CAM_EST @ np.linalg.inv(T_CAM_TRUE) @ pose(TARGET_M)


def test_an_sfm_detection_is_judged_relative_to_the_sensor():
    T_found = seen_through_the_estimated_pose()
    assert np.linalg.norm(T_found[:3, 3] - TARGET_M) > 2.0  # in the world frame it would be an FP
    verdict = score(*messages("sfm-gftt", T_found))
    assert verdict.outcome == "tp"
    assert verdict.translation_error_m < 1e-9
    assert "-> TP, error 0.00 m" in scene_line(*messages("sfm-gftt", T_found))


def test_a_lidar_detection_is_placed_with_the_true_pose_so_drift_does_not_excuse_it():
    verdict = score(*messages("lidar", seen_through_the_estimated_pose()))
    assert verdict.outcome == "fp"
    truth, detections, _ = messages("lidar", pose(TARGET_M + [0.3, 0.0, 0.0]))
    assert score(truth, detections, None).outcome == "tp"


def test_without_a_camera_pose_the_world_frame_is_used():
    truth, detections, _ = messages("sfm-gftt", seen_through_the_estimated_pose())
    assert score(truth, detections, None).outcome == "fp"


def write_recording(path: Path, messages: list[tuple[str, dict]]) -> None:
    """An MCAP file of bus messages, as the recorder writes them (msgpack payloads)."""
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        for i, (key, message) in enumerate(messages):
            schema = writer.register_schema(keys.message_type(key), "jsonschema", b"{}")
            channel = writer.register_channel(key, "msgpack", schema)
            payload = codec.encode(keys.message_type(key), message)
            writer.add_message(
                channel, log_time=STAMP_NS + i, data=payload, publish_time=STAMP_NS + i
            )
        writer.finish()


def test_a_recorded_flight_is_summarised_with_the_camera_pose_of_each_frame(tmp_path: Path):
    path = tmp_path / "flight.mcap"
    truth, detections, camera_pose = messages("sfm-gftt", seen_through_the_estimated_pose())
    write_recording(
        path,
        [
            (keys.truth("uav1"), truth),
            (keys.camera_pose("uav1"), camera_pose),
            (keys.detections("uav1"), detections),
        ],
    )

    [(t, d, c)] = flight_scenes(path)
    assert t["frame_seq"] == 1 and d["source"] == "sfm-gftt"
    assert np.array_equal(c["T_world_cam"], T_CAM_EST)
    counts = summarise(path)
    assert (counts.tp, counts.fp, counts.fn) == (1, 0, 0)


def test_nothing_to_judge_gives_no_counts(tmp_path: Path):
    truth, detections, camera_pose = messages("sfm-gftt", seen_through_the_estimated_pose())
    real_flight = tmp_path / "real.mcap"  # no truth on the bus
    write_recording(
        real_flight,
        [(keys.camera_pose("uav1"), camera_pose), (keys.detections("uav1"), detections)],
    )
    assert summarise(real_flight) is None
    unanswered = tmp_path / "unanswered.mcap"  # the pipeline never answered a pair
    write_recording(unanswered, [(keys.truth("uav1"), truth)])
    assert summarise(unanswered) is None


def tracks_message(state: str, T_world_target: np.ndarray) -> dict:
    """The tracker's answer to the scene: one track of the target in the given state."""
    return {
        "stamp_ns": STAMP_NS,
        "seq": 1,
        "version": 1,
        "detections_seq": 1,
        "tracks": [
            {
                "id": 7,
                "target": "t72",
                "state": state,
                "T_world_target": T_world_target,
                "covariance": np.eye(4),
                "yaw_ambiguous": False,
                "hits": 3,
                "supporting_stamps_ns": [STAMP_NS],
                "first_seen_ns": STAMP_NS,
                "last_seen_ns": STAMP_NS,
            }
        ],
    }


def test_recorded_tracks_are_judged_relative_to_the_sensor_and_only_once_established(
    tmp_path: Path,
):
    truth, detections, camera_pose = messages("sfm-gftt", seen_through_the_estimated_pose())
    scene = [
        (keys.truth("uav1"), truth),
        (keys.camera_pose("uav1"), camera_pose),
        (keys.detections("uav1"), detections),
    ]
    for state, outcome in [("confirmed", (1, 0, 0)), ("lost", (1, 0, 0)), ("tentative", (0, 0, 1))]:
        path = tmp_path / f"{state}.mcap"
        track = tracks_message(state, seen_through_the_estimated_pose())
        write_recording(path, [*scene, (keys.tracks("uav1"), track)])
        result = summarise_tracks(path)
        assert (result.counts.tp, result.counts.fp, result.counts.fn) == outcome, state
        assert result.false_tracks == 0
    # a confirmed track 5 m off the target is a false track and an FP, and the line says so
    off = seen_through_the_estimated_pose() @ pose(np.array([5.0, 0.0, 0.0]))
    path = tmp_path / "off.mcap"
    write_recording(path, [*scene, (keys.tracks("uav1"), tracks_message("confirmed", off))])
    result = summarise_tracks(path)
    assert (result.counts.tp, result.counts.fp, result.false_tracks) == (0, 1, 1)
    assert "1 false confirmed tracks" in track_line(result)
    assert "never confirmed" in track_line(result)
    # a flight without a tracker has no track figures
    path = tmp_path / "untracked.mcap"
    write_recording(path, scene)
    assert summarise_tracks(path) is None
