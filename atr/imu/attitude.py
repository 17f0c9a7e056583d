"""Attitude and relative pose as printed in the paper (§II-B-1, eqs. 1-3).

Eq. (3) as printed is R = Rz(u) · Ry(v) · Rx(w), the aerospace z-y-x matrix, with u, v, w called
"pitch, roll and yaw". The matrix itself rotates by u about z and by w about x, i.e. the printed
labels put "pitch" where the usual convention has yaw. We keep the matrix exactly as printed and the
paper's argument order; see docs/imu.md.
"""

from __future__ import annotations

import numpy as np

from atr.errors import InputError


def attitude_matrix(pitch_rad: float, roll_rad: float, yaw_rad: float) -> np.ndarray:
    """Eq. (3) of the paper exactly as printed, with u, v, w = pitch, roll, yaw.

    Args:
        pitch_rad: u, radians (the printed matrix rotates about z by u).
        roll_rad: v, radians (about y).
        yaw_rad: w, radians (about x).

    Returns:
        (3, 3) float64 rotation matrix R(u, v, w) = Rz(u) Ry(v) Rx(w).

    """
    su, cu = np.sin(pitch_rad), np.cos(pitch_rad)
    sv, cv = np.sin(roll_rad), np.cos(roll_rad)
    sw, cw = np.sin(yaw_rad), np.cos(yaw_rad)
    return np.array(
        [
            [cu * cv, cu * sv * sw - su * cw, cu * sv * cw + su * sw],
            [su * cv, su * sv * sw + cu * cw, su * sv * cw - cu * sw],
            [-sv, cv * sw, cv * cw],
        ],
        dtype=np.float64,
    )


def attitude_angles(R: np.ndarray) -> tuple[float, float, float]:
    """Inverse of eq. (3): the (pitch u, roll v, yaw w) angles, radians, of a rotation matrix.

    Args:
        R: (3, 3) rotation matrix.

    Returns:
        (u, v, w) with v in [-pi/2, pi/2]; at v = ±pi/2 (gimbal lock) w is set to 0.

    """
    R = np.asarray(R, dtype=np.float64)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise InputError(f"rotation must be a finite (3, 3) matrix, got shape {R.shape}")
    v = float(np.arcsin(np.clip(-R[2, 0], -1.0, 1.0)))
    if abs(R[2, 0]) < 1.0 - 1e-12:
        u = float(np.arctan2(R[1, 0], R[0, 0]))
        w = float(np.arctan2(R[2, 1], R[2, 2]))
    else:  # gimbal lock: only u - w (or u + w) is defined; put it all in u
        w = 0.0
        u = float(np.arctan2(-R[0, 1], R[1, 1]))
    return u, v, w


def invert_pose(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (uses R^T, not a general matrix inverse).

    Args:
        T: (4, 4) float64 rigid transform T_a_b.

    Returns:
        (4, 4) float64 T_b_a.

    """
    T = _check_pose(T, "pose")
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


def relative_camera_pose(T_world_cam_t: np.ndarray, T_world_cam_t1: np.ndarray) -> np.ndarray:
    """Eq. (1): R*_cam = R_cam^{t+1} · (R_cam^t)^-1, the camera's pose shift between two frames.

    R_cam^t is the camera-from-world extrinsic at t, i.e. inv(T_world_cam_t), so
    R*_cam = T_cam_t1_world · T_world_cam_t = T_cam_t1_cam_t.

    Args:
        T_world_cam_t: (4, 4) world-from-camera pose at frame t.
        T_world_cam_t1: (4, 4) world-from-camera pose at frame t+1.

    Returns:
        (4, 4) float64 T_cam_t1_cam_t: maps a point from the camera frame at t to the camera frame
        at t+1.

    """
    T_t = _check_pose(T_world_cam_t, "T_world_cam_t")
    return invert_pose(T_world_cam_t1) @ T_t


def _check_pose(T: np.ndarray, name: str) -> np.ndarray:
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise InputError(f"{name} must be a (4, 4) matrix, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise InputError(f"{name} contains NaN or inf: {T.tolist()}")
    return T
