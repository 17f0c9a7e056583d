"""`atr run` through the real service graph: a simulated flight replayed twice gives byte-identical data (§5).

Everything is real: `atr simulate` writes the flight, `atr run` starts the layout's processes on a Zenoh bus on
loopback, replays in lock-step and records; the recordings are read back with the mcap library.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from bus import codec, keys
from cli.flight_report import f1_line, summarise

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))
from _atr_cli import atr, simulate_small_flight  # noqa: E402
from _small_camera import SMALL_CAMERA  # noqa: E402

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


def data_messages(path: Path) -> dict[str, list[bytes]]:
    """Payloads per topic of every data message (status and timing carry wall-clock content)."""
    out: dict[str, list[bytes]] = {}
    with path.open("rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            if keys.is_data_key(channel.topic) and "/replayer/" not in channel.topic:
                out.setdefault(channel.topic, []).append(message.data)
    return out


def run_twice_identically(flight: Path, folder: Path, *settings: str) -> dict[str, list[bytes]]:
    """`atr run` the flight twice with these settings; the first run's data messages, after checking
    that both runs succeeded with the same bytes. The first run's recording is `folder`/a.mcap."""
    outs = [folder / "a.mcap", folder / "b.mcap"]
    done = [
        atr("run", str(flight), "--out", str(out), *SMALL_CAMERA, *settings, timeout_s=900)
        for out in outs
    ]
    assert all(d.returncode == 0 for d in done), [d.stdout + d.stderr for d in done]
    first, second = (data_messages(p) for p in outs)
    assert first == second
    return first


def matcher_stages(path: Path) -> list[dict[str, float]]:
    """The matcher's stage times per scene, in order."""
    stages = []
    with path.open("rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages():
            if channel.topic == "atr/uav1/atr_matcher/timing":
                stages.append(codec.unpack(message.data)["stages_ms"])
    return stages


@pytest.fixture(scope="module")
def flight(tmp_path_factory) -> Path:
    return simulate_small_flight(tmp_path_factory.mktemp("flight") / "flight.mcap", frames=4)


def test_run_twice_gives_identical_data_messages(flight, tmp_path):
    outs = [tmp_path / "a.mcap", tmp_path / "b.mcap"]
    done = [
        atr("run", str(flight), "--out", str(out), *SMALL_CAMERA, timeout_s=900) for out in outs
    ]
    assert all(d.returncode == 0 for d in done), [d.stdout + d.stderr for d in done]
    printed = [d.stdout for d in done]
    first, second = (data_messages(p) for p in outs)
    # A simulated flight carries its truth: the run prints its F1, judged from what it recorded.
    counts = summarise(outs[0])
    assert counts is not None and counts.tp + counts.fp + counts.fn + counts.tn == 3
    assert f1_line(counts) in printed[0] and f1_line(counts) in printed[1]
    # Every frame was answered and every stage published.
    assert len(first[keys.detections("uav1")]) == 4
    assert len(first[keys.sfm_cloud("uav1")]) == 4
    assert len(first[keys.relative_pose("uav1")]) == 3
    assert first.keys() == second.keys()
    for topic in first:
        assert first[topic] == second[topic], (
            f"{topic} differs between two runs of the same recording"
        )


def test_a_paced_run_answers_every_frame_and_times_each_scene_once(flight, tmp_path):
    out = tmp_path / "paced.mcap"
    done = atr("run", str(flight), "--out", str(out), "--rate", "4", *SMALL_CAMERA, timeout_s=900)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "replayed 4 frames (0 unanswered)" in done.stdout
    messages = data_messages(out)
    assert len(messages[keys.detections("uav1")]) == 4
    # each answer says where its cloud was seen from: the tracker weighs the line of sight by it
    clouds = {c["seq"]: c for c in map(codec.unpack, messages[keys.sfm_cloud("uav1")])}
    for answer in map(codec.unpack, messages[keys.detections("uav1")]):
        assert np.array_equal(answer["viewpoint_m"], clouds[answer["cloud_seq"]]["viewpoint_m"])
    timings = []
    with out.open("rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages():
            if channel.topic == "atr/uav1/atr_matcher/timing":
                timings.append(codec.unpack(message.data))
    assert len(timings) == 4
    for timing in timings:
        # the matcher's whole wall time is its total, not one more stage to add up; the stages are
        # parts of it (no upper bound: how much a loaded machine adds between stages is not a property)
        assert "total" not in timing["stages_ms"]
        assert sum(timing["stages_ms"].values()) <= timing["total_ms"]


def test_track_guided_search_through_the_services_is_deterministic_and_confirms(tmp_path):
    """With `tracking.guided_search` the matcher's answers depend on the scenes before; the same
    recording still gives the same bytes, and the scenes after a confirmed track only confirm it."""
    flight = simulate_small_flight(tmp_path / "flight.mcap", frames=7)
    first = run_twice_identically(flight, tmp_path, "--set", "tracking.guided_search=true")
    detections = [codec.unpack(m)["detections"] for m in first[keys.detections("uav1")]]
    confirmed = matcher_stages(tmp_path / "a.mcap")  # the matcher's scenes, in order
    assert len(confirmed) == len(detections) == 7
    guided_scenes = [
        k for k, stages in enumerate(confirmed) if stages["describe"] == 0.0 and stages["icp"] > 0
    ]
    # a guided scene (no description: the tracks' poses confirmed by ICP) found the T-72 again
    assert any(any(d["target"] == "t72" for d in detections[k]) for k in guided_scenes), (
        guided_scenes,
        [[d["target"] for d in ds] for ds in detections],
    )
    # the sfm matched a guided scene's pair only where the matcher looked: its cloud says so, and holds
    # fewer points than a scene matched whole
    assert len(first[keys.guidance("uav1")]) == 7
    clouds = [codec.unpack(m) for m in first[keys.sfm_cloud("uav1")]]
    windowed = [k for k, cloud in enumerate(clouds) if len(cloud.get("regions_m", ())) > 0]
    # the second scene tried the first one's tentative tracks where they stand (ICP, no description)
    # on a pair matched whole: sfm gets no guidance before a track is confirmed
    assert guided_scenes[0] == 2 and 2 not in windowed
    assert windowed == guided_scenes[1:]
    whole_points = [len(clouds[k]["points_m"]) for k in range(1, 7) if k not in windowed]
    assert all(len(clouds[k]["points_m"]) < min(whole_points) for k in windowed), [
        len(cloud["points_m"]) for cloud in clouds
    ]


def test_lagged_whole_searches_through_the_services_are_deterministic(tmp_path):
    """With `tracking.whole_search_lag_frames` the matcher answers a scene that a held track makes
    due a whole search by confirming its tracks, while the whole search runs in a worker process of
    its own and answers a later scene: the same recording still gives the same bytes, and the T-72
    is found throughout."""
    flight = simulate_small_flight(tmp_path / "flight.mcap", frames=7)
    first = run_twice_identically(
        flight,
        tmp_path,
        *("--set", "tracking.guided_search=true", "--set", "tracking.full_search_every_frames=3"),
        *("--set", "tracking.whole_search_lag_frames=2"),
    )
    detections = [codec.unpack(m)["detections"] for m in first[keys.detections("uav1")]]
    clouds = [codec.unpack(m) for m in first[keys.sfm_cloud("uav1")]]
    stages = matcher_stages(tmp_path / "a.mcap")
    assert len(detections) == len(clouds) == len(stages) == 7
    assert all(any(d["target"] == "t72" for d in answer) for answer in detections[1:]), detections
    # frames 1 and 2 are matched whole and answered by their own searches (no track is held yet):
    # frame 1's whole, frame 2's a try of frame 1's tentative tracks where they stand; frame 5, three
    # frames after frame 2, is matched whole too, but answered at the held T-72's place while its
    # whole search runs aside
    whole = [k for k in range(1, 7) if len(clouds[k].get("regions_m", ())) == 0]
    assert whole == [1, 2, 5], [len(c.get("regions_m", ())) for c in clouds]
    assert stages[1]["describe"] > 0
    assert stages[2]["describe"] == 0.0 and stages[2]["icp"] > 0
    assert stages[5]["describe"] == 0.0 and stages[5]["icp"] > 0
