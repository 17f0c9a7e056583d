"""Time `atr diff` on a generated ~100-frame recording: two equal recordings (bytes fast path) and two that
differ in every data message (every pair decoded and compared field by field). Median of several runs.

    python bench/diff.py [--frames 100] [--width 1280] [--height 960] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bus import codec, schemas
from bus.diff import diff_recordings
from bus.mcap_tools import ChunkedWriter

TOPICS = {
    "atr/uav1/camera/image": "Image",
    "atr/uav1/sfm/cloud": "PointCloud",
    "atr/uav1/detections": "Detections",
    "atr/uav1/pose/camera": "CameraPose",
}


def write(path: Path, frames: int, width: int, height: int, shift: float) -> int:
    """A flight-shaped recording; `shift` is added to every float of every data message but images."""
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (height, width, 3), dtype=np.uint8)
    points = rng.normal(size=(20_000, 3)).astype(np.float32)
    with ChunkedWriter(path) as writer:
        ids = {}
        for topic, kind in TOPICS.items():
            ids[topic] = writer.add_channel(
                topic, "msgpack", writer.add_schema(kind, "jsonschema", schemas.schema_bytes(kind))
            )
        for k in range(frames):
            stamp = 1_000_000_000 + k * 250_000_000
            base = {"stamp_ns": stamp, "seq": k, "version": 1}
            T = np.eye(4)
            T[:3, 3] = [k + shift, 0.0, 50.0]
            image_k = np.roll(image, k, axis=1)
            if shift:
                image_k = image_k.copy()
                image_k[0, 0, 0] ^= 1
            messages = {
                "atr/uav1/camera/image": base
                | {"frame_seq": k, "encoding": "rgb8", "data": image_k, "K": np.eye(3)},
                "atr/uav1/sfm/cloud": base
                | {"source": "sfm-gftt", "frame_seqs": [k], "points_m": points + np.float32(shift)},
                "atr/uav1/detections": base
                | {
                    "cloud_seq": k,
                    "frame_seqs": [k],
                    "source": "sfm-gftt",
                    "detections": [
                        {
                            "target": "t72",
                            "descriptor": "shot",
                            "T_world_target": T,
                            "score": 150.0 + shift,
                            "overlap": 0.6,
                            "inliers": 40,
                        }
                    ],
                },
                "atr/uav1/pose/camera": base
                | {"frame_seq": k, "T_world_cam": T, "integration": "strapdown"},
            }
            for topic, message in messages.items():
                writer.add_message(ids[topic], stamp, stamp, k, codec.pack(message))
    return path.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=960)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        base, same, other = (Path(tmp) / n for n in ("base.mcap", "same.mcap", "other.mcap"))
        size = write(base, args.frames, args.width, args.height, 0.0)
        write(same, args.frames, args.width, args.height, 0.0)
        write(other, args.frames, args.width, args.height, 1e-3)
        print(
            f"{args.frames} frames of {args.width}x{args.height} RGB: {size / 1e6:.0f} MB per recording"
        )
        for name, new in (("equal (bytes fast path)", same), ("every data message differs", other)):
            times = []
            for _ in range(args.repeat):
                start = time.perf_counter()
                report = diff_recordings(base, new)
                times.append(time.perf_counter() - start)
            verdict = "same" if report.same else f"{len(report.differing_topics)} topics differ"
            print(
                f"{name}: median {statistics.median(times):.2f} s over {args.repeat} runs ({verdict})"
            )


if __name__ == "__main__":
    main()
