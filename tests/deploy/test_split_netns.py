"""The `split` layout on two hosts of one machine: network namespaces `ground` and `air` joined by a veth pair.

The ground namespace runs `atr up split --host ground` (router, recorder, template_store, atr_matcher), the air
namespace `atr up split --host air --no-source` (air router, pose_integrator, sfm); flights are the air's
sensor_source in lock-step. Everything is the real deployment: mutual TLS, access control, the certificates of
`atr certs`. The air router reaches the ground router through the link emulator (tests/deploy/_link_emulator.py)
running in the ground namespace, so the radio link can be impaired: 50 ms each way and 1 % segment loss in the
emulator, 2 Mbit/s by htb on both ends of the veth pair (this kernel has no netem).

Needs root (namespaces); skips otherwise. Figures are printed (run with -s) and written to docs/performance/link.md
by hand.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from statistics import median
from typing import Any

import json5
import pytest
from mcap.reader import make_reader

from bus import codec, keys
from bus.certs import Deployment, make_deployment, seal_key_name
from bus.mcap_tools import recover
from bus.seal import load_public_key, verify

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))
from _netns import GROUND_IP, TwoHosts, netns_unavailable  # noqa: E402

sys.path.insert(0, str(HERE.parent))
from _small_camera import SMALL_CAMERA  # noqa: E402

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

PY = sys.executable
UAV = "uav1"
LINK_PORT = 7000  # the emulator, in the ground namespace, in front of the ground router (7447)
GROUND_SERVICES = ["recorder", "template_store", "atr_matcher"]
AIR_SERVICES = ["pose_integrator", "sfm"]
# Keys published on the ground: everything else in the ground recording crossed the radio link.
GROUND_KEYS = (
    f"atr/{UAV}/detections",
    f"atr/{UAV}/atr_matcher/",
    f"atr/{UAV}/template_store/",
    f"atr/{UAV}/recorder/",
)


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["NUMBA_CACHE_DIR"] = str(REPO / ".numba_cache")
    for name in ("ATR_ZENOH_CONFIG", "ATR_ZENOH_CONNECT", "ATR_ZENOH_LISTEN"):
        env.pop(name, None)
    return env


class Watch:
    """`_ns_helper.py watch` in the air namespace: what the air sees, with receive times."""

    def __init__(self, hosts: TwoHosts, config: Path) -> None:
        self.events: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._proc = hosts.start(
            "air",
            [PY, str(HERE / "_ns_helper.py"), "watch", "--zenoh", str(config)],
            env=_env(),
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        self._ready = threading.Event()
        threading.Thread(target=self._read, daemon=True).start()
        if not self._ready.wait(60):
            raise TimeoutError("the watcher did not start within 60 s")

    def _read(self) -> None:
        for line in self._proc.stdout:
            event = json.loads(line)
            if event.get("ready"):
                self._ready.set()
                continue
            with self._lock:
                self.events.append(event)

    def since(self, t_ns: int) -> list[dict[str, Any]]:
        with self._lock:
            return [e for e in self.events if e["t_ns"] >= t_ns]

    def wait_for(self, predicate: Any, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self._lock:
                if predicate(self.events):
                    return True
            time.sleep(0.1)
        return False


class Link:
    """The link emulator process in the ground namespace: air router -> GROUND_IP:7000 -> 127.0.0.1:7447."""

    def __init__(self, hosts: TwoHosts, folder: Path) -> None:
        self.hosts, self.folder = hosts, folder
        self.proc: subprocess.Popen[Any] | None = None
        self.stats_path = folder / "link.json"

    def start(self, delay_ms: float = 0.0, loss: float = 0.0, seed: int = 0) -> None:
        if self.proc is not None:
            self.hosts.stop(self.proc)
        self.stats_path.unlink(missing_ok=True)
        self.proc = self.hosts.start(
            "ground",
            [
                PY,
                str(HERE / "_link_emulator.py"),
                "--listen",
                f"{GROUND_IP}:{LINK_PORT}",
                "--to",
                "127.0.0.1:7447",
                "--delay-ms",
                str(delay_ms),
                "--loss",
                str(loss),
                "--seed",
                str(seed),
                "--stats",
                str(self.stats_path),
            ],
            env=_env(),
            stdout=subprocess.PIPE,
            text=True,
        )
        line = self.proc.stdout.readline()
        assert line.startswith("ready"), f"link emulator did not start: {line!r}"

    def stats(self) -> dict[str, Any]:
        time.sleep(1.2)  # the emulator writes its counters every second
        return json.loads(self.stats_path.read_text()) if self.stats_path.exists() else {}


@dataclass
class Split:
    hosts: TwoHosts
    deploy: Deployment
    link: Link
    ground: subprocess.Popen[Any]
    air: subprocess.Popen[Any]
    watch: Watch
    folder: Path
    recording: Path
    figures: dict[str, Any] = field(default_factory=dict)

    def wait_ready(self, timeout_s: float = 300.0) -> None:
        services = ",".join(GROUND_SERVICES + AIR_SERVICES)
        self.hosts.run(
            "air",
            [
                PY,
                str(HERE / "_ns_helper.py"),
                "wait-ready",
                "--zenoh",
                str(self.deploy.zenoh("split-air")),
                "--services",
                services,
                "--timeout",
                str(timeout_s),
            ],
            timeout_s=timeout_s + 30,
        )

    def fly(
        self, frames: int, answer_timeout_s: float = 60.0, seed: int = 0, during: Any = None
    ) -> tuple[int, int, int]:
        """Fly `frames` frames from the air; (start, end) wall times in ns and the source's exit code."""
        start = time.time_ns()
        env = _env() | {"ATR_ZENOH_CONFIG": str(self.deploy.zenoh("split-air"))}
        source = self.hosts.start(
            "air",
            [
                PY,
                "-m",
                "cli.main",
                "service",
                "sensor_source",
                "--frames",
                str(frames),
                "--seed",
                str(seed),
                "--pace",
                "lock-step",
                "--answer-timeout",
                str(answer_timeout_s),
                *SMALL_CAMERA,
            ],
            env=env,
            cwd=REPO,
            stdout=(self.folder / "source.log").open("ab"),
            stderr=subprocess.STDOUT,
        )
        if during is not None:
            during()
        code = source.wait(timeout=frames * (answer_timeout_s + 30))
        time.sleep(2.5)  # the last messages reach the recorder, which flushes every second
        return start, time.time_ns(), code

    def recorded(self, start_ns: int, end_ns: int) -> list[tuple[str, int, bytes]]:
        """(topic, log_time, payload) of the ground recording between two wall times."""
        snapshot = self.folder / "snapshot.mcap"
        readable = self.folder / "readable.mcap"
        shutil.copyfile(self.recording, snapshot)
        readable.unlink(missing_ok=True)  # recover never overwrites a recording
        recover(snapshot, readable)
        with readable.open("rb") as stream:
            return [
                (c.topic, m.log_time, m.data)
                for _, c, m in make_reader(stream).iter_messages(log_time_order=True)
                if start_ns <= m.log_time <= end_ns
            ]


@pytest.fixture(scope="module")
def split(tmp_path_factory: pytest.TempPathFactory) -> Split:
    reason = netns_unavailable()
    if reason:
        pytest.skip(reason)
    folder = tmp_path_factory.mktemp("split")
    deploy = make_deployment(folder / "deploy", ground=GROUND_IP)
    air_router = deploy.zenoh("split-air-router")
    config = json5.loads(air_router.read_text())
    config["connect"]["endpoints"] = [f"tls/{GROUND_IP}:{LINK_PORT}"]  # through the link emulator
    air_router.write_text(json.dumps(config, indent=2))
    recording = folder / "ground.mcap"
    with TwoHosts() as hosts:
        link = Link(hosts, folder)
        link.start()
        common = ["--var", f"deploy={deploy.root}", *SMALL_CAMERA]
        ground = hosts.start(
            "ground",
            [
                PY,
                "-m",
                "cli.main",
                "up",
                "split",
                "--host",
                "ground",
                "--var",
                f"out={recording}",
                *common,
            ],
            env=_env(),
            cwd=REPO,
            stdout=(folder / "ground.log").open("wb"),
            stderr=subprocess.STDOUT,
        )
        air = hosts.start(
            "air",
            [
                PY,
                "-m",
                "cli.main",
                "up",
                "split",
                "--host",
                "air",
                "--no-source",
                "--var",
                f"air_out={folder / 'air.mcap'}",
                *common,
            ],
            env=_env(),
            cwd=REPO,
            stdout=(folder / "air.log").open("wb"),
            stderr=subprocess.STDOUT,
        )
        watch = Watch(hosts, deploy.zenoh("split-air"))
        result = Split(hosts, deploy, link, ground, air, watch, folder, recording)
        result.wait_ready()
        yield result
        for proc in (
            air,
            ground,
        ):  # SIGTERM: the launcher stops its services, the recorder closes its file
            hosts.stop(proc, timeout_s=30)
        print("\nsplit figures:", json.dumps(result.figures, indent=1))
    # the chain of custody: the air recorder sealed its file as it closed, and the ground's pinned
    # key (made by `atr certs`) verifies it intact
    public = load_public_key(deploy.root / f"{seal_key_name(UAV)}.pub")
    verdict = verify(folder / "air.mcap", public)
    assert verdict.intact and verdict.sealed_messages > 0, verdict.lines()


def _best_effort_gap(event: dict[str, Any]) -> bool:
    """A recorder's report of a sequence gap on a Status or Timing key (published with DROP)."""
    reason = str(event.get("reason", ""))
    return event["key"].endswith("/recorder/errors") and any(
        f"/{kind} from " in reason for kind in ("status", "timing")
    )


def _frames(records: list[tuple[str, int, bytes]]) -> dict[int, dict[str, Any]]:
    """Per frame stamp: its truth and detections as recorded on the ground."""
    frames: dict[int, dict[str, Any]] = {}
    for topic, log_time, data in records:
        if topic in (keys.truth(UAV), keys.detections(UAV)):
            message = codec.unpack(data)
            frames.setdefault(message["stamp_ns"], {})[topic] = (log_time, message)
    return frames


def _crossing_bytes(records: list[tuple[str, int, bytes]]) -> dict[str, int]:
    out: dict[str, int] = {}
    for topic, _, data in records:
        if not topic.startswith(GROUND_KEYS):
            out[topic] = out.get(topic, 0) + len(data)
    return out


def _latencies_ms(events: list[dict[str, Any]]) -> list[float]:
    """Image published on the air -> its Detections back on the air (lock-step answer), ms."""
    images = {e["stamp_ns"]: e["t_ns"] for e in events if e["key"] == keys.image(UAV)}
    answers = {e["stamp_ns"]: e["t_ns"] for e in events if e["key"] == keys.detections(UAV)}
    return [(answers[s] - images[s]) / 1e6 for s in images if s in answers]


def _flight_figures(
    split: Split,
    start: int,
    end: int,
    frames: int,
    link_before: dict[str, Any],
    veth_before: dict[str, int],
) -> dict[str, Any]:
    records = split.recorded(start, end)
    link_after, veth_after = split.link.stats(), split.hosts.link_bytes()
    events = split.watch.since(start)
    seconds = (end - start) / 1e9
    up = link_after.get("bytes_up", 0) - link_before.get("bytes_up", 0)
    down = link_after.get("bytes_down", 0) - link_before.get("bytes_down", 0)
    crossing = _crossing_bytes(records)
    images = [e["bytes"] for e in events if e["key"] == keys.image(UAV)]
    latencies = _latencies_ms(events)
    return {
        "frames": frames,
        "seconds": round(seconds, 1),
        "link_up_bytes": up,
        "link_down_bytes": down,
        "link_up_Bps": round(up / seconds),
        "link_down_Bps": round(down / seconds),
        "link_up_bytes_per_frame": round(up / frames),
        "veth_air_tx_bytes": veth_after["air"] - veth_before["air"],
        "veth_ground_tx_bytes": veth_after["ground"] - veth_before["ground"],
        "lost_segments_up": link_after.get("lost_up", 0) - link_before.get("lost_up", 0),
        "payload_bytes_per_frame_by_key": {
            k: round(v / frames) for k, v in sorted(crossing.items())
        },
        "image_bytes_per_frame_kept_on_air": round(sum(images) / max(1, len(images))),
        "latency_ms_median": round(median(latencies), 1) if latencies else None,
        "latency_ms_max": round(max(latencies), 1) if latencies else None,
        "records": records,
    }


def _check_complete(figures: dict[str, Any], frames: int) -> None:
    recorded = _frames(figures["records"])
    assert len(recorded) == frames, f"{len(recorded)} frames recorded on the ground, {frames} flown"
    for stamp, per_key in recorded.items():
        assert keys.truth(UAV) in per_key, f"frame {stamp}: no truth reached the ground"
        assert keys.detections(UAV) in per_key, (
            f"frame {stamp}: no Detections in the ground recording"
        )
    topics = {t for t, _, _ in figures["records"]}
    assert keys.image(UAV) not in topics, "camera images crossed the radio link"
    for key in (keys.imu(UAV), keys.relative_pose(UAV), keys.sfm_cloud(UAV)):
        assert key in topics, f"{key} did not reach the ground recording"


def test_flight_over_two_hosts(split: Split) -> None:
    frames = 4
    link_before, veth_before = split.link.stats(), split.hosts.link_bytes()
    start, end, code = split.fly(frames)
    assert code == 0, (split.folder / "source.log").read_text()[-3000:]
    figures = _flight_figures(split, start, end, frames, link_before, veth_before)
    _check_complete(figures, frames)
    assert figures["image_bytes_per_frame_kept_on_air"] > 640 * 480 * 3
    assert figures["link_up_bytes_per_frame"] < figures["image_bytes_per_frame_kept_on_air"] / 4
    split.figures["clean"] = {k: v for k, v in figures.items() if k != "records"}


def test_flight_over_impaired_link(split: Split) -> None:
    """50 ms each way, 1 % segment loss (retransmitted: TCP), 2 Mbit/s: every detection still arrives."""
    split.hosts.rate_limit(2_000_000)
    try:
        split.link.start(delay_ms=50, loss=0.01, seed=1)  # the air router redials the new emulator
        split.wait_ready(120)
        frames = 3
        link_before, veth_before = split.link.stats(), split.hosts.link_bytes()
        start, end, code = split.fly(frames, seed=0)
        assert code == 0, (split.folder / "source.log").read_text()[-3000:]
        figures = _flight_figures(split, start, end, frames, link_before, veth_before)
        _check_complete(figures, frames)
        # Status and Timing are published best-effort (DROP: a heartbeat never holds a service up),
        # so on a throttled link the recorder may rightly report gaps in them; nothing else may fail
        errors = [
            e
            for e in split.watch.since(start)
            if e["key"].endswith("/errors") and not _best_effort_gap(e)
        ]
        assert not errors, errors
        split.figures["impaired"] = {k: v for k, v in figures.items() if k != "records"}
    finally:
        split.hosts.rate_limit(None)
        split.link.start()
        split.wait_ready(120)


def _child_pid(parent: int, service: str) -> int:
    """The pid of the `atr service SERVICE` process a launcher started."""
    for task in Path(f"/proc/{parent}/task").iterdir():
        for pid in (task / "children").read_text().split():
            command = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            if b"service" in command and command[command.index(b"service") + 1] == service.encode():
                return int(pid)
    raise LookupError(f"no {service} process under {parent}")


def test_ground_router_restart_mid_flight(split: Split) -> None:
    """SIGKILL the ground router after two answered frames; the launcher restarts it, every client redials.

    Zenoh keeps no data for a route that is down: what the air publishes during the outage is lost. The
    pipeline says so: the sensor source reports each unanswered frame on its errors key (and counts it in its
    Status), the recorder reports the sequence gaps it saw; the flight goes on and its last frames are answered.
    """
    frames, start = 6, time.time_ns()
    outage: dict[str, int] = {}

    def restart_router() -> None:
        answered = split.watch.wait_for(
            lambda events: (
                sum(1 for e in events if e["key"] == keys.detections(UAV) and e["t_ns"] >= start)
                >= 2
            ),
            300,
        )
        assert answered, "no two frames answered before the restart"
        router = _child_pid(split.ground.pid, "router")
        outage["killed_ns"] = time.time_ns()
        os.kill(router, 9)

    first, end, code = split.fly(frames, answer_timeout_s=15, during=restart_router)
    assert code == 0, (split.folder / "source.log").read_text()[-3000:]
    events = split.watch.since(first)
    images = sorted({e["stamp_ns"] for e in events if e["key"] == keys.image(UAV)})
    assert len(images) == frames
    records = split.recorded(first, end)
    answered = {s for s, per_key in _frames(records).items() if keys.detections(UAV) in per_key}
    lost = {
        e.get("input_stamp_ns") for e in events if e["key"] == f"atr/{UAV}/sensor_source/errors"
    }
    assert set(images) <= answered | lost, (
        f"frames neither answered nor reported lost: {set(images) - answered - lost}"
    )
    assert images[-1] in answered, "the pipeline did not resume after the router restart"
    statuses = [
        e for e in events if e["key"] == f"atr/{UAV}/sensor_source/status" and e.get("counters")
    ]
    assert statuses and statuses[-1]["counters"]["errors"] >= len(lost & set(images))
    recorder_errors = [codec.unpack(d) for t, _, d in records if t == f"atr/{UAV}/recorder/errors"]
    resumed = min(
        (
            e["t_ns"]
            for e in events
            if e["key"] == keys.detections(UAV) and e["t_ns"] > outage["killed_ns"]
        ),
        default=None,
    )
    split.figures["restart"] = {
        "frames": frames,
        "answered": len(answered & set(images)),
        "reported_lost": len(lost & set(images)),
        "sensor_source_error_count": statuses[-1]["counters"]["errors"],
        "recorder_gap_reports": [e["reason"] for e in recorder_errors][:10],
        "first_answer_after_kill_s": round((resumed - outage["killed_ns"]) / 1e9, 1)
        if resumed
        else None,
    }
