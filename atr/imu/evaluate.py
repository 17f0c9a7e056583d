"""Accuracy of IMU pose integration against a ground-truth trajectory over fixed time windows.

Pure functions on arrays: each window starts from the ground-truth state (pose, velocity, biases) at a
ground-truth instant, integrates the IMU to the ground-truth instant nearest `window_s` later, and compares
the integrated motion with the ground truth's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from atr.errors import InputError
from atr.imu.config import ImuConfig
from atr.imu.strapdown import NavState, PoseIntegrator


@dataclass(frozen=True)
class WindowErrors:
    """Errors of windows of one length.

    Attributes:
        window_s: nominal window length, seconds.
        start_ns: (K,) int64 start stamps, ns.
        duration_s: (K,) actual window lengths (end on a ground-truth instant), seconds.
        rotation_error_rad: (K,) angle of R_gt_end^T R_est_end (the start is exact), radians.
        translation_error_m: (K,) |p_est_end - p_gt_end| (the start is exact), metres.
        gt_distance_m: (K,) distance travelled according to the ground truth, metres.
    """

    window_s: float
    start_ns: np.ndarray
    duration_s: np.ndarray
    rotation_error_rad: np.ndarray
    translation_error_m: np.ndarray
    gt_distance_m: np.ndarray


def window_errors(
    imu_t_ns: np.ndarray,
    gyro_radps: np.ndarray,
    accel_mps2: np.ndarray,
    gt_t_ns: np.ndarray,
    gt_R_world_imu: np.ndarray,
    gt_p_world_m: np.ndarray,
    gt_v_world_mps: np.ndarray,
    gt_gyro_bias_radps: np.ndarray,
    gt_accel_bias_mps2: np.ndarray,
    start_indices: np.ndarray,
    window_s: float,
    *,
    config: ImuConfig,
) -> WindowErrors:
    """Integrate the IMU over windows that start from ground-truth states.

    Args:
        imu_t_ns, gyro_radps, accel_mps2: the whole IMU stream, (N,), (N, 3), (N, 3).
        gt_t_ns: (M,) ground-truth stamps, ns. gt_R_world_imu: (M, 3, 3). gt_p_world_m, gt_v_world_mps,
            gt_gyro_bias_radps, gt_accel_bias_mps2: (M, 3).
        start_indices: (K,) indices into the ground truth where windows start.
        window_s: window length, seconds (ends on the nearest ground-truth instant).
        config: integration settings (its T_imu_cam is ignored: errors are of the IMU pose).

    Returns:
        WindowErrors for the windows that lie inside both streams.
    """
    if window_s <= 0.0:
        raise InputError(f"window_s {window_s} must be > 0")
    starts, durations, rot, trans, dist = [], [], [], [], []
    for i in np.asarray(start_indices, dtype=np.int64):
        t0 = int(gt_t_ns[i])
        j = int(np.argmin(np.abs(gt_t_ns - (t0 + window_s * 1e9))))
        t1 = int(gt_t_ns[j])
        if j <= i or t0 < imu_t_ns[0] or t1 > imu_t_ns[-1]:
            continue
        a = max(int(np.searchsorted(imu_t_ns, t0, side="right")) - 1, 0)
        b = int(np.searchsorted(imu_t_ns, t1, side="left")) + 1
        state = NavState(t0, gt_R_world_imu[i], gt_p_world_m[i], gt_v_world_mps[i],
                         gt_gyro_bias_radps[i], gt_accel_bias_mps2[i])  # fmt: skip
        pi = PoseIntegrator(config, state)
        pi.add_imu(imu_t_ns[a:b], gyro_radps[a:b], accel_mps2[a:b])
        pi.camera_pose(t1)
        end = pi.state
        starts.append(t0)
        durations.append((t1 - t0) / 1e9)
        rot.append(Rotation.from_matrix(gt_R_world_imu[j].T @ end.R_world_imu).magnitude())
        trans.append(float(np.linalg.norm(end.p_world_m - gt_p_world_m[j])))
        dist.append(float(np.linalg.norm(gt_p_world_m[j] - gt_p_world_m[i])))
    return WindowErrors(
        window_s,
        np.asarray(starts, dtype=np.int64),
        np.asarray(durations),
        np.asarray(rot),
        np.asarray(trans),
        np.asarray(dist),
    )
