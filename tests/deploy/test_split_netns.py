"""The `split` layout on two hosts of one machine: network namespaces `ground` and `air` joined by a veth pair.

The ground namespace runs `atr up split --host ground` (router, recorder, template_store, atr_matcher), the air
namespace `atr up split --host air --no-source` (air router, pose_integrator, sfm); flights are the air's
sensor_source in lock-step. Everything is the real deployment: mutual TLS, access control, the certificates of
`atr certs`. The air router reaches the ground router through the link emulator (tests/deploy/_link_emulator.py)
running in the ground namespace, so the radio link can be impaired: 50 ms each way and 1 % segment loss in the
emulator, 2 Mbit/s by htb on both ends of the veth pair (this kernel has no netem), and cut: a 10 s outage and a
ground router restart lose nothing (zenoh-ext's recovery, bus/reliable.py), a 60 s outage loses what no longer
fits the publishers' caches and the ground recording says exactly how much.

Needs root (namespaces); skips otherwise. Figures are printed (run with -s) and written to docs/performance/link.md
by hand.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
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
from bus.reliable import LinkBudget, loss_count
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
IDLE_S = 8.0  # how long the idle link is measured, s
GROUND_SERVICES = ["recorder", "template_store", "atr_matcher"]
AIR_SERVICES = ["pose_integrator", "sfm"]
# Keys published on the ground: everything else in the ground recording crossed the radio link.
GROUND_KEYS = (
    f"atr/{UAV}/detections",
    f"atr/{UAV}/tracks",
    f"atr/{UAV}/atr_matcher/",
    f"atr/{UAV}/template_store/",
    f"atr/{UAV}/tracker/",
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

    def start(
        self, delay_ms: float = 0.0, loss: float = 0.0, seed: int = 0, rate_kbps: float = 0.0
    ) -> None:
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
                *(["--rate-kbps", str(rate_kbps)] if rate_kbps else []),
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

    def down(self) -> None:
        """Cut the link: open connections close, new ones are refused (the emulator's `drop` outage)."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGUSR1)

    def up(self) -> None:
        """End the outage; the air router's next redial gets through."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGUSR2)


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

        def up(host: str, *args: str) -> subprocess.Popen:
            """`atr up split` for one host in its namespace, its output in <host>.log."""
            command = [PY, "-m", "cli.main", "up", "split", "--host", host, *args, *common]
            log = (folder / f"{host}.log").open("wb")
            return hosts.start(
                host, command, env=_env(), cwd=REPO, stdout=log, stderr=subprocess.STDOUT
            )

        ground = up("ground", "--var", f"out={recording}")
        air = up("air", "--no-source", "--var", f"air_out={folder / 'air.mcap'}")
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


def _first_seen(events: list[dict[str, Any]], key: str) -> dict[int, int]:
    """stamp_ns -> the first wall time the air's watch saw a message of that stamp on `key`."""
    out: dict[int, int] = {}
    for e in events:
        if e["key"] == key and "stamp_ns" in e:
            out.setdefault(e["stamp_ns"], e["t_ns"])
    return out


def _first_recorded(records: list[tuple[str, int, bytes]], key: str) -> dict[int, int]:
    """stamp_ns -> the first log time (receive wall time) of a message of that stamp on `key`."""
    out: dict[int, int] = {}
    for topic, log_time, data in records:
        if topic == key:
            out.setdefault(int(codec.unpack(data)["stamp_ns"]), log_time)
    return out


def _percentile(values: list[float], q: float) -> float:
    """Nearest-rank percentile (q in 0..100) of a non-empty list."""
    ordered = sorted(values)
    return ordered[max(0, min(len(ordered) - 1, round(q / 100 * len(ordered) + 0.5) - 1))]


def _hops(events: list[dict[str, Any]], records: list[tuple[str, int, bytes]]) -> dict[str, Any]:
    """Where a frame's time goes, per hop (ms, median and p99 over the frames that have every hop).

    image published on the air -> sfm's cloud on the air (SfM: waiting for the pose, computing) -> the
    cloud in the ground recording (the radio link up) -> Detections in the ground recording (the
    matcher) -> Detections on the air (the link down: lock-step's answer). `air_to_ground` is image ->
    Detections on the ground; `round_trip` image -> Detections back on the air; `pace` the answer ->
    the next frame's image (lock-step: the source renders the next frame only then).
    """
    image = _first_seen(events, keys.image(UAV))
    cloud_air = _first_seen(events, keys.sfm_cloud(UAV))
    cloud_ground = _first_recorded(records, keys.sfm_cloud(UAV))
    detections_ground = _first_recorded(records, keys.detections(UAV))
    detections_air = _first_seen(events, keys.detections(UAV))
    stamps = [
        s
        for s in image
        if s in cloud_air and s in cloud_ground and s in detections_ground and s in detections_air
    ]
    spans = {
        "sfm": (image, cloud_air),
        "link_up": (cloud_air, cloud_ground),
        "matcher": (cloud_ground, detections_ground),
        "link_down": (detections_ground, detections_air),
        "air_to_ground": (image, detections_ground),
        "round_trip": (image, detections_air),
    }
    out: dict[str, Any] = {"frames_timed": len(stamps)}
    values_by_span = {
        name: [(finish[s] - begin[s]) / 1e6 for s in stamps]
        for name, (begin, finish) in spans.items()
    }
    ordered = sorted(image)
    values_by_span["pace"] = [
        (image[later] - detections_air[earlier]) / 1e6
        for earlier, later in zip(ordered, ordered[1:], strict=False)
        if earlier in detections_air
    ]
    for name, values in values_by_span.items():
        if values:
            out[f"{name}_ms_median"] = round(median(values), 1)
            out[f"{name}_ms_p99"] = round(_percentile(values, 99), 1)
    return out


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
        "latency": _hops(events, records),
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
    # what the link carries with no flight: Status heartbeats and the publishers' heartbeats
    idle_before = split.link.stats()
    time.sleep(IDLE_S)
    idle_after = split.link.stats()
    idle_s = IDLE_S + 1.2  # stats() waits for the emulator's next write
    frames = 4
    link_before, veth_before = split.link.stats(), split.hosts.link_bytes()
    start, end, code = split.fly(frames)
    assert code == 0, (split.folder / "source.log").read_text()[-3000:]
    figures = _flight_figures(split, start, end, frames, link_before, veth_before)
    for direction in ("up", "down"):
        moved = idle_after[f"bytes_{direction}"] - idle_before[f"bytes_{direction}"]
        figures[f"idle_{direction}_Bps"] = round(moved / idle_s)
    split.figures["clean"] = {k: v for k, v in figures.items() if k != "records"}
    _check_complete(figures, frames)
    assert figures["image_bytes_per_frame_kept_on_air"] > 640 * 480 * 3
    assert figures["link_up_bytes_per_frame"] < figures["image_bytes_per_frame_kept_on_air"] / 4


def test_flight_over_impaired_link(split: Split) -> None:
    """50 ms each way, 1 % segment loss (retransmitted: TCP), 2 Mbit/s: every detection still arrives."""
    split.hosts.rate_limit(2_000_000)
    try:
        # the rate twice: htb lets a GSO burst of up to 64 KB through at once and makes the traffic
        # after it wait, the emulator charges each 1448-byte segment its airtime: a cloud's latency
        split.link.start(delay_ms=50, loss=0.01, seed=1, rate_kbps=2000)
        split.wait_ready(120)
        frames = 10  # enough for a median and a tail of the latency
        link_before, veth_before = split.link.stats(), split.hosts.link_bytes()
        start, end, code = split.fly(frames, seed=0)
        assert code == 0, (split.folder / "source.log").read_text()[-3000:]
        figures = _flight_figures(split, start, end, frames, link_before, veth_before)
        split.figures["impaired"] = {k: v for k, v in figures.items() if k != "records"}
        _check_complete(figures, frames)
        # Status and Timing are published best-effort (DROP: a heartbeat never holds a service up),
        # but a dropped one is fetched again from its publisher's cache: nothing may be missing
        errors = [e for e in split.watch.since(start) if e["key"].endswith("/errors")]
        assert not errors, errors
        assert not _holes_by_key(figures["records"])
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


def _holes_by_key(records: list[tuple[str, int, bytes]]) -> dict[str, int]:
    """Per key that crossed the radio link: how many seqs between its first and last recorded are
    missing from the ground recording (a seq sent again counts once). One publisher per key here.
    """
    seqs: dict[str, set[int]] = {}
    for topic, _, data in records:
        if not topic.startswith(GROUND_KEYS):
            seqs.setdefault(topic, set()).add(int(codec.unpack(data)["seq"]))
    holes = {key: max(s) - min(s) + 1 - len(s) for key, s in seqs.items()}
    return {key: n for key, n in holes.items() if n}


def _reported_losses(records: list[tuple[str, int, bytes]]) -> dict[str, int]:
    """Per key: messages the ground recorder reported lost (gone from their publisher's cache)."""
    out: dict[str, int] = {}
    for topic, _, data in records:
        if topic == keys.service_key(UAV, "recorder", "errors"):
            report = codec.unpack(data)
            count = loss_count(report["reason"])
            if count is not None:
                out[report["key"]] = out.get(report["key"], 0) + count
    return out


def _after_answers(split: Split, start_ns: int, answered: int, fault: Any) -> Any:
    """A `fly(during=...)`: once `answered` frames of this flight are answered, run `fault()`."""

    def during() -> None:
        ok = split.watch.wait_for(
            lambda events: (
                sum(1 for e in events if e["key"] == keys.detections(UAV) and e["t_ns"] >= start_ns)
                >= answered
            ),
            300,
        )
        assert ok, f"no {answered} frames answered before the fault"
        fault()

    return during


def _check_nothing_lost(split: Split, first: int, end: int, frames: int) -> dict[str, Any]:
    """Every frame flown has its Detections in the ground recording, no frame went unanswered,
    nothing that crosses the link is missing from the ground recording or reported lost.
    """
    events = split.watch.since(first)
    images = sorted({e["stamp_ns"] for e in events if e["key"] == keys.image(UAV)})
    assert len(images) == frames
    records = split.recorded(first, end)
    recorded = _frames(records)
    unanswered = [s for s in images if keys.detections(UAV) not in recorded.get(s, {})]
    assert not unanswered, f"frames without Detections in the ground recording: {unanswered}"
    timeouts = [e for e in events if e["key"] == keys.service_key(UAV, "sensor_source", "errors")]
    assert not timeouts, timeouts
    assert not _holes_by_key(records), "messages missing from the ground recording"
    assert not _reported_losses(records)
    return {
        "frames": frames,
        "answered": len(images) - len(unanswered),
        "seconds": round((end - first) / 1e9, 1),
    }


def _first_answer_after(split: Split, since_ns: int) -> float | None:
    times = [
        e["t_ns"]
        for e in split.watch.since(since_ns)
        if e["key"] == keys.detections(UAV) and e["t_ns"] > since_ns
    ]
    return round((min(times) - since_ns) / 1e9, 1) if times else None


def _fly_through(split: Split, fault: Any, recovered_figure: str) -> dict[str, Any]:
    """Fly five frames with `fault()` striking after two are answered, and check that nothing was lost.
    The figures add, as `recovered_figure`, the seconds from the time `fault()` returns (ns) to the
    first answer after it."""
    frames, start, fault_ns = 5, time.time_ns(), []
    during = _after_answers(split, start, 2, lambda: fault_ns.append(fault()))
    first, end, code = split.fly(frames, during=during)
    assert code == 0, (split.folder / "source.log").read_text()[-3000:]
    figures = _check_nothing_lost(split, first, end, frames)
    figures[recovered_figure] = _first_answer_after(split, fault_ns[0])
    return figures


def test_link_outage_of_10_s_mid_flight_loses_nothing(split: Split) -> None:
    """The link drops for 10 s (connections cut, redials refused) after two answered frames: what was
    published meanwhile, on either side, arrives afterwards from the publishers' caches."""

    def cut() -> int:
        split.link.down()
        time.sleep(10)
        split.link.up()
        return time.time_ns()  # the link is back

    split.figures["outage_10s"] = _fly_through(split, cut, "first_answer_after_link_back_s")


def test_ground_router_restart_mid_flight_loses_nothing(split: Split) -> None:
    """SIGKILL the ground router after two answered frames; the launcher restarts it, every client
    redials, and what was published meanwhile arrives from the publishers' caches: no frame lost."""

    def kill_router() -> int:
        router = _child_pid(split.ground.pid, "router")
        killed_ns = time.time_ns()
        os.kill(router, signal.SIGKILL)
        return killed_ns

    split.figures["router_restart"] = _fly_through(split, kill_router, "first_answer_after_kill_s")


def test_link_outage_beyond_the_cache_is_reported_exactly(split: Split) -> None:
    """A 60 s outage, twice what the caches cover (LinkBudget.outage_s = 30 s): the Status heartbeats
    of that time no longer fit their publishers' caches. For every key that crossed the link, the
    ground recorder reports exactly the messages missing from its recording; the frame in flight
    fitted in the caches and is answered."""
    budget = LinkBudget.from_env()  # what the services run with
    seconds = 2 * budget.outage_s
    frames, first = 4, time.time_ns()

    def cut() -> None:
        split.link.down()
        time.sleep(seconds)
        split.link.up()

    first, end, code = split.fly(
        frames, answer_timeout_s=seconds + 60, during=_after_answers(split, first, 1, cut)
    )
    assert code == 0, (split.folder / "source.log").read_text()[-3000:]
    records = split.recorded(first, end)
    missing, reported = _holes_by_key(records), _reported_losses(records)
    split.figures["outage_60s"] = {"missing": missing, "reported": reported}
    assert missing, "nothing lost in an outage twice the caches' budget: the caches are too big"
    assert reported == missing
    recorded = _frames(records)
    images = {e["stamp_ns"] for e in split.watch.since(first) if e["key"] == keys.image(UAV)}
    assert all(keys.detections(UAV) in recorded.get(s, {}) for s in images)
