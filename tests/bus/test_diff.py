"""`bus.diff.diff_recordings` on small MCAP files written with the project's writer and codec: one change
at a time, each caught with its topic and field path; tolerances hide what they should and nothing more."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from atr.errors import ConfigError, RecordingError
from atr.regression.compare import pose_difference
from atr.regression.tolerances import parse_tolerances
from bus import codec, schemas
from bus.diff import diff_recordings
from bus.mcap_tools import ChunkedWriter

STAMPS = [1_000_000_000, 1_250_000_000, 1_500_000_000]
CLOUD, DETECTIONS = "atr/uav1/sfm/cloud", "atr/uav1/detections"
ERRORS, STATUS = "atr/uav1/sfm/errors", "atr/uav1/sfm/status"


def _pose(x: float, yaw_deg: float = 0.0) -> np.ndarray:
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = [x, 25.0, 0.0]
    return T


def flight(**change) -> list[tuple[str, str, dict]]:
    """Messages of a 3-frame run; `change` alters one thing (see the tests)."""
    out = []
    for k, stamp in enumerate(STAMPS):
        points = np.arange(30, dtype=np.float32).reshape(10, 3) + k
        if change.get("point") and k == 1:
            points[3, 1] += change["point"]
        detection = {
            "target": "t72",
            "descriptor": "shot",
            "T_world_target": _pose(
                -5.0 + change.get("moved_m", 0.0) * (k == 2), change.get("turned", 0.0) * (k == 2)
            ),
            "score": 150.0 + change.get("score", 0.0) * (k == 2),
            "overlap": 0.6,
            "inliers": 40,
        }
        out.append(
            (
                CLOUD,
                "PointCloud",
                {
                    "stamp_ns": stamp,
                    "seq": k,
                    "version": 1,
                    "source": "sfm-gftt",
                    "frame_seqs": [k],
                    "points_m": points,
                },
            )
        )
        if not (change.get("drop_frame") and k == 2):
            dets = [] if (change.get("lose_target") and k == 1) else [detection]
            out.append(
                (
                    DETECTIONS,
                    "Detections",
                    {
                        "stamp_ns": stamp,
                        "seq": k,
                        "version": 1,
                        "cloud_seq": k,
                        "frame_seqs": [k],
                        "source": "sfm-gftt",
                        "detections": dets,
                    },
                )
            )
        out.append(
            (
                STATUS,
                "Status",
                {
                    "stamp_ns": stamp + change.get("clock", 0),
                    "seq": k,
                    "version": 1,
                    "service": "sfm",
                    "uav": "uav1",
                    "host": "h",
                    "pid": 1 + change.get("pid", 0),
                    "state": "running",
                    "uptime_s": 1.0 * k,
                    "counters": {},
                    "handled_by_key": {},
                },
            )
        )
    out.append(
        (
            ERRORS,
            "ErrorReport",
            {
                "stamp_ns": STAMPS[1],
                "seq": 0,
                "version": 1,
                "service": "sfm",
                "key": "atr/uav1/imu",
                "error_type": "InputError",
                "reason": change.get("reason", "bad batch"),
                "input_seq": 1,
                "input_stamp_ns": STAMPS[1],
                "input_source": f"replayer@h:{100 + change.get('pid', 0)}",
                "count": 1,
            },
        )
    )
    return out


def write(
    path: Path, messages: list[tuple[str, str, dict]], types: dict[str, str] | None = None
) -> Path:
    with ChunkedWriter(path) as writer:
        schema_ids, channel_ids = {}, {}
        for topic, type_name, message in messages:
            type_name = (types or {}).get(topic, type_name)
            if type_name not in schema_ids:
                schema_ids[type_name] = writer.add_schema(
                    type_name, "jsonschema", schemas.schema_bytes(type_name)
                )
            if topic not in channel_ids:
                channel_ids[topic] = writer.add_channel(topic, "msgpack", schema_ids[type_name])
            stamp = message["stamp_ns"]
            writer.add_message(
                channel_ids[topic], stamp, stamp, message["seq"], codec.pack(message)
            )
    return path


def rules(*items: dict):
    return parse_tolerances({"rules": list(items)})


@pytest.fixture
def base(tmp_path) -> Path:
    return write(tmp_path / "base.mcap", flight())


def test_identical_recordings_are_the_same_without_decoding(base, tmp_path):
    new = write(tmp_path / "new.mcap", flight())
    report = diff_recordings(base, new)
    assert report.same
    cloud = next(t for t in report.topics if t.topic == CLOUD)
    assert (cloud.identical, cloud.tolerated, cloud.differing) == (3, 0, 0)


def test_status_clock_and_process_ids_are_ignored_by_default(base, tmp_path):
    new = write(tmp_path / "new.mcap", flight(clock=7, pid=5))
    report = diff_recordings(base, new)
    assert report.same
    assert next(t for t in report.topics if t.topic == STATUS).ignored


def test_an_error_reason_change_is_caught(base, tmp_path):
    report = diff_recordings(base, write(tmp_path / "new.mcap", flight(reason="other")))
    [topic] = report.differing_topics
    assert topic.topic == ERRORS and topic.first[1].path == "reason"


def test_one_point_moved_names_topic_element_and_both_values(base, tmp_path):
    report = diff_recordings(base, write(tmp_path / "new.mcap", flight(point=1e-3)))
    [topic] = report.differing_topics
    assert topic.topic == CLOUD and topic.differing == 1 and topic.identical == 2
    stamp, first = topic.first
    assert stamp == STAMPS[1] and first.path == "points_m[3,1]"
    assert (float(first.base), float(first.new)) == (11.0, np.float32(11.0) + np.float32(1e-3))
    assert report.frames[STAMPS[1]][CLOUD][0] == "differs"
    assert report.frames[STAMPS[0]][CLOUD][0] == "identical"


def test_a_tolerance_hides_a_float_change_and_nothing_more(base, tmp_path):
    new = write(tmp_path / "new.mcap", flight(point=1e-3, score=0.5))
    hide_points = {"topic": "atr/*/sfm/cloud", "field": "points_m", "abs": 2e-3}
    report = diff_recordings(base, new, rules(hide_points))
    [topic] = report.differing_topics  # the score change is still caught
    assert topic.topic == DETECTIONS and topic.first[1].path == "detections[t72#0].score"
    assert next(t for t in report.topics if t.topic == CLOUD).tolerated == 1
    # Too tight a tolerance hides nothing; a tolerance on the score hides the rest.
    tight = {**hide_points, "abs": 1e-4}
    assert CLOUD in [t.topic for t in diff_recordings(base, new, rules(tight)).differing_topics]
    score = {"topic": DETECTIONS, "field": "detections.score", "rel": 0.01}
    assert diff_recordings(base, new, rules(hide_points, score)).same


def test_detections_are_compared_by_pose_in_metres_and_degrees(base, tmp_path):
    new = write(tmp_path / "new.mcap", flight(moved_m=0.3, turned=2.0))
    [topic] = diff_recordings(base, new).differing_topics
    first = topic.first[1]
    assert first.path == "detections[t72#0].T_world_target"
    assert "moved 0.3 m" in first.detail and "turned 2 deg" in first.detail
    pose = {"topic": DETECTIONS, "field": "detections.T_world_target", "metres": 0.5, "degrees": 3}
    assert diff_recordings(base, new, rules(pose)).same
    assert not diff_recordings(base, new, rules({**pose, "metres": 0.1})).same
    assert not diff_recordings(base, new, rules({**pose, "degrees": 1})).same


def test_a_lost_target_and_a_missing_frame(base, tmp_path):
    lost = diff_recordings(base, write(tmp_path / "lost.mcap", flight(lose_target=True)))
    first = lost.differing_topics[0].first[1]
    assert (
        first.path == "detections[t72#0]"
        and first.new == "<none>"
        and "target lost" in first.detail
    )
    dropped = diff_recordings(base, write(tmp_path / "drop.mcap", flight(drop_frame=True)))
    [topic] = dropped.differing_topics
    assert topic.only_base == [STAMPS[2]] and topic.only_new == []
    assert "1 only in base" in topic.summary()


def test_ignore_rule_hides_a_field_of_a_topic(base, tmp_path):
    new = write(tmp_path / "new.mcap", flight(reason="other"))
    assert diff_recordings(
        base, new, rules({"topic": "*/errors", "field": "reason", "ignore": True})
    ).same
    assert diff_recordings(base, new, rules({"topic": ERRORS, "ignore": True})).same
    assert not diff_recordings(
        base, new, rules({"topic": "*/errors", "field": "count", "ignore": True})
    ).same


def test_schema_mismatch_and_unreadable_files_are_errors(base, tmp_path):
    other = write(tmp_path / "other.mcap", flight(), types={ERRORS: "Timing"})
    with pytest.raises(RecordingError, match=f"schema mismatch on {ERRORS}"):
        diff_recordings(base, other)
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"not an mcap file at all" * 10)
    with pytest.raises(RecordingError, match="garbage.mcap"):
        diff_recordings(base, garbage)
    with pytest.raises(RecordingError, match="does not exist"):
        diff_recordings(base, tmp_path / "missing.mcap")


@pytest.mark.parametrize(
    ("rule", "message"),
    [
        ({"topic": "a", "field": "b", "abs": -1}, "'abs' is -1"),
        ({"topic": "a", "field": "b"}, "accepts no difference"),
        ({"topic": "a", "field": "b", "absolute": 1}, "unknown keys"),
        ({"field": "b", "abs": 1}, "needs 'topic'"),
        ({"topic": "a", "abs": 1}, "without 'field' must be 'ignore: true'"),
    ],
)
def test_bad_tolerance_rules_are_refused_by_name(rule, message):
    with pytest.raises(ConfigError, match=message):
        rules(rule)


def test_pose_difference_in_metres_and_degrees():
    metres, degrees = pose_difference(_pose(0.0), _pose(3.0, 10.0))
    assert metres == pytest.approx(3.0) and degrees == pytest.approx(10.0)
    assert pose_difference(_pose(1.0, 1e-6), _pose(1.0))[1] == pytest.approx(1e-6, rel=1e-3)


def test_a_recording_in_segments_is_compared_as_one(base, tmp_path):
    """A restarted recorder continues in flight.1.mcap: the diff reads both, and a segment's
    messages are not reported as missing."""
    messages = flight()
    half = len(messages) // 2
    split = tmp_path / "split"
    split.mkdir()
    write(split / "flight.mcap", messages[:half])
    write(split / "flight.1.mcap", messages[half:])
    assert diff_recordings(base, split / "flight.mcap").same
    assert not diff_recordings(base, write(tmp_path / "half.mcap", messages[:half])).same
