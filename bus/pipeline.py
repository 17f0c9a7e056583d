"""Run a layout around a flight: replay a recording through it (`atr run`), or let its source fly (`atr demo`)."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import zenoh

from bus.launcher import Supervisor, load_layout, observer_session, wait_until_ready
from bus.replayer import Replayer


@dataclass
class RunResult:
    """What a run did."""

    frames: int = 0
    timeouts: int = 0
    failures: dict[str, list[int]] = field(default_factory=dict)
    log_dir: Path = Path()


def free_hub_endpoint() -> str:
    """A loopback endpoint on a free port, so runs never collide with each other or a live layout."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


@contextmanager
def _running(
    layout_name: str, out: Path, overrides: list[str], ready_timeout_s: float, result: RunResult
) -> Iterator[tuple[Supervisor, zenoh.Session, str]]:
    """The layout (without its source) up and ready, an observer session on its bus, and the vehicle id.

    Stops everything on exit and records which processes failed in `result`.
    """
    layout = load_layout(layout_name, {"out": str(out), "hub": free_hub_endpoint()})
    supervisor = Supervisor(
        layout, overrides=overrides, skip_roles=("source",), log_dir=result.log_dir
    )
    supervisor.start()
    try:
        session = observer_session(layout)
        try:
            uav = layout.variables.get("uav", "uav1")
            services = [p.name for p in supervisor.specs if p.role != "hub"]
            wait_until_ready(session, uav, services, ready_timeout_s, supervisor)
            yield supervisor, session, uav
            time.sleep(0.5)  # the last answers reach the recorder
        finally:
            session.close()
    finally:
        supervisor.stop()
        result.failures |= supervisor.failures()


def run_recording(
    input_path: Path,
    out: Path,
    *,
    layout: str = "local",
    overrides: list[str] = (),
    answer_timeout_s: float = 600.0,
    ready_timeout_s: float = 900.0,
) -> RunResult:
    """Replay `input_path` through `layout` in lock-step, recording everything into `out`."""
    result = RunResult(log_dir=out.with_suffix(".logs"))
    with _running(layout, out, list(overrides), ready_timeout_s, result) as (_, session, uav):
        with Replayer(input_path, session, uav=uav) as replayer:
            stats = replayer.lock_step(answer_timeout_s=answer_timeout_s)
        result.frames, result.timeouts = stats.frames, stats.timeouts
    return result


def fly_layout(
    out: Path,
    *,
    layout: str = "local",
    overrides: list[str] = (),
    source_args: list[str] = (),
    ready_timeout_s: float = 900.0,
    on_session: Callable[[zenoh.Session], None] | None = None,
    flight_timeout_s: float = 3600.0,
) -> RunResult:
    """Start the whole layout, its sensor source flying with `source_args`, until the source is done.

    `on_session(session)` is called with an observer session before the flight starts (progress display).
    """
    result = RunResult(log_dir=out.with_suffix(".logs"))
    with _running(layout, out, list(overrides), ready_timeout_s, result) as (
        supervisor,
        session,
        _,
    ):
        if on_session is not None:
            on_session(session)
        source = next(p for p in supervisor.layout.processes if p.role == "source")
        popen = supervisor.spawn_once(replace(source, args=source.args + tuple(source_args)))
        deadline = time.monotonic() + flight_timeout_s
        while popen.poll() is None and time.monotonic() < deadline:
            supervisor.poll()
            time.sleep(0.2)
        if popen.poll() is None:
            popen.terminate()
        if popen.wait() != 0:
            result.failures[source.name] = [popen.returncode]
    return result


class FlightWatch:
    """Pairs each Detections message with its frame's truth and estimated camera pose (simulated flights).

    The callback gets (Truth, Detections, CameraPose or None) as the Detections message crosses the bus.
    """

    def __init__(
        self,
        session: object,
        uav: str,
        on_scene: Callable[[dict | None, dict, dict | None], None],
    ) -> None:
        from bus import codec, keys  # noqa: PLC0415

        self._truth: dict[int, dict] = {}
        self._camera_pose: dict[int, dict] = {}
        self._on_scene = on_scene

        def on_truth(sample: object) -> None:
            message = codec.unpack(sample.payload.to_bytes())
            self._truth[message["stamp_ns"]] = message

        def on_camera_pose(sample: object) -> None:
            message = codec.unpack(sample.payload.to_bytes())
            self._camera_pose.setdefault(message["stamp_ns"], message)

        def on_detections(sample: object) -> None:
            message = codec.unpack(sample.payload.to_bytes())
            stamp = message["stamp_ns"]
            self._on_scene(self._truth.get(stamp), message, self._camera_pose.get(stamp))

        self._subs = [
            session.declare_subscriber(keys.truth(uav), on_truth),
            session.declare_subscriber(keys.camera_pose(uav), on_camera_pose),
            session.declare_subscriber(keys.detections(uav), on_detections),
        ]

    def close(self) -> None:
        """Stop watching."""
        for sub in self._subs:
            sub.undeclare()
        self._subs = []


def flight_scenes(path: Path, uav: str = "uav1") -> list[tuple[dict | None, dict, dict | None]]:
    """(truth, detections, camera pose) per Detections message of a recording, in order.

    The camera pose is the frame's first CameraPose message (None when the recording has none).
    """
    from mcap.reader import make_reader  # noqa: PLC0415

    from bus import codec, keys  # noqa: PLC0415

    truth: dict[int, dict] = {}
    camera_pose: dict[int, dict] = {}
    detections = []
    with open(path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(
            topics=[keys.truth(uav), keys.camera_pose(uav), keys.detections(uav)],
            log_time_order=False,
        ):
            data = codec.unpack(message.data)
            if channel.topic == keys.truth(uav):
                truth[data["stamp_ns"]] = data
            elif channel.topic == keys.camera_pose(uav):
                camera_pose.setdefault(data["stamp_ns"], data)
            else:
                detections.append(data)
    return [(truth.get(d["stamp_ns"]), d, camera_pose.get(d["stamp_ns"])) for d in detections]


def flight_clouds(path: Path, uav: str = "uav1") -> dict[int, np.ndarray]:
    """The SfM cloud of each frame of a recording, keyed by its stamp_ns: (N, 3) float32 world positions."""
    from mcap.reader import make_reader  # noqa: PLC0415

    from bus import codec, keys  # noqa: PLC0415
    from bus.clouds import cloud_points  # noqa: PLC0415

    clouds: dict[int, np.ndarray] = {}
    with open(path, "rb") as stream:
        for _, _, message in make_reader(stream).iter_messages(
            topics=[keys.sfm_cloud(uav)], log_time_order=False
        ):
            data = codec.unpack(message.data)
            clouds[data["stamp_ns"]] = cloud_points(data)
    return clouds
