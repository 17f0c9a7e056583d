"""kill -9 of each service mid-flight under a real supervisor (issue: services that recover their state).

One short lock-step flight of the `local` layout; every few frames one more service is killed (as a crash
would: SIGKILL of its process) and restarted by the supervisor. Every frame must be answered (Detections) or
reported (an ErrorReport naming its stamp), the flight must go on to its end, frames after the last kill are
reconstructed and recognised, and the recording holds the whole flight across the recorder's restart.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from bus import keys, mcap_tools
from bus.recorder import RecorderConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _killed_flight import (  # noqa: E402
    UAV,
    Seen,
    fly,
    kill,
    problems_beyond_recorder_kills,
    unanswered,
)

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

SERVICES = ["pose_integrator", "sfm", "atr_matcher", "template_store", "recorder", "router"]
FIRST_KILL, EVERY, FRAMES = 2, 3, 22  # a kill after frames 2, 5, 8, ...; quiet frames at the end


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("killed")
    killed: dict[str, tuple[int, int]] = {}  # service -> (pid killed, when: wall-clock ns)
    schedule = {FIRST_KILL + EVERY * i: name for i, name in enumerate(SERVICES)}

    def kill_when(seen: Seen, supervisor) -> None:
        name = schedule.get(seen.answered())
        if name is not None and name not in killed:
            killed[name] = (kill(supervisor, name), time.time_ns())

    seen, out, supervisor = fly(tmp_path, FRAMES, kill_when)
    return seen, out, supervisor, killed


def test_every_service_was_killed_and_restarted(flight):
    _, _, supervisor, killed = flight
    assert sorted(killed) == sorted(SERVICES)
    for name in SERVICES:
        assert supervisor.running[name].restarts >= 1, f"{name} was not restarted"


def test_every_frame_is_answered_or_reported(flight):
    seen = flight[0]
    assert len(seen.frames) == FRAMES
    assert unanswered(seen) == []


def test_frames_after_the_kills_are_reconstructed_and_recognised(flight):
    seen = flight[0]
    last = sorted(seen.frames)[-2:]  # two quiet frames after the last restart
    for stamp in last:
        assert seen.detections.get(stamp) == 1, f"frame {seen.frames[stamp]}: one Detections"
        assert seen.cloud_points.get(stamp, 0) > 0, f"frame {seen.frames[stamp]}: an empty cloud"


def test_the_recording_holds_the_flight_across_the_recorder_restart(flight):
    seen, out, _, killed = flight
    assert len(mcap_tools.segments(out)) == 2, "a restarted recorder continues in a new segment"
    recorded = {
        message.publish_time
        for _, message in mcap_tools.iter_messages(out, topics=[keys.image(UAV)])
    }
    # every frame but those the recorder could not hold: in flight when it was killed (at most its
    # last flush interval) or sent before its successor was up (before the first frame it holds)
    kill_ns = killed["recorder"][1]
    back = [seen.seen_ns[s] for s in recorded if seen.seen_ns.get(s, 0) > kill_ns]
    assert back, "the restarted recorder holds the frames after its restart"
    flush_ns = RecorderConfig().flush_interval_s * 1e9
    down = {s for s, t in seen.seen_ns.items() if kill_ns - flush_ns <= t < min(back)}
    missing = set(seen.frames) - down - recorded
    assert not missing, [seen.frames[s] for s in sorted(missing)]
    assert len(down) < FRAMES // 2, "the recorder came back mid-flight"
    assert problems_beyond_recorder_kills(out, [killed["recorder"][1]]) == []
