"""Codec and MCAP writer throughput: encode/decode MB/s of typical messages, chunk writing MB/s.

For each message (1280x960 RGB Image, 20k-point PointCloud, 200-sample ImuBatch):
  - bus.codec.encode (schema validation + msgpack with the ndarray extension) and bus.codec.decode;
  - reference in the same run: a plain copy of the same payload bytes (`bytes(memoryview)`), the
    floor of any encoder that must produce one contiguous buffer.
Then the recorder's ChunkedWriter on a stream of such messages: zstd level 1 (default) and 3.
Figures: median of REPEATS runs; MB = 1e6 bytes of encoded message.

Run: ./dev bench codec
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bus import codec, schemas
from bus.mcap_tools import ChunkedWriter

REPEATS = 15


def camera_image(rng: np.random.Generator) -> np.ndarray:
    """A 1280x960 RGB frame with smooth texture and sensor noise (compresses like a real frame, not
    like noise)."""
    y, x = np.mgrid[0:960, 0:1280].astype(np.float32)
    base = np.stack(
        [(x * 0.2 + y * 0.1) % 256, 128 + 60 * np.sin(x / 40), 128 + 60 * np.cos(y / 30)], -1
    )
    return np.clip(base + rng.normal(0, 3, base.shape), 0, 255).astype(np.uint8)


def messages(rng: np.random.Generator, imu_samples: int = 200) -> dict[str, tuple[str, dict]]:
    """Typical messages of the load described in docs/performance/bus.md: label -> (type, message)."""
    n = imu_samples
    return {
        "Image 1280x960 rgb8": (
            "Image",
            {
                "stamp_ns": 1,
                "seq": 0,
                "version": 1,
                "frame_seq": 0,
                "encoding": "rgb8",
                "data": camera_image(rng),
                "K": np.eye(3),
            },
        ),
        "PointCloud 20k float32": (
            "PointCloud",
            {
                "stamp_ns": 1,
                "seq": 0,
                "version": 1,
                "source": "lidar",
                "frame_seqs": [0],
                "points_m": rng.normal(size=(20_000, 3)).astype(np.float32),
            },
        ),
        f"ImuBatch {n} samples": (
            "ImuBatch",
            {
                "stamp_ns": 1,
                "seq": 0,
                "version": 1,
                "frame_seq": 0,
                "t_ns": np.arange(n, dtype=np.int64) * 5_000_000,
                "gyro_radps": rng.normal(size=(n, 3)),
                "accel_mps2": rng.normal(size=(n, 3)),
            },
        ),
    }


def median_s(fn: Callable[[], object], repeats: int = REPEATS) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    rng = np.random.default_rng(0)
    print(
        f"{'message':<24} {'bytes':>9} {'encode MB/s':>12} {'decode MB/s':>12} {'copy MB/s':>10} "
        f"{'enc/copy':>9} {'dec/copy':>9}"
    )
    encoded = {}
    for label, (type_name, message) in messages(rng).items():
        payload = codec.encode(type_name, message)
        encoded[label] = payload
        mb = len(payload) / 1e6
        t_enc = median_s(lambda: codec.encode(type_name, message))
        t_dec = median_s(lambda: codec.decode(type_name, payload))
        view = memoryview(payload)
        t_copy = median_s(lambda: bytes(view))
        print(
            f"{label:<24} {len(payload):>9} {mb / t_enc:>12.0f} {mb / t_dec:>12.0f} {mb / t_copy:>10.0f} "
            f"{t_enc / t_copy:>9.1f} {t_dec / t_copy:>9.1f}"
        )
    # validation share of decode for the image
    image = codec.unpack(encoded["Image 1280x960 rgb8"])
    t_val = median_s(lambda: schemas.validate("Image", image))
    print(f"schema validation of a decoded Image: {t_val * 1e3:.2f} ms")

    print(
        "\nChunkedWriter (recorder), 30 frames of the 2x load mix (per frame: 2 images, 2 clouds, 14 IMU):"
    )
    frame = (
        [encoded["Image 1280x960 rgb8"]] * 2
        + [encoded["PointCloud 20k float32"]] * 2
        + [encoded["ImuBatch 200 samples"][:600]] * 14
    )
    total = sum(map(len, frame)) * 30
    path = Path(tempfile.mkdtemp()) / "bench.mcap"
    for level, background in ((1, False), (1, True), (3, True), (-1, True)):

        def write(level: int = level, background: bool = background) -> int:
            path.unlink(missing_ok=True)  # the writer never overwrites
            w = ChunkedWriter(path, zstd_level=level, background=background)
            cid = w.add_channel("t", "msgpack", 0)
            for i in range(30):
                for j, data in enumerate(frame):
                    w.add_message(cid, i * 100 + j, i, i, data)
            w.close()
            return path.stat().st_size

        size = write()
        t = median_s(write, repeats=3)
        print(
            f"  zstd level {level:>2}, background={background!s:<5}: {total / t / 1e6:6.0f} MB/s, file/raw = {size / total:.2f}"
        )


if __name__ == "__main__":
    main()
