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

from atr.errors import InputError
from bus.launcher import Supervisor, load_layout, observer_session, wait_until_ready
from bus.replayer import Replayer


@dataclass
class RunResult:
    """What a run did."""

    frames: int = 0
    timeouts: int = 0
    failures: dict[str, list[int]] = field(default_factory=dict)
    log_dir: Path = Path()


MCAP_MAGIC = b"\x89MCAP0\r\n"


def free_hub_endpoint() -> str:
    """A loopback endpoint on a free port, so runs never collide with each other or a live layout."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def check_input(path: Path) -> Path:
    """The absolute path of an existing, readable MCAP recording.

    Raises:
        InputError: it does not exist, is a directory, cannot be read, or is not an MCAP file.

    """
    path = Path(path).absolute()
    if path.is_dir():
        raise InputError(f"input {path} is a directory; expected an MCAP recording file")
    if not path.is_file():
        raise InputError(f"input {path}: no such file")
    try:
        with path.open("rb") as stream:
            magic = stream.read(len(MCAP_MAGIC))
    except OSError as exc:
        raise InputError(f"input {path} cannot be read: {exc.strerror}") from exc
    if magic != MCAP_MAGIC:
        raise InputError(
            f"input {path} is not an MCAP recording (it does not start with MCAP's magic)"
        )
    return path


def check_output(path: Path) -> Path:
    """The absolute path of an output file, resolved against the caller's working directory.

    The services run from the repository, so a relative path handed to them would land there.

    Raises:
        InputError: it is a directory, its folder is a file, or it exists (a recording is never
            overwritten, and a recorder that finds its file continues it in a new segment).

    """
    path = Path(path).absolute()
    if path.is_file():
        raise InputError(
            f"output {path} exists; a recording is never overwritten: choose another path"
        )
    if path.is_dir():
        raise InputError(
            f"output {path} is a directory; expected a file path such as {path}/flight.mcap"
        )
    blocking = next((p for p in path.parents if p.exists()), None)
    if blocking is not None and not blocking.is_dir():
        raise InputError(f"output {path}: {blocking} is a file, not a folder")
    return path


def check_run(layout: str, overrides: list[str]) -> None:
    """Check a run's layout and configuration overrides before any process starts.

    A bad `--set` would otherwise crash-loop every service until the ready timeout.

    Raises:
        ConfigError: the layout cannot be loaded, or an override names an unknown field or a bad value.

    """
    from atr.config import load_config

    load_layout(layout)
    load_config(None, list(overrides))


@contextmanager
def _running(
    layout_name: str,
    out: Path,
    overrides: list[str],
    ready_timeout_s: float,
    result: RunResult,
    input_recording: Path | None = None,
) -> Iterator[tuple[Supervisor, zenoh.Session, str]]:
    """The layout (without its source) up and ready, an observer session on its bus, and the vehicle id.

    Stops everything on exit and records which processes failed in `result`.
    """
    layout = load_layout(layout_name, {"out": str(out), "hub": free_hub_endpoint()})
    supervisor = Supervisor(
        layout,
        overrides=overrides,
        skip_roles=("source",),
        log_dir=result.log_dir,
        input_recording=input_recording,
    )
    try:
        supervisor.start()
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
    rate: float | None = None,
) -> RunResult:
    """Replay `input_path` through `layout` in lock-step, recording everything into `out`.

    With `rate`, the frames go out at the recording's pace times `rate` instead, whether or not the
    pipeline has answered (`Replayer.paced`): the service graph's throughput and latency, as in flight.

    Everything is checked before anything starts (`check_run`); relative paths are the caller's, not the
    services' (they run from the repository).

    Raises:
        ConfigError: a bad override or layout; InputError: a bad input or output path.

    """
    input_path = check_input(input_path)
    out = check_output(out)
    check_run(layout, overrides)
    result = RunResult(log_dir=out.with_suffix(".logs"))
    running = _running(layout, out, list(overrides), ready_timeout_s, result, input_path)
    with running as (sup, session, uav):
        # with a tracker the last answer to a frame is its Tracks: wait for it, or the run could end
        # before the last scene's Tracks is recorded
        tracked = any(p.service == "tracker" for p in sup.layout.processes)
        answer_key = "atr/{uav}/tracks" if tracked else "atr/{uav}/detections"
        with Replayer(input_path, session, uav=uav) as replayer:
            if rate is None:
                stats = replayer.lock_step(answer_key, answer_timeout_s=answer_timeout_s)
            else:
                stats = replayer.paced(rate, answer_key, answer_timeout_s=answer_timeout_s)
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

    Raises:
        ConfigError: a bad override or layout; InputError: a bad output path (checked before anything starts).

    """
    out = check_output(out)
    check_run(layout, overrides)
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
        from bus import codec, keys

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
    from bus import codec, keys
    from bus.mcap_tools import iter_messages

    truth: dict[int, dict] = {}
    camera_pose: dict[int, dict] = {}
    detections = []
    wanted = [keys.truth(uav), keys.camera_pose(uav), keys.detections(uav)]
    for topic, message in iter_messages(path, topics=wanted):  # every segment of the recording
        data = codec.unpack(message.data)
        if topic == keys.truth(uav):
            truth[data["stamp_ns"]] = data
        elif topic == keys.camera_pose(uav):
            camera_pose.setdefault(data["stamp_ns"], data)
        else:
            detections.append(data)
    return [(truth.get(d["stamp_ns"]), d, camera_pose.get(d["stamp_ns"])) for d in detections]


def flight_tracks(path: Path, uav: str = "uav1") -> dict[int, dict]:
    """The Tracks message of each scene of a recording (services/tracker), keyed by its stamp_ns."""
    from bus import codec, keys
    from bus.mcap_tools import iter_messages

    return {
        (data := codec.unpack(message.data))["stamp_ns"]: data
        for _, message in iter_messages(path, topics=[keys.tracks(uav)])
    }


def flight_clouds(path: Path, uav: str = "uav1") -> dict[int, np.ndarray]:
    """The SfM cloud of each frame of a recording, keyed by its stamp_ns: (N, 3) float32 world positions."""
    from bus import codec, keys
    from bus.clouds import cloud_points
    from bus.mcap_tools import iter_messages

    clouds: dict[int, np.ndarray] = {}
    for _, message in iter_messages(path, topics=[keys.sfm_cloud(uav)]):
        data = codec.unpack(message.data)
        clouds[data["stamp_ns"]] = cloud_points(data)
    return clouds
