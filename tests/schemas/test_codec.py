"""Codec and schema registry: round trips, golden bytes, and the typed errors of bad payloads."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest

from atr.errors import SchemaError
from bus import codec, keys, schemas


def example(name: str) -> dict:
    """A valid message of every registered type (shared with the bus round-trip test)."""
    rng = np.random.default_rng(7)
    T = np.eye(4)
    T[:3, 3] = rng.normal(size=3)
    base = {"stamp_ns": 1_000_000_123, "seq": 4, "version": 1}
    bodies = {
        "Image": {
            "frame_seq": 4,
            "encoding": "rgb8",
            "data": rng.integers(0, 255, (48, 64, 3), dtype=np.uint8),
            "K": np.array([[100.0, 0, 32], [0, 100.0, 24], [0, 0, 1]]),
            "distortion": np.zeros(0),
        },
        "ImuBatch": {
            "frame_seq": 4,
            "t_ns": np.arange(5, dtype=np.int64) * 5_000_000,
            "gyro_radps": rng.normal(size=(5, 3)),
            "accel_mps2": rng.normal(size=(5, 3)),
            "init": {"T_world_imu": T, "v_world_mps": np.array([15.0, 0, 0])},
        },
        "PointCloud": {
            "source": "sfm-gftt",
            "frame_seqs": [3, 4],
            "points_m": rng.normal(size=(100, 3)).astype(np.float32),
            "sigma_m": rng.random(100).astype(np.float32),
            "viewpoint_m": np.zeros(3),
            "regions_m": np.array([[10.0, -4.0, 13.1, -0.2, 3.4]]),
        },
        "SearchGuidance": {"regions_m": np.array([[10.0, -4.0, 13.1, -0.2, 3.4]])},
        "CameraPose": {"frame_seq": 4, "T_world_cam": T, "integration": "strapdown"},
        "RelativePose": {
            "frame_seq_t": 3,
            "frame_seq_t1": 4,
            "stamp_ns_t": 1,
            "T_camt1_camt": T,
            "T_world_cam_t": T,
            "T_world_cam_t1": T,
        },
        "Detections": {
            "cloud_seq": 4,
            "frame_seqs": [3, 4],
            "source": "sfm-gftt",
            "detections": [
                {
                    "target": "t72",
                    "descriptor": "shot",
                    "T_world_target": T,
                    "score": 0.7,
                    "overlap": 0.8,
                    "inliers": 12,
                }
            ],
        },
        "Template": {
            "target": "t72",
            "descriptor": "fpfh",
            "cache_key": "abc",
            "radius_m": 1.5,
            "resolution_m": 0.3,
            "points_m": rng.normal(size=(50, 3)).astype(np.float32),
            "normals": rng.normal(size=(50, 3)).astype(np.float32),
            "keypoints_m": rng.normal(size=(20, 3)).astype(np.float32),
            "descriptors": rng.random((20, 33)).astype(np.float32),
            "params": {"views": 1},
        },
        "Truth": {
            "frame_seq": 4,
            "T_world_cam": T,
            "scenario": 1,
            "run": 3,
            "seed": 0,
            "targets": [{"name": "t72", "T_world_target": T, "visible_fraction": 0.9}],
        },
        "Status": {
            "service": "sfm",
            "state": "running",
            "counters": {"received": 3},
            "uptime_s": 1.5,
        },
        "ErrorReport": {
            "service": "sfm",
            "key": "atr/uav1/imu",
            "error_type": "SchemaError",
            "reason": "bad",
            "input_seq": None,
            "input_stamp_ns": None,
            "count": 1,
        },
        "Timing": {"service": "sfm", "input_seq": 4, "stages_ms": {"klt": 3.5}, "total_ms": 3.5},
        "Tracks": {
            "detections_seq": 4,
            "tracks": [
                {
                    "id": 1,
                    "target": "t72",
                    "state": "confirmed",
                    "T_world_target": T,
                    "covariance": np.diag([0.1, 0.1, 0.1, 0.01]),
                    "yaw_ambiguous": False,
                    "hits": 3,
                    "supporting_stamps_ns": [1, 2, 1_000_000_123],
                    "first_seen_ns": 1,
                    "last_seen_ns": 1_000_000_123,
                }
            ],
        },
    }
    return base | bodies[name]


def assert_same(a: object, b: object) -> None:
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape
        assert a.tobytes() == b.tobytes()
    elif isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            assert_same(a[k], b[k])
    elif isinstance(a, list):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            assert_same(x, y)
    else:
        assert a == b


def test_every_schema_is_covered_and_valid_json_schema():
    import jsonschema

    assert set(schemas.names()) == {
        "CameraPose",
        "Detections",
        "ErrorReport",
        "Image",
        "ImuBatch",
        "PointCloud",
        "RelativePose",
        "SearchGuidance",
        "Status",
        "Template",
        "Timing",
        "Tracks",
        "Truth",
    }
    for name in schemas.names():
        jsonschema.Draft202012Validator.check_schema(schemas.load(name))
        assert schemas.load(name)["description"]


@pytest.mark.parametrize("name", schemas.names())
def test_round_trip_is_exact(name):
    message = example(name)
    decoded = codec.decode(name, codec.encode(name, message))
    assert_same(message, decoded)


@pytest.mark.parametrize("name", schemas.names())
def test_encoding_is_plain_msgpack(name):
    # Our fast framing of large arrays must give exactly what msgpack itself writes.
    message = example(name)
    assert codec.pack(message) == msgpack.packb(message, default=codec._default, use_bin_type=True)


def test_golden_bytes_decode():
    # Written by hand from the wire format: {"a": float64[2] = [1.5, -2.0]}.
    header = bytes([3]) + b"<f8" + bytes([1]) + (2).to_bytes(8, "little")
    body = np.array([1.5, -2.0], "<f8").tobytes()
    ext = bytes([0xC7, len(header) + len(body), 1]) + header + body
    payload = bytes([0x81, 0xA1]) + b"a" + ext
    decoded = codec.unpack(payload)
    np.testing.assert_array_equal(decoded["a"], [1.5, -2.0])
    assert codec.pack({"a": np.array([1.5, -2.0])}) == payload


def test_decoded_arrays_are_read_only_views():
    message = example("Image")
    decoded = codec.decode("Image", codec.encode("Image", message))
    assert not decoded["data"].flags.writeable


@pytest.mark.parametrize(
    "payload", [b"", b"\xc1", b"\x92\x01", b"\x81\xa1a\xc7\x03\x01abc", b"\x81\xa1a\xc7\x01\x07x"]
)
def test_garbage_bytes_raise_schema_error(payload):
    with pytest.raises(SchemaError):
        codec.decode("ImuBatch", payload)


@pytest.mark.parametrize(
    ("field", "value", "expected"),
    [
        ("gyro_radps", np.zeros((5, 2)), "shape"),
        ("gyro_radps", np.zeros((5, 3), np.float32), "dtype"),
        ("accel_mps2", np.full((5, 3), np.nan), "NaN"),
        ("t_ns", [1, 2, 3], "numpy array"),
        ("frame_seq", -1, "minimum"),
    ],
)
def test_schema_violations_name_the_field(field, value, expected):
    message = example("ImuBatch") | {field: value}
    with pytest.raises(SchemaError) as info:
        codec.encode("ImuBatch", message)
    assert field in str(info.value) and expected in str(info.value)


def test_missing_and_unknown_fields_are_refused():
    message = example("Detections")
    with pytest.raises(SchemaError, match="cloud_seq"):
        codec.encode("Detections", {k: v for k, v in message.items() if k != "cloud_seq"})
    with pytest.raises(SchemaError, match="surprise"):
        codec.encode("Detections", message | {"surprise": 1})


def test_oversized_payload_is_refused_before_decoding():
    with pytest.raises(SchemaError, match="exceeds"):
        codec.unpack(b"\x00" * (codec.MAX_MESSAGE_BYTES + 1))


@pytest.mark.parametrize(
    ("key", "type_name"),
    [
        ("atr/uav1/camera/image", "Image"),
        ("atr/uav7/sfm/cloud", "PointCloud"),
        ("atr/templates/t72/hod-s", "Template"),
        ("atr/uav1/sfm/errors", "ErrorReport"),
        ("sim/uav1/truth", "Truth"),
        ("atr/uav2/tracks", "Tracks"),
        ("atr/uav1/guidance", "SearchGuidance"),
    ],
)
def test_key_table(key, type_name):
    assert keys.message_type(key) == type_name


def test_unknown_key_is_refused():
    from atr.errors import BusError

    with pytest.raises(BusError):
        keys.message_type("atr/uav1/camera/image/extra")


@pytest.mark.parametrize(
    ("name", "field", "path"),
    [
        ("PointCloud", "points_m", "points_m"),
        ("CameraPose", "T_world_cam", "T_world_cam"),
        ("ImuBatch", "gyro_radps", "gyro_radps"),
        ("Detections", "T_world_target", "detections/0/T_world_target"),
    ],
)
def test_finite_but_absurd_values_are_refused_naming_field_value_and_range(name, field, path):
    message = example(name)
    if name == "Detections":
        target = message["detections"][0]
    else:
        target = message
    array = np.array(target[field])
    array.flat[1] = 1e30
    target[field] = array
    with pytest.raises(SchemaError) as info:
        codec.encode(name, message)
    text = str(info.value)
    assert path in text and "1e+30" in text and "allowed range" in text
    payload = codec.pack(message)
    with pytest.raises(SchemaError, match="1e\\+30"):
        codec.decode(name, payload)


def test_values_at_the_bound_are_accepted():
    message = example("PointCloud")
    message["points_m"] = np.array([[1e5, -1e5, 0.0]])
    message["sigma_m"] = np.zeros(1)
    codec.decode("PointCloud", codec.encode("PointCloud", message))


@pytest.mark.parametrize("shape", [(0, 0), (0, 0, 3), (8, 64, 3)])
def test_an_empty_or_tiny_image_is_refused_with_its_shape(shape):
    message = example("Image") | {"data": np.zeros(shape, np.uint8)}
    with pytest.raises(SchemaError) as info:
        codec.decode("Image", codec.pack(message))
    assert "data" in str(info.value) and str(shape) in str(info.value)
    assert "at least (16, 16)" in str(info.value)


@pytest.mark.parametrize(
    ("encoding", "shape", "expected"),
    [("rgb8", (48, 64), "rgb8 is (H, W, 3)"), ("mono8", (48, 64, 3), "mono8 is (H, W)")],
)
def test_image_encoding_and_shape_must_agree(encoding, shape, expected):
    message = example("Image") | {"encoding": encoding, "data": np.zeros(shape, np.uint8)}
    with pytest.raises(SchemaError) as info:
        codec.encode("Image", message)
    assert "data" in str(info.value) and str(shape) in str(info.value)
    assert expected in str(info.value)
    agreeing = (48, 64, 3) if encoding == "rgb8" else (48, 64)
    codec.encode("Image", message | {"data": np.zeros(agreeing, np.uint8)})
