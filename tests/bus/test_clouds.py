"""Compact clouds: only the points the matcher uses, half the bytes a point, positions within half a
quantisation step, sigma within float16's relative error, the same decoded form."""

import numpy as np
import pytest

from atr.errors import SchemaError
from atr.recognition.steps import uniform_subsample
from bus import codec
from bus.clouds import cloud_points, compact_cloud, compact_points


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


def test_compact_sigma_keeps_its_relative_error_and_halves_its_bytes():
    rng = np.random.default_rng(5)
    points = rng.uniform(-50, 50, (5_000, 3))
    sigma = rng.lognormal(-2.0, 1.5, 5_000)  # millimetres to metres, as SfM's depth sigma
    sigma[:2] = (0.0, 1e5)  # a perfect point, and one that says nothing
    base = {"stamp_ns": 1, "seq": 0, "version": 1, "source": "sfm-sgm", "frame_seqs": [0, 1]}
    message = base | compact_cloud(points, sigma, leaf_m=1e-3)  # no two points share a voxel
    decoded = codec.decode("PointCloud", codec.encode("PointCloud", message))
    sent = np.asarray(decoded["sigma_m"], np.float64)
    assert decoded["sigma_m"].dtype == np.float16 and len(sent) == len(points)
    assert sent.min() == 0.0 and np.isfinite(sent).all() and sent.max() > 6e4  # clipped, never inf
    expected = sigma[uniform_subsample(points, 1e-3)]  # the order the matcher sees
    told = expected > 0
    assert (np.abs(sent - np.minimum(expected, 65504.0))[told] / expected[told]).max() <= 2.0**-11
    float32 = base | compact_points(points) | {"sigma_m": sigma.astype(np.float32)}
    saved = len(codec.encode("PointCloud", float32)) - len(codec.encode("PointCloud", message))
    assert saved >= 2 * len(points)  # two bytes a point


def test_the_air_sends_what_the_matcher_would_keep_of_a_dense_cloud():
    rng = np.random.default_rng(8)
    leaf_m = 0.15
    # dense: 7 points a voxel
    points = rng.uniform([-3, -3, 0], [3, 3, 0.3], (60_000, 3)).astype(np.float32)
    sigma = rng.uniform(0.01, 0.5, len(points))
    base = {"stamp_ns": 1, "seq": 0, "version": 1, "source": "sfm-sgm", "frame_seqs": [0, 1]}
    message = base | compact_cloud(points, sigma, leaf_m)
    decoded = codec.decode("PointCloud", codec.encode("PointCloud", message))
    sent = cloud_points(decoded).astype(np.float64)
    kept = uniform_subsample(points.astype(np.float64), leaf_m)
    assert len(sent) == len(kept) < len(points) / 2
    # the matcher's points, in its order, to within the quantisation
    np.testing.assert_allclose(sent, points[kept], atol=float(decoded["step_m"].max()))
    np.testing.assert_allclose(decoded["sigma_m"], sigma[kept], rtol=2.0**-11)
    # and its own subsampling of what arrives keeps (nearly) all of it: points a quantisation step
    # from a voxel face may cross it
    assert len(uniform_subsample(sent, leaf_m)) >= 0.99 * len(sent)
