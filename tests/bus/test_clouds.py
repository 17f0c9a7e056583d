"""Compact cloud positions: half the bytes, error within half a quantisation step, same decoded form."""

import numpy as np
import pytest

from atr.errors import SchemaError
from bus import codec
from bus.clouds import cloud_points, compact_points


def test_compact_cloud_round_trip_error_is_within_half_a_step():
    rng = np.random.default_rng(3)
    points = rng.uniform([-250, -250, 0], [250, 250, 40], (20_000, 3))
    fields = compact_points(points)
    message = {
        "stamp_ns": 1,
        "seq": 0,
        "version": 1,
        "source": "sfm-gftt",
        "frame_seqs": [0, 1],
    } | fields
    decoded = codec.decode("PointCloud", codec.encode("PointCloud", message))
    error = np.abs(cloud_points(decoded) - points)
    assert (error <= fields["step_m"] / 2 + 1e-4).all()  # + float32 rounding at 250 m
    assert error.max() < 0.004  # 500 m extent / 65535 / 2 = 3.8 mm
    full = {k: v for k, v in message.items() if k not in fields} | {
        "points_m": points.astype(np.float32)
    }
    assert len(codec.encode("PointCloud", message)) < 0.55 * len(codec.encode("PointCloud", full))


def test_full_form_decodes_unchanged_and_empty_clouds_work():
    points = np.arange(12, dtype=np.float32).reshape(4, 3)
    np.testing.assert_array_equal(cloud_points({"points_m": points}), points)
    assert cloud_points(compact_points(np.zeros((0, 3)))).shape == (0, 3)


def test_a_cloud_needs_one_of_the_two_forms():
    base = {"stamp_ns": 1, "seq": 0, "version": 1, "source": "sfm-gftt", "frame_seqs": [0]}
    with pytest.raises(SchemaError):
        codec.encode("PointCloud", base)
    with pytest.raises(SchemaError):
        codec.encode(
            "PointCloud", base | {"points_q": np.zeros((2, 3), np.uint16)}
        )  # no origin/step
