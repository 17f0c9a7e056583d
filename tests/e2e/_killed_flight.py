"""A short simulated flight through the `local` layout under a real supervisor, with kill -9 of its services.

The layout's processes run as `atr up` runs them (bus.launcher.Supervisor, restarted when they die); the
sensor source flies in lock-step with the small camera. An observer session on the hub (with the bus's own
recovering subscribers) notes what every frame got: Detections, or an ErrorReport naming its stamp.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import zenoh

from bus import codec, keys, reliable
from bus.launcher import Supervisor, load_layout, observer_session, wait_until_ready
from bus.pipeline import free_hub_endpoint

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _small_camera import SMALL_CAMERA  # noqa: E402

UAV = "uav1"


@dataclass
class Seen:
    """What the observer saw on the bus, per frame stamp."""

    frames: dict[int, int] = field(default_factory=dict)  # stamp_ns -> frame_seq (IMU batches)
    seen_ns: dict[int, int] = field(default_factory=dict)  # stamp_ns -> wall clock when first seen
    detections: dict[int, int] = field(default_factory=dict)  # stamp_ns -> how many
    reported: dict[int, list[str]] = field(default_factory=dict)  # stamp_ns -> error reasons
    cloud_points: dict[int, int] = field(default_factory=dict)  # stamp_ns -> points of its cloud
    lock: threading.Lock = field(default_factory=threading.Lock)

    def answered(self) -> int:
        """Frames with Detections or an ErrorReport naming them."""
        with self.lock:
            return sum(1 for s in self.frames if s in self.detections or s in self.reported)


def _message(sample: zenoh.Sample) -> dict:
    return codec.unpack(sample.payload.to_bytes())


def fly(
    tmp_path: Path,
    frames: int,
    kill_when: Callable[[Seen, Supervisor], None],
    timeout_s: float = 120.0,
) -> tuple[Seen, Path, Supervisor]:
    """Fly `frames` frames; `kill_when(seen, supervisor)` is called every 50 ms and may kill.

    Returns what was seen, the recording and the (stopped) supervisor.
    """
    out = tmp_path / "flight.mcap"
    layout = load_layout("local", {"out": str(out), "hub": free_hub_endpoint()})
    os.environ["ATR_STATE_DIR"] = str(
        tmp_path / "state"
    )  # read by the services the supervisor starts
    overrides = [a for a in SMALL_CAMERA if a != "--set"]
    supervisor = Supervisor(
        layout, overrides=overrides, skip_roles=("source",), log_dir=tmp_path / "logs"
    )
    seen = Seen()

    def on_imu(sample: zenoh.Sample) -> None:
        m = _message(sample)
        with seen.lock:
            seen.frames[int(m["stamp_ns"])] = int(m["frame_seq"])
            seen.seen_ns.setdefault(int(m["stamp_ns"]), time.time_ns())

    def on_detections(sample: zenoh.Sample) -> None:
        stamp = int(_message(sample)["stamp_ns"])
        with seen.lock:
            seen.detections[stamp] = seen.detections.get(stamp, 0) + 1

    def on_error(sample: zenoh.Sample) -> None:
        m = _message(sample)
        if m.get("input_stamp_ns") is not None:
            with seen.lock:
                seen.reported.setdefault(int(m["input_stamp_ns"]), []).append(str(m["reason"]))

    def on_cloud(sample: zenoh.Sample) -> None:
        m = _message(sample)
        with seen.lock:
            seen.cloud_points[int(m["stamp_ns"])] = len(m["points_m"])

    try:
        supervisor.start()
        session = observer_session(layout)
        subscribers = [
            # as every subscriber of the bus: a restarted process's first messages (the report of the
            # input a killed one had in hand) may leave before the routes to a plain subscriber exist
            reliable.Subscriber(session, keys.imu(UAV), on_imu),
            reliable.Subscriber(session, keys.detections(UAV), on_detections),
            reliable.Subscriber(session, f"atr/{UAV}/*/errors", on_error),
            reliable.Subscriber(session, keys.sfm_cloud(UAV), on_cloud),
        ]
        try:
            services = [p.name for p in supervisor.specs if p.role != "hub"]
            wait_until_ready(session, UAV, services, 300, supervisor)
            source = next(p for p in layout.processes if p.role == "source")
            args = ("--scenario", "1", "--run", "3", "--frames", str(frames))
            popen = supervisor.spawn_once(replace(source, args=source.args + args))
            deadline = time.monotonic() + timeout_s
            while popen.poll() is None and time.monotonic() < deadline:
                supervisor.poll()
                kill_when(seen, supervisor)
                time.sleep(0.05)
            assert popen.poll() == 0, f"the source did not finish its flight ({popen.poll()})"
            time.sleep(0.5)  # the last answers reach the recorder
        finally:
            for subscriber in subscribers:
                subscriber.undeclare()
            session.close()
    finally:
        supervisor.stop()
        os.environ.pop("ATR_STATE_DIR", None)
    return seen, out, supervisor


def kill(supervisor: Supervisor, name: str) -> int:
    """kill -9 the running process of `name` (not its group: as a crash would); returns its pid."""
    pid = supervisor.running[name].popen.pid
    os.kill(pid, signal.SIGKILL)
    return pid


def unanswered(seen: Seen) -> list[int]:
    """frame_seqs with neither Detections nor an ErrorReport naming their stamp."""
    with seen.lock:
        return sorted(
            f for s, f in seen.frames.items() if s not in seen.detections and s not in seen.reported
        )


def problems_beyond_recorder_kills(
    out: Path, recorder_kills_ns: list[int], window_s: float = 3.0
) -> list[str]:
    """`bus.audit.audit` of the recording, less what a killed recorder loses by design.

    A recorder killed at time T leaves its segment cut (not closed) and loses what it had not yet
    written (its last second or so) and what was sent while it was down: gaps logged within
    [T - window_s, T + 3 * window_s], and frames in flight then whose answer fell into such a gap.
    Everything else the audit finds is returned.
    """
    from bus.audit import audit

    report = audit(out)
    segments = [Path(f).name for f in report.files]

    def near_a_kill(log_ns: int) -> bool:
        return any(
            t - window_s * 1e9 <= log_ns <= t + 3 * window_s * 1e9 for t in recorder_kills_ns
        )

    cut = segments[: len(recorder_kills_ns)]  # the segments whose recorder was killed
    left = []
    for problem in report.problems:
        name = problem.split(" ", 1)[0]
        if name in cut and ("cut short" in problem or "not closed cleanly" in problem):
            continue
        if " message(s) lost " in problem and near_a_kill(int(problem.rsplit(" ", 1)[-1])):
            continue
        if "got neither detections nor an error" in problem:
            continue  # checked below, frame by frame
        left.append(problem)
    lost_answers = {
        topic
        for topic, p in report.publishers.items()
        if topic.endswith(("/detections", "/errors")) and p.gaps
    }
    if report.unanswered_frames and not (recorder_kills_ns and lost_answers):
        left.append(f"frames without an answer in the recording: {report.unanswered_frames}")
    if len(report.unanswered_frames) > 2 * len(recorder_kills_ns):
        left.append(
            f"more frames without an answer than kills can explain: {report.unanswered_frames}"
        )
    return left
