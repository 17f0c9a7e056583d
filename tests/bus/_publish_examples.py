"""Child process: publishes one example message of every type on its contract key, through a Node."""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "schemas"))
from test_codec import example  # noqa: E402

from bus.node import Node  # noqa: E402
from bus.session import default_config  # noqa: E402

KEYS = {
    "Image": "atr/uav1/camera/image",
    "ImuBatch": "atr/uav1/imu",
    "PointCloud": "atr/uav1/sfm/cloud",
    "CameraPose": "atr/uav1/pose/camera",
    "RelativePose": "atr/uav1/pose/relative",
    "Detections": "atr/uav1/detections",
    "Tracks": "atr/uav1/tracks",
    "SearchGuidance": "atr/uav1/guidance",
    "Template": "atr/templates/t72/fpfh",
    "Truth": "sim/uav1/truth",
    "Status": "atr/uav1/x/status",
    "ErrorReport": "atr/uav1/x/errors",
    "Timing": "atr/uav1/x/timing",
}

if __name__ == "__main__":
    config = default_config("peer", connect=[sys.argv[1]], listen=["tcp/127.0.0.1:0"])
    with Node("examples", "uav9", zenoh_config=config, heartbeat_s=60) as node:
        time.sleep(float(sys.argv[2]))
        for name, key in KEYS.items():
            node.publish(key, example(name))
        time.sleep(0.5)
