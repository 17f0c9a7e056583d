"""Helper processes for the recorder/replayer tests (run as scripts; not collected by pytest).

python _bus_helpers.py publish --frames N [--uav uav1] [--image-shape 48 64]
    waits until a recorder's Status is seen, then publishes N frames of inputs (truth, IMU
    batch, image, LIDAR cloud) plus one non-input message (a camera pose) per frame through
    bus.node.Node, and exits.
python _bus_helpers.py pipeline --seed S [--error-every K]
    a fake pipeline: answers every camera image with one Detections of the same stamp_ns after a
    random delay (or, every K-th frame, with an ErrorReport whose input_stamp_ns is the
    image's), until SIGTERM. Before each answer it checks that the next image has not arrived
    yet, says so on stderr if it has, and then exits with code 3 (what a lock-step replay must
    never cause).
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from typing import Any

import numpy as np

from atr.errors import InputError
from bus import keys
from bus.node import Node

FRAME_PERIOD_NS = 33_333_333
STAMP0_NS = 1_000_000_000


def frame_messages(
    frame: int, uav: str, image_shape: tuple[int, int], rng: np.random.Generator
) -> list[tuple[str, dict[str, Any]]]:
    """The inputs of one frame, in the order a sensor source would publish them."""
    stamp = STAMP0_NS + frame * FRAME_PERIOD_NS
    t_ns = stamp - FRAME_PERIOD_NS + np.arange(1, 8, dtype=np.int64) * (FRAME_PERIOD_NS // 7)
    t_ns[-1] = stamp
    T = np.eye(4)
    T[:3, 3] = rng.normal(size=3)
    return [
        (
            keys.truth(uav),
            {
                "stamp_ns": stamp,
                "frame_seq": frame,
                "T_world_cam": T,
                "scenario": 1,
                "run": 1,
                "targets": [{"name": "t72", "T_world_target": np.eye(4), "visible_fraction": 0.5}],
            },
        ),
        (
            keys.imu(uav),
            {
                "stamp_ns": stamp,
                "frame_seq": frame,
                "t_ns": t_ns,
                "gyro_radps": rng.normal(size=(7, 3)),
                "accel_mps2": rng.normal(size=(7, 3)),
            },
        ),
        (
            keys.image(uav),
            {
                "stamp_ns": stamp,
                "frame_seq": frame,
                "encoding": "rgb8",
                "data": rng.integers(0, 256, (*image_shape, 3), dtype=np.uint8),
                "K": np.eye(3),
            },
        ),
        (
            keys.lidar(uav),
            {
                "stamp_ns": stamp,
                "source": "lidar",
                "frame_seqs": [frame],
                "points_m": rng.normal(size=(500, 3)).astype(np.float32),
            },
        ),
        (keys.camera_pose(uav), {"stamp_ns": stamp, "frame_seq": frame, "T_world_cam": T}),
    ]


def _wait_for_status(node: Node, service: str, timeout_s: float = 20.0) -> None:
    seen = threading.Event()
    sub = node.session.declare_subscriber(f"atr/*/{service}/status", lambda _s: seen.set())
    try:
        if not seen.wait(timeout_s):
            raise SystemExit(f"no {service} status within {timeout_s} s")
    finally:
        sub.undeclare()


def publish(args: argparse.Namespace) -> int:
    rng = np.random.default_rng(args.seed)
    with Node("sensor_source", args.uav) as node:
        _wait_for_status(node, args.wait_for)
        time.sleep(0.3)
        for frame in range(args.frames):
            for key, message in frame_messages(frame, args.uav, tuple(args.image_shape), rng):
                try:
                    node.publish(key, message)
                except Exception as exc:  # a helper script reports and fails loudly
                    print(f"publish {key} failed: {exc}", file=sys.stderr)
                    return 1
            time.sleep(args.period)
        time.sleep(0.3)
    print("published", args.frames, flush=True)
    return 0


def pipeline(args: argparse.Namespace) -> int:
    rng = np.random.default_rng(args.seed)
    early = 0
    with Node("fake_pipeline", "uav1", inputs=["atr/*/camera/image"]) as node:
        node.ready()
        for n, message in enumerate(node.events()):
            with node.handling(message):
                time.sleep(float(rng.uniform(0.0, args.max_delay)))
                if node.pending():
                    early += 1
                    print(
                        f"next image arrived before the answer to frame {message.data['frame_seq']}",
                        file=sys.stderr,
                        flush=True,
                    )
                uav = message.key.split("/")[1]
                if args.error_every and n % args.error_every == args.error_every - 1:
                    raise InputError(f"frame {message.data['frame_seq']} refused on purpose")
                node.publish(
                    keys.detections(uav),
                    {
                        "stamp_ns": message.stamp_ns,
                        "cloud_seq": message.seq,
                        "detections": [],
                        "frame_seqs": [message.data["frame_seq"]],
                        "source": "fake",
                    },
                )
    return 3 if early else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("publish")
    p.add_argument("--frames", type=int, default=5)
    p.add_argument("--uav", default="uav1")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--period", type=float, default=0.02)
    p.add_argument("--image-shape", type=int, nargs=2, default=[48, 64])
    p.add_argument("--wait-for", default="recorder")
    q = sub.add_parser("pipeline")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--max-delay", type=float, default=0.05)
    q.add_argument("--error-every", type=int, default=0)
    args = parser.parse_args(argv)
    return publish(args) if args.cmd == "publish" else pipeline(args)


if __name__ == "__main__":
    sys.exit(main())
