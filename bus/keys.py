"""Key expressions of the contract (docs/architecture.md) and the message type each one carries."""

from __future__ import annotations

import re

from atr.errors import BusError

SERVICE_KEYS = {"status": "Status", "errors": "ErrorReport", "timing": "Timing"}

# (pattern, message type); {uav}, {service}, {target}, {descriptor} are single chunks.
_TABLE: list[tuple[str, str]] = [
    ("atr/{uav}/camera/image", "Image"),
    ("atr/{uav}/imu", "ImuBatch"),
    ("atr/{uav}/lidar/cloud", "PointCloud"),
    ("atr/{uav}/pose/camera", "CameraPose"),
    ("atr/{uav}/pose/relative", "RelativePose"),
    ("atr/{uav}/sfm/cloud", "PointCloud"),
    ("atr/{uav}/detections", "Detections"),
    ("atr/{uav}/tracks", "Tracks"),
    ("atr/templates/{target}/{descriptor}", "Template"),
    ("atr/{uav}/{service}/status", "Status"),
    ("atr/{uav}/{service}/errors", "ErrorReport"),
    ("atr/{uav}/{service}/timing", "Timing"),
    ("sim/{uav}/truth", "Truth"),
]
_COMPILED = [
    (re.compile("^" + re.sub(r"\{\w+\}", r"[^/]+", pattern) + "$"), name)
    for pattern, name in _TABLE
]

# Keys whose messages are sensor inputs: what a replay publishes back on the bus.
INPUT_KEYS = ("camera/image", "imu", "lidar/cloud")


def message_type(key: str) -> str:
    """The message type carried on `key`, e.g. "Image" for atr/uav1/camera/image.

    Raises:
        BusError: the key is not one of the contract's key expressions.

    """
    for pattern, name in _COMPILED:
        if pattern.match(key):
            return name
    raise BusError(f"key {key!r} is not a key expression of the contract (docs/architecture.md)")


def image(uav: str) -> str:
    """Key of the camera images of `uav`."""
    return f"atr/{uav}/camera/image"


def imu(uav: str) -> str:
    """Key of the IMU batches of `uav`."""
    return f"atr/{uav}/imu"


def lidar(uav: str) -> str:
    """Key of the LIDAR clouds of `uav` (baseline only)."""
    return f"atr/{uav}/lidar/cloud"


def camera_pose(uav: str) -> str:
    """Key of the integrated camera poses of `uav`."""
    return f"atr/{uav}/pose/camera"


def relative_pose(uav: str) -> str:
    """Key of the relative poses (eq. 1) of `uav`."""
    return f"atr/{uav}/pose/relative"


def sfm_cloud(uav: str) -> str:
    """Key of the SfM clouds of `uav`."""
    return f"atr/{uav}/sfm/cloud"


def detections(uav: str) -> str:
    """Key of the detections of `uav`."""
    return f"atr/{uav}/detections"


def tracks(uav: str) -> str:
    """Key of the tracks of `uav` (services/tracker)."""
    return f"atr/{uav}/tracks"


def template(target: str, descriptor: str) -> str:
    """Key of the template of `target` described with `descriptor`."""
    return f"atr/templates/{target}/{descriptor}"


def truth(uav: str) -> str:
    """Key of the simulator's truth for `uav`."""
    return f"sim/{uav}/truth"


def service_key(uav: str, service: str, kind: str) -> str:
    """Key of a service's `status`, `errors` or `timing` messages."""
    if kind not in SERVICE_KEYS:
        raise BusError(f"service key kind {kind!r} must be one of {sorted(SERVICE_KEYS)}")
    return f"atr/{uav}/{service}/{kind}"


def is_data_key(key: str) -> bool:
    """True for keys whose messages fall under the determinism contract (all but status and timing)."""
    return not (key.endswith("/status") or key.endswith("/timing"))
