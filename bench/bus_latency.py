"""One-way latency between two processes: our codec + Node versus a raw Zenoh put of the same bytes.

Topology as in compose/local: a hub peer on loopback, a sender (this process) and a receiver
process, both peers that dial the hub. Messages:
  - ~1 KB: an ImuBatch of 10 samples on atr/bench/imu;
  - 3.7 MB: a 1280x960 RGB Image on atr/bench/camera/image.
"node": the sender calls Node.publish (schema validation + encode + put) with stamp_ns =
time.time_ns() taken just before; the receiver takes the time when Node.events() yields the decoded,
validated message. "raw": session.put of the same encoded bytes with the send time in the
attachment; the receiver takes the time in the Zenoh callback after `payload.to_bytes()`. Both
clocks are the host's CLOCK_REALTIME. Raw and node messages alternate; figures are medians over
rounds of each round's p50/p99. Paced sends (latency, not throughput).

Run: ./dev bench bus_latency [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SIZES = {  # label -> (node key, raw key, messages per round, period s)
    "1 KB": ("atr/bench/imu", "bench/raw/imu", 200, 0.005),
    "3.7 MB": ("atr/bench/camera/image", "bench/raw/image", 40, 0.1),
}


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def bus_env(hub: str) -> dict[str, str]:
    env = dict(
        os.environ,
        ATR_ZENOH_CONNECT=hub,
        ATR_ZENOH_LISTEN="tcp/127.0.0.1:0",
        ATR_LOG_LEVEL="WARNING",
    )
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("ATR_ZENOH_CONFIG", None)
    return env


def start_hub() -> tuple[subprocess.Popen[bytes], str]:
    """A hub peer (services/router) on a free loopback port; returns the process and its
    endpoint."""
    port = free_port()
    hub = f"tcp/127.0.0.1:{port}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "cli.main", "service", "router", "--mode", "peer", "--listen", hub],
        env=bus_env(hub),
        cwd=REPO,
    )
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return proc, hub
        time.sleep(0.05)
    proc.kill()
    raise RuntimeError("hub did not start")


def imu_message(n: int = 16) -> dict:
    rng = np.random.default_rng(1)
    return {
        "stamp_ns": 0,
        "frame_seq": 0,
        "t_ns": np.arange(n, dtype=np.int64),
        "gyro_radps": rng.normal(size=(n, 3)),
        "accel_mps2": rng.normal(size=(n, 3)),
    }


def image_message() -> dict:
    rng = np.random.default_rng(2)
    return {
        "stamp_ns": 0,
        "frame_seq": 0,
        "encoding": "rgb8",
        "data": rng.integers(0, 256, (960, 1280, 3), dtype=np.uint8),
        "K": np.eye(3),
    }


def receiver() -> int:
    """Print "<key> <latency ns>" for every message received, until SIGTERM."""
    from bus.node import Node

    out = sys.stdout

    def on_raw(sample) -> None:  # noqa: ANN001
        sample.payload.to_bytes()
        (sent,) = struct.unpack("<q", sample.attachment.to_bytes())
        out.write(f"{sample.key_expr} {time.time_ns() - sent}\n")
        out.flush()

    # Breakdown of the node path: also note when Zenoh's callback has the bytes (before the queue
    # hop).
    original_on_sample = Node._on_sample

    def on_sample(self, sample) -> None:  # noqa: ANN001
        original_on_sample(self, sample)
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        from bus import codec as _codec

        decoded = _codec.decode_attachment(attachment)
        if decoded is not None:
            out.write(f"{sample.key_expr}#callback {time.time_ns() - decoded[1]}\n")

    Node._on_sample = on_sample  # type: ignore[method-assign]

    with Node("bench_rx", "bench", inputs=[SIZES["1 KB"][0], SIZES["3.7 MB"][0]]) as node:
        sub = node.session.declare_subscriber("bench/raw/**", on_raw)
        print("ready", flush=True)
        for message in node.events():
            out.write(f"{message.key} {time.time_ns() - message.stamp_ns}\n")
            out.flush()
        sub.undeclare()
    return 0


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--role", default="sender", choices=["sender", "receiver"])
    args = parser.parse_args()
    if args.role == "receiver":
        return receiver()

    from bus import codec
    from bus.node import Node
    from bus.session import default_config

    hub_proc, hub = start_hub()
    rx = subprocess.Popen(
        [sys.executable, __file__, "--role", "receiver"],
        env=bus_env(hub),
        cwd=REPO,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert rx.stdout is not None and rx.stdout.readline().strip() == "ready"
        config = default_config("peer", connect=[hub], listen=["tcp/127.0.0.1:0"])
        node = Node("bench_tx", "bench", zenoh_config=config, heartbeat_s=60)
        time.sleep(1.5)  # routes settle
        templates = {"1 KB": ("ImuBatch", imu_message()), "3.7 MB": ("Image", image_message())}
        for label, (type_name, message) in templates.items():
            size = len(codec.encode(type_name, {"seq": 0, "version": 1} | message))
            print(f"{label}: {type_name} of {size} bytes")
        publish_ms: dict[str, list[float]] = {}
        for r in range(args.rounds):
            for label, (node_key, raw_key, count, period) in SIZES.items():
                type_name, message = templates[label]
                payload = codec.encode(type_name, {"seq": 0, "version": 1} | message)
                encode_s = []
                for _ in range(count):  # raw and ours alternate, so both see the same machine load
                    node.session.put(raw_key, payload, attachment=struct.pack("<q", time.time_ns()))
                    time.sleep(period)
                    t0 = time.perf_counter()
                    node.publish(node_key, message | {"stamp_ns": time.time_ns()})
                    encode_s.append(time.perf_counter() - t0)
                    time.sleep(period)
                publish_ms.setdefault(label, []).append(statistics.median(encode_s) * 1e3)
            print(f"round {r + 1}/{args.rounds} sent", flush=True)
        time.sleep(1.0)
        node.close()
    finally:
        rx.terminate()
        lines, _ = rx.communicate(timeout=30)
        hub_proc.terminate()
        hub_proc.wait()

    per_key: dict[str, list[int]] = {}
    for line in lines.splitlines():
        key, _, value = line.partition(" ")
        if value:
            per_key.setdefault(key, []).append(int(value))
    print(
        f"\nload average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; {args.rounds} rounds"
    )
    print(f"{'size':<8} {'path':<5} {'n':>5} {'p50 ms':>8} {'p99 ms':>8}   (median over rounds)")
    figures = {}
    for label, (node_key, raw_key, count, _) in SIZES.items():
        for path, key in (("raw", raw_key), ("node", node_key)):
            values = per_key.get(key, [])
            rounds = [values[i * count : (i + 1) * count] for i in range(args.rounds)]
            rounds = [v for v in rounds if v]
            p50 = statistics.median(float(np.percentile(v, 50)) for v in rounds) / 1e6
            p99 = statistics.median(float(np.percentile(v, 99)) for v in rounds) / 1e6
            figures[(label, path)] = (p50, p99)
            lost = count * args.rounds - len(values)
            print(
                f"{label:<8} {path:<5} {len(values):>5} {p50:>8.2f} {p99:>8.2f}"
                + (f"   LOST {lost}" if lost else "")
            )
        values = per_key.get(node_key + "#callback", [])
        if values:
            print(
                f"{label:<8} node: send -> Zenoh callback p50 {np.percentile(values, 50) / 1e6:.2f} ms "
                f"(validate + encode + transport); the rest is queue hop + decode + validate"
            )
        print(
            f"{label:<8} node: Node.publish call (validate + encode + put) median {statistics.median(publish_ms[label]):.2f} ms"
        )
        (r50, r99), (n50, n99) = figures[(label, "raw")], figures[(label, "node")]
        print(f"{label:<8} node/raw: p50 x{n50 / r50:.2f}, p99 x{n99 / r99:.2f}")
    print(json.dumps({f"{k[0]} {k[1]}": v for k, v in figures.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
