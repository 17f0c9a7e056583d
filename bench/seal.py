"""Sealing cost against reading a recording once (issue goal: seal <= 1.5 x one read).

A recording of SIZE_MB is generated with the project's writer: camera-like frames (smooth texture and
sensor noise, so they compress like images, not random bytes) at 3.7 MB each, and 10 small messages
per frame. Then, alternating in one process, REPEATS times each:
  - read: every record once through `mcap`'s StreamReader (chunks decompressed), what any reader does;
  - seal: `bus.seal.seal` (the same read, plus a SHA-256 per payload, the Merkle tree, the signature,
    the manifest written).
Prints the median of each and their ratio.

Run: ./dev bench seal [--size-mb 1024] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bus import mcap_tools  # noqa: E402
from bus import seal as sealing  # noqa: E402


def make_recording(path: Path, size_mb: int) -> int:
    """Write camera-like frames until the payloads reach size_mb; returns the message count."""
    rng = np.random.default_rng(0)
    h, w = 960, 1280
    yy, xx = np.mgrid[0:h, 0:w]
    base = (127 + 60 * np.sin(xx / 37.0) * np.cos(yy / 23.0)).astype(np.int16)
    messages, written, frame = 0, 0, 0
    with mcap_tools.ChunkedWriter(path, background=True) as writer:
        image = writer.add_channel("atr/uav1/camera/image", "msgpack", 0)
        small = writer.add_channel("atr/uav1/imu", "msgpack", 0)
        while written < size_mb * 1_000_000:
            noise = rng.integers(-4, 5, size=(h, w), dtype=np.int16)
            gray = np.clip(base + noise, 0, 255).astype(np.uint8)
            payload = np.repeat(gray[:, :, None], 3, axis=2).tobytes()
            t = 1_000_000_000 + frame * 33_000_000
            writer.add_message(image, t, t, frame, payload)
            for k in range(10):
                writer.add_message(small, t + k, t + k, frame * 10 + k, rng.bytes(200))
            written += len(payload)
            messages += 11
            frame += 1
    return messages


def read_once(path: Path) -> int:
    """Every record through StreamReader; returns the payload bytes seen."""
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    total = 0
    with path.open("rb") as f:
        for record in StreamReader(f).records:
            if isinstance(record, Message):
                total += len(record.data)
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size-mb", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.mcap"
        count = make_recording(path, args.size_mb)
        keys = sealing.generate_keys(Path(tmp) / "keys")
        key = sealing.load_private_key(keys[0])
        print(f"recording: {path.stat().st_size / 1e6:.0f} MB on disk, {count} messages")
        reads, seals = [], []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            read_once(path)
            reads.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            sealing.seal(path, key)
            seals.append(time.perf_counter() - t0)
        r, s = statistics.median(reads), statistics.median(seals)
        print(
            f"read once: {r:.2f} s   seal: {s:.2f} s   seal / read: {s / r:.2f} (median of {args.repeats})"
        )


if __name__ == "__main__":
    main()
