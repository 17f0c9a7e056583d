"""IMU pose integration (paper §II-B-1, eqs. 1-4): gyro + accelerometer -> camera pose, R*_cam."""

from atr.imu.attitude import attitude_angles, attitude_matrix, invert_pose, relative_camera_pose
from atr.imu.config import ImuConfig
from atr.imu.strapdown import NavState, PoseIntegrator, check_imu_samples, integrate, warm_up

__all__ = [
    "ImuConfig",
    "NavState",
    "PoseIntegrator",
    "attitude_angles",
    "attitude_matrix",
    "check_imu_samples",
    "integrate",
    "invert_pose",
    "relative_camera_pose",
    "warm_up",
]
