"""Key expressions of the contract (docs/architecture.md) and the message type each one carries."""

from __future__ import annotations

import re
from collections.abc import Callable

from atr.errors import BusError

SERVICE_KEYS = {"status": "Status", "errors": "ErrorReport", "timing": "Timing"}

# (pattern, message type) of every key expression, in the order they are matched; {uav}, {service},
# {target}, {descriptor} are single chunks. Each key below adds its row where it is declared.
_TABLE: list[tuple[str, str]] = []


def _uav_key(stream: str, message_type: str, doc: str) -> Callable[[str], str]:
    """Declare atr/{uav}/`stream`, carrying `message_type`; returns the function naming it for a UAV."""
    _TABLE.append((f"atr/{{uav}}/{stream}", message_type))

    def key(uav: str) -> str:
        return f"atr/{uav}/{stream}"

    key.__doc__ = doc
    return key


image = _uav_key("camera/image", "Image", "Key of the camera images of `uav`.")
imu = _uav_key("imu", "ImuBatch", "Key of the IMU batches of `uav`.")
lidar = _uav_key("lidar/cloud", "PointCloud", "Key of the LIDAR clouds of `uav` (baseline only).")
camera_pose = _uav_key("pose/camera", "CameraPose", "Key of the integrated camera poses of `uav`.")
relative_pose = _uav_key(
    "pose/relative", "RelativePose", "Key of the relative poses (eq. 1) of `uav`."
)
sfm_cloud = _uav_key("sfm/cloud", "PointCloud", "Key of the SfM clouds of `uav`.")
detections = _uav_key("detections", "Detections", "Key of the detections of `uav`.")
tracks = _uav_key("tracks", "Tracks", "Key of the tracks of `uav` (services/tracker).")
guidance = _uav_key(
    "guidance", "SearchGuidance", "Key of where atr_matcher looks next (track-guided search)."
)

# Keys whose messages are sensor inputs: what a replay publishes back on the bus.
INPUT_KEYS = ("camera/image", "imu", "lidar/cloud")


def template(target: str, descriptor: str) -> str:
    """Key of the template of `target` described with `descriptor`."""
    return f"atr/templates/{target}/{descriptor}"


def service_key(uav: str, service: str, kind: str) -> str:
    """Key of a service's `status`, `errors` or `timing` messages."""
    if kind not in SERVICE_KEYS:
        raise BusError(f"service key kind {kind!r} must be one of {sorted(SERVICE_KEYS)}")
    return f"atr/{uav}/{service}/{kind}"


def truth(uav: str) -> str:
    """Key of the simulator's truth for `uav`."""
    return f"sim/{uav}/truth"


_TABLE.append((template("{target}", "{descriptor}"), "Template"))
_TABLE += [(service_key("{uav}", "{service}", k), name) for k, name in SERVICE_KEYS.items()]
_TABLE.append((truth("{uav}"), "Truth"))
_COMPILED = [
    (re.compile("^" + re.sub(r"\{\w+\}", r"[^/]+", pattern) + "$"), name)
    for pattern, name in _TABLE
]


def message_type(key: str) -> str:
    """The message type carried on `key`, e.g. "Image" for atr/uav1/camera/image.

    Raises:
        BusError: the key is not one of the contract's key expressions.

    """
    for pattern, name in _COMPILED:
        if pattern.match(key):
            return name
    raise BusError(f"key {key!r} is not a key expression of the contract (docs/architecture.md)")


def is_data_key(key: str) -> bool:
    """True for keys whose messages fall under the determinism contract (all but status and timing)."""
    return not (key.endswith("/status") or key.endswith("/timing"))
