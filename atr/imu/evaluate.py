"""Accuracy of IMU pose integration against a ground-truth trajectory over fixed time windows.

Pure functions of an IMU stream and a ground-truth trajectory as `atr.io.euroc` reads them: each window
starts from the ground-truth state (pose, velocity, biases) at a ground-truth instant, integrates the IMU
to the ground-truth instant nearest `window_s` later, and compares the integrated motion with the ground
truth's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from atr.errors import InputError
from atr.imu.config import ImuConfig
from atr.imu.strapdown import NavState, PoseIntegrator
from atr.io.euroc import EurocGroundTruth, EurocImu


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
    imu: EurocImu,
    gt: EurocGroundTruth,
    start_indices: np.ndarray,
    window_s: float,
    *,
    config: ImuConfig,
) -> WindowErrors:
    """Integrate the IMU over windows that start from ground-truth states.

    Args:
        imu: the whole IMU stream.
        gt: the ground-truth states (the body frame is the IMU's).
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
        t0 = int(gt.t_ns[i])
        j = int(np.argmin(np.abs(gt.t_ns - (t0 + window_s * 1e9))))
        t1 = int(gt.t_ns[j])
        if j <= i or t0 < imu.t_ns[0] or t1 > imu.t_ns[-1]:
            continue
        a = max(int(np.searchsorted(imu.t_ns, t0, side="right")) - 1, 0)
        b = int(np.searchsorted(imu.t_ns, t1, side="left")) + 1
        state = NavState(t0, gt.R_world_body[i], gt.p_world_m[i], gt.v_world_mps[i],
                         gt.gyro_bias_radps[i], gt.accel_bias_mps2[i])  # fmt: skip
        pi = PoseIntegrator(config, state)
        pi.add_imu(imu.t_ns[a:b], imu.gyro_radps[a:b], imu.accel_mps2[a:b])
        pi.camera_pose(t1)
        end = pi.state
        starts.append(t0)
        durations.append((t1 - t0) / 1e9)
        rot.append(Rotation.from_matrix(gt.R_world_body[j].T @ end.R_world_imu).magnitude())
        trans.append(float(np.linalg.norm(end.p_world_m - gt.p_world_m[j])))
        dist.append(float(np.linalg.norm(gt.p_world_m[j] - gt.p_world_m[i])))
    return WindowErrors(
        window_s,
        np.asarray(starts, dtype=np.int64),
        np.asarray(durations),
        np.asarray(rot),
        np.asarray(trans),
        np.asarray(dist),
    )


@dataclass(frozen=True)
class GroundTruthErrors:
    """The ground truth's own errors, measured from the data without the integrator under test.

    Attributes:
        world_tilt_rad: angle between the ground truth's world z and the gravity measured at rest
            (mean of R_world_imu (f - b_a) over a static segment), radians.
        gyro_bias_error_radps: |mean gyro at rest - ground-truth gyro bias|, rad/s (Earth rate,
            7.3e-5 rad/s, is below it and counted in).
        velocity_error_mps: RMS of the ground-truth speed at rest, m/s.
        position_noise_m: per-sample position noise at rest: 3-D norm of the per-axis robust std of
            second differences / sqrt(6), metres.
        rotation_noise_rad: per-sample rotation noise at rest, the same on rotation vectors,
            radians.

    """

    world_tilt_rad: float
    gyro_bias_error_radps: float
    velocity_error_mps: float
    position_noise_m: float
    rotation_noise_rad: float


def ground_truth_errors(
    imu: EurocImu, gt: EurocGroundTruth, static_until_ns: int
) -> GroundTruthErrors:
    """Estimate the ground truth's own error terms (see GroundTruthErrors).

    Args:
        imu: the whole IMU stream.
        gt: the ground-truth states (the body frame is the IMU's).
        static_until_ns: the vehicle is at rest from the first ground-truth instant to this stamp;
            every term is measured over that segment.

    """
    i = 0  # the static segment starts at the first ground-truth row
    m = (imu.t_ns >= gt.t_ns[0]) & (imu.t_ns <= static_until_ns)
    if m.sum() < 10:
        raise InputError(
            f"static segment up to {static_until_ns} ns holds {int(m.sum())} IMU samples (need 10)"
        )
    f_world = (gt.R_world_body[i] @ (imu.accel_mps2[m] - gt.accel_bias_mps2[i]).T).T.mean(axis=0)
    tilt = float(np.arctan2(np.hypot(f_world[0], f_world[1]), f_world[2]))
    bias_err = float(np.linalg.norm(imu.gyro_radps[m].mean(axis=0) - gt.gyro_bias_radps[i]))
    # At rest the true velocity is zero and the true pose constant: what the ground truth shows is
    # its error.
    k = int(np.searchsorted(gt.t_ns, static_until_ns, side="right"))
    if k < 5:
        raise InputError(
            f"static segment up to {static_until_ns} ns holds {k} ground-truth rows (need 5)"
        )
    vel_err = float(np.sqrt(np.mean(np.sum(gt.v_world_mps[:k] ** 2, axis=1))))
    p = gt.p_world_m[:k]
    d2 = p[2:] - 2.0 * p[1:-1] + p[:-2]
    pos_noise = float(np.linalg.norm(1.4826 * np.median(np.abs(d2), axis=0)) / np.sqrt(6.0))
    Rs = gt.R_world_body[:k]
    rv = Rotation.from_matrix(np.einsum("ji,njk->nik", Rs[0], Rs)).as_rotvec()
    d2r = rv[2:] - 2.0 * rv[1:-1] + rv[:-2]
    rot_noise = float(np.linalg.norm(1.4826 * np.median(np.abs(d2r), axis=0)) / np.sqrt(6.0))
    return GroundTruthErrors(tilt, bias_err, vel_err, pos_noise, rot_noise)


def error_bound(
    window_s: float,
    gyro_noise_density: float,
    accel_noise_density: float,
    gt: GroundTruthErrors,
    gravity_mps2: float,
) -> tuple[float, float]:
    """One-sigma-scale prediction of the rotation (rad) and translation (m) error of a window.

    rotation = sqrt(3) sigma_g sqrt(T)                  angle random walk, 3 axes
             + db_g T                                    ground-truth gyro bias error
             + sqrt(2) sigma_R,gt                        ground-truth rotation noise at both ends
    translation = sqrt(3) sigma_a T^1.5 / sqrt(3)        velocity random walk, 3 axes
                + g tilt T^2 / 2                         ground-truth world z not along gravity
                + g db_g T^3 / 6                         tilt growing from the gyro bias error
                + dv_gt T + sqrt(2) sigma_p,gt           ground-truth velocity and position errors
    """
    T = window_s
    rot = np.sqrt(3.0) * gyro_noise_density * np.sqrt(T) + gt.gyro_bias_error_radps * T
    rot += np.sqrt(2.0) * gt.rotation_noise_rad
    trans = accel_noise_density * T**1.5
    trans += gravity_mps2 * np.sin(gt.world_tilt_rad) * T**2 / 2.0
    trans += gravity_mps2 * gt.gyro_bias_error_radps * T**3 / 6.0
    trans += gt.velocity_error_mps * T + np.sqrt(2.0) * gt.position_noise_m
    return float(rot), float(trans)
