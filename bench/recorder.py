"""Recorder throughput with zero loss, as deployed: `atr record` in its own process, a load
generator in another.

Reference load ("1x"): a 30 Hz 1280x960 RGB camera (3.7 MB frames), a 200 Hz IMU (one ImuBatch per
sample) and one 20k-point float32 cloud per frame: about 118 MB/s and 260 messages/s. The goal is to
record 2x that.
Runs:
  - paced at 1x and 2x for DURATION seconds;
  - "max": frames back to back (publishers block rather than drop) for DURATION seconds.
The generator uses pre-encoded payloads (codec cost is bench/codec.py's business) with a fresh
attachment per message, so the recorder sees real seq numbers and would report a gap. Images have
smooth texture plus sensor noise (they compress like camera frames, not like random bytes).
Figures per run: offered load (what the generator managed to send), recorded MB/s and messages/s
over first send -> file closed (includes draining the queue), the drain time after the last send, the
recorder's largest queue, and loss (messages sent minus messages in the file; must be 0). Median of
REPEATS runs.

Run: ./dev bench recorder [--duration 8] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bus_latency import REPO, bus_env, start_hub  # noqa: E402

CAMERA_HZ, IMU_HZ = 30, 200


def generator(factor: float, duration_s: float) -> int:
    """Publish the load (factor x reference; 0 = frames back to back) and print what was sent as
    JSON."""
    import zenoh
    from codec import messages

    from bus import codec, keys
    from bus.session import open_session

    # bench/codec.py's image and cloud; one IMU sample per message
    typical = dict(messages(np.random.default_rng(0), imu_samples=1).values())
    image, cloud, imu = (codec.encode(t, typical[t]) for t in ("Image", "PointCloud", "ImuBatch"))
    uav = "uav1"
    session = open_session()
    pubs = {
        k: session.declare_publisher(k, congestion_control=zenoh.CongestionControl.BLOCK)
        for k in (keys.image(uav), keys.lidar(uav), keys.imu(uav))
    }
    seqs = dict.fromkeys(pubs, 0)
    sent_bytes = 0

    def put(key: str, payload: bytes) -> None:
        nonlocal sent_bytes
        stamp = time.time_ns()
        pubs[key].put(payload, attachment=codec.encode_attachment(seqs[key], stamp, "bench"))
        seqs[key] += 1
        sent_bytes += len(payload)

    deadline = time.monotonic() + 10
    while not all(p.matching_status for p in pubs.values()) and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.3)
    frame_period = 1 / (CAMERA_HZ * factor) if factor else 0.0
    imu_per_frame = IMU_HZ / CAMERA_HZ
    start = time.monotonic()
    frame, imu_due = 0, 0.0
    while time.monotonic() - start < duration_s:
        imu_due += imu_per_frame
        while imu_due >= 1:
            put(keys.imu(uav), imu)
            imu_due -= 1
        put(keys.image(uav), image)
        put(keys.lidar(uav), cloud)
        frame += 1
        if frame_period:
            delay = start + frame * frame_period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
    elapsed = time.monotonic() - start
    end_ns = time.time_ns()
    start_ns = end_ns - int(elapsed * 1e9)
    # Keep the session (and its queued data) until the recorder says it has everything.
    recorded: dict[str, int] = {}
    sub = session.declare_subscriber(
        "atr/*/recorder/status",
        lambda s: recorded.update(codec.unpack(s.payload.to_bytes())["handled_by_key"]),
    )
    deadline = time.monotonic() + 120
    while any(recorded.get(k, 0) < n for k, n in seqs.items()) and time.monotonic() < deadline:
        time.sleep(0.1)
    sub.undeclare()
    session.close()
    print(
        json.dumps(
            {
                "sent": {k: v for k, v in seqs.items()},
                "bytes": sent_bytes,
                "elapsed_s": elapsed,
                "start_ns": start_ns,
                "end_ns": end_ns,
            }
        ),
        flush=True,
    )
    return 0


def _generator_command(factor: float, duration_s: float) -> list[str]:
    """This script as the load generator (in its own process, as a sensor would be)."""
    role = ["--role", "generator", "--factor", str(factor), "--duration", str(duration_s)]
    return [sys.executable, __file__, *role]


def one_run(factor: float, duration_s: float, workdir: Path) -> dict:
    from bus import mcap_tools

    hub_proc, hub = start_hub()
    out = workdir / f"rec-{factor}.mcap"
    env = bus_env(hub)
    env["ATR_LOG_LEVEL"] = "INFO"
    recorder = subprocess.Popen(
        [sys.executable, "-m", "cli.main", "record", "--out", str(out)],
        env=env,
        cwd=REPO,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        time.sleep(2.0)
        gen = subprocess.run(
            _generator_command(factor, duration_s),
            env=bus_env(hub),
            cwd=REPO,
            capture_output=True,
            text=True,
            timeout=duration_s + 120,
        )
        if gen.returncode != 0:
            raise RuntimeError(gen.stderr)
        sent = json.loads(gen.stdout.strip().splitlines()[-1])
        recorder.send_signal(signal.SIGTERM)
        _, err = recorder.communicate(timeout=300)
        closed_ns = time.time_ns()
    finally:
        if recorder.poll() is None:
            recorder.kill()
        hub_proc.terminate()
        hub_proc.wait()
    problems = mcap_tools.check(out)
    info = mcap_tools.info(out)
    counts = {c.topic: c.messages for c in info.channels}
    lost = sum(n - counts.get(k, 0) for k, n in sent["sent"].items())
    match = re.search(r"(\d+) gaps, max queue (\d+)", err)
    gaps, queue_max = (int(match.group(1)), int(match.group(2))) if match else (-1, -1)
    # the recorder is done when the last message is written; log times tell when it received it
    last_log_ns = info.end_ns or closed_ns
    messages = sum(sent["sent"].values())
    total_s = (last_log_ns - sent["start_ns"]) / 1e9
    size = out.stat().st_size
    out.unlink()
    return {
        "offered_MBps": sent["bytes"] / sent["elapsed_s"] / 1e6,
        "offered_msgps": messages / sent["elapsed_s"],
        "recorded_MBps": sent["bytes"] / total_s / 1e6,
        "recorded_msgps": messages / total_s,
        "lag_s": (last_log_ns - sent["end_ns"]) / 1e9,
        "queue_max": queue_max,
        "lost": lost,
        "gaps": gaps,
        "check": "OK" if not problems else problems[0],
        "file_ratio": size / sent["bytes"],
    }


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--role", default="bench", choices=["bench", "generator"])
    parser.add_argument("--factor", type=float, default=1.0)
    parser.add_argument("--duration", type=float, default=8.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--runs", default="1,2,0", help="load factors to run (0 = back to back)")
    parser.add_argument(
        "--profile", action="store_true", help="time each recorder stage (in-process) instead"
    )
    parser.add_argument("--zstd-levels", default="1,-1,-3", help="zstd levels to profile")
    args = parser.parse_args()
    if args.role == "generator":
        return generator(args.factor, args.duration)
    if args.profile:
        for level in args.zstd_levels.split(","):
            profile(args.factor, args.duration, int(level))
        return 0
    workdir = Path(tempfile.mkdtemp(prefix="atr-bench-"))
    ref_mb = (CAMERA_HZ * 3_686_588 + CAMERA_HZ * 240_087 + IMU_HZ * 300) / 1e6
    print(
        f"reference load (1x): {ref_mb:.0f} MB/s, {CAMERA_HZ * 2 + IMU_HZ} msg/s; "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    print(
        f"{'load':<6} {'offered MB/s':>12} {'recorded MB/s':>13} {'msg/s':>7} {'x ref':>6} {'lag s':>6} "
        f"{'queue':>6} {'lost':>5} {'gaps':>5} {'file/raw':>8}  check"
    )
    for factor in (float(f) for f in args.runs.split(",")):
        runs = [one_run(factor, args.duration, workdir) for _ in range(args.repeats)]
        med = {k: statistics.median(r[k] for r in runs) for k in runs[0] if k != "check"}
        label = f"{factor:g}x" if factor else "max"
        print(
            f"{label:<6} {med['offered_MBps']:>12.0f} {med['recorded_MBps']:>13.0f} "
            f"{med['recorded_msgps']:>7.0f} {med['recorded_MBps'] / ref_mb:>6.2f} {med['lag_s']:>6.2f} "
            f"{med['queue_max']:>6.0f} {max(r['lost'] for r in runs):>5} {max(r['gaps'] for r in runs):>5} "
            f"{med['file_ratio']:>8.2f}  {'; '.join(sorted({r['check'] for r in runs}))}",
            flush=True,
        )
    workdir.rmdir()
    return 0


def profile(factor: float, duration_s: float, zstd_level: int) -> None:
    """Recorder in this process with CPU timers on each stage (Zenoh's callback, the writer thread,
    the chunk thread): MB recorded per CPU-second of each, a figure that holds on a loaded
    machine."""
    from bus.mcap_tools import ChunkedWriter
    from bus.recorder import Recorder, RecorderConfig
    from bus.session import open_session

    busy: dict[str, float] = {"callback": 0.0, "writer": 0.0, "chunks (zstd+crc+write)": 0.0}

    def timed(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*a: Any, **k: Any) -> Any:
            t0 = time.thread_time()  # CPU time of this thread: meaningful on a loaded machine
            try:
                return fn(*a, **k)
            finally:
                busy[name] += time.thread_time() - t0

        return wrapper

    Recorder._on_sample = timed("callback", Recorder._on_sample)  # type: ignore[method-assign]
    Recorder._write = timed("writer", Recorder._write)  # type: ignore[method-assign]
    ChunkedWriter._write_chunk = timed("chunks (zstd+crc+write)", ChunkedWriter._write_chunk)  # type: ignore
    hub_proc, hub = start_hub()
    workdir = Path(tempfile.mkdtemp(prefix="atr-bench-"))
    try:
        os.environ.update(bus_env(hub))
        session = open_session()
        recorder = Recorder(session, workdir / "p.mcap", RecorderConfig(zstd_level=zstd_level))
        t0, cpu0 = time.perf_counter(), time.process_time()
        gen = subprocess.Popen(
            _generator_command(factor, duration_s),
            env=bus_env(hub),
            cwd=REPO,
            stdout=subprocess.PIPE,
            text=True,
        )
        # the generator waits for a recorder Status before closing; stand in for the recorder
        # service
        from bus import codec, keys

        while gen.poll() is None:
            session.put(
                keys.service_key("uav1", "recorder", "status"),
                codec.pack({"counters": {}, "handled_by_key": dict(recorder.stats.by_topic)}),
            )
            time.sleep(0.2)
        recorder.close()
        wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
        session.close()
    finally:
        hub_proc.terminate()
        hub_proc.wait()
    ratio = (workdir / "p.mcap").stat().st_size / recorder.stats.bytes
    print(
        f"profile at {factor:g}x, zstd level {zstd_level}, file/raw {ratio:.2f}, "
        f"{recorder.stats.bytes / 1e6:.0f} MB in wall {wall:.1f} s, "
        f"load average {os.getloadavg()[0]:.1f}):"
    )
    mb = recorder.stats.bytes / 1e6
    for name, seconds in busy.items():
        print(
            f"  {name:<26} CPU {seconds:6.2f} s -> {mb / max(seconds, 1e-9):6.0f} MB per CPU-second"
        )
    print(
        f"  {'whole process':<26} CPU {cpu:6.2f} s -> {mb / cpu:6.0f} MB per CPU-second "
        f"(2x reference load = {2 * 118} MB/s)"
    )
    for p in workdir.iterdir():
        p.unlink()
    workdir.rmdir()


if __name__ == "__main__":
    sys.exit(main())
