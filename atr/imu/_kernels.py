"""Numba kernels of the IMU integration: one sequential pass over the samples (the rotation chain
cannot
be vectorised, so a compiled loop is the fast way; 100 samples take a few microseconds).

Both kernels take the samples *including* the left endpoint (the measurement at the start state's
time): gyro and accel are (N+1, 3), dt_s is (N,), and the measurements are taken as linear in time
between samples.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _quat_mul(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    aw, ax, ay, az = a[0], a[1], a[2], a[3]
    bw, bx, by, bz = b[0], b[1], b[2], b[3]
    out[0] = aw * bw - ax * bx - ay * by - az * bz
    out[1] = aw * bx + ax * bw + ay * bz - az * by
    out[2] = aw * by - ax * bz + ay * bw + az * bx
    out[3] = aw * bz + ax * by - ay * bx + az * bw


@numba.njit(cache=True, inline="always")
def _quat_exp(phi0: float, phi1: float, phi2: float, out: np.ndarray) -> None:
    angle = np.sqrt(phi0 * phi0 + phi1 * phi1 + phi2 * phi2)
    half = 0.5 * angle
    if angle < 1e-8:
        # Taylor series of sin(x/2)/x keeps full precision for tiny steps.
        s = 0.5 - angle * angle / 48.0
        out[0] = 1.0 - angle * angle / 8.0
    else:
        s = np.sin(half) / angle
        out[0] = np.cos(half)
    out[1] = s * phi0
    out[2] = s * phi1
    out[3] = s * phi2


@numba.njit(cache=True, inline="always")
def _quat_to_matrix(q: np.ndarray, R: np.ndarray) -> None:
    w, x, y, z = q[0], q[1], q[2], q[3]
    R[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[0, 1] = 2.0 * (x * y - w * z)
    R[0, 2] = 2.0 * (x * z + w * y)
    R[1, 0] = 2.0 * (x * y + w * z)
    R[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[1, 2] = 2.0 * (y * z - w * x)
    R[2, 0] = 2.0 * (x * z - w * y)
    R[2, 1] = 2.0 * (y * z + w * x)
    R[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@numba.njit(cache=True)
def matrix_to_quat(R: np.ndarray, q: np.ndarray) -> None:
    """Rotation matrix -> unit quaternion (w, x, y, z), Shepperd's method (stable at any angle)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > R[0, 0] and tr > R[1, 1] and tr > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + tr)
        q[0] = 0.25 * s
        q[1] = (R[2, 1] - R[1, 2]) / s
        q[2] = (R[0, 2] - R[2, 0]) / s
        q[3] = (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q[0] = (R[2, 1] - R[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (R[0, 1] + R[1, 0]) / s
        q[3] = (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q[0] = (R[0, 2] - R[2, 0]) / s
        q[1] = (R[0, 1] + R[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (R[1, 2] + R[2, 1]) / s
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q[0] = (R[1, 0] - R[0, 1]) / s
        q[1] = (R[0, 2] + R[2, 0]) / s
        q[2] = (R[1, 2] + R[2, 1]) / s
        q[3] = 0.25 * s
    norm = np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    for i in range(4):
        q[i] /= norm


@numba.njit(cache=True)
def strapdown_kernel(
    R0: np.ndarray,
    p0: np.ndarray,
    v0: np.ndarray,
    gyro_bias: np.ndarray,
    accel_bias: np.ndarray,
    gravity_world: np.ndarray,
    dt_s: np.ndarray,
    gyro: np.ndarray,
    accel: np.ndarray,
    q_out: np.ndarray,
    p_out: np.ndarray,
    v_out: np.ndarray,
    R_end: np.ndarray,
) -> None:
    """Strapdown propagation from R0 (3, 3); writes the state at every sample into q_out (N+1, 4)
    (w, x, y, z), p_out, v_out (N+1, 3), and the final attitude into R_end (3, 3).

    Attitude: q_{k+1} = q_k ⊗ Exp(h (w_k + w_{k+1}) / 2 + h^2 / 12 · w_k × w_{k+1}) — the rotation
    vector of a linearly varying body rate to third order (Bortz coning term), with bias-corrected
    rates.
    Velocity: trapezoid on the world acceleration a = R (f - b_a) + g. Position: exact for a linear
    in time, p_{k+1} = p_k + h v_k + h^2 (2 a_k + a_{k+1}) / 6.
    """
    n = dt_s.shape[0]
    q = np.empty(4)
    dq = np.empty(4)
    qn = np.empty(4)
    R = np.empty((3, 3))
    a_prev = np.empty(3)
    a_next = np.empty(3)
    matrix_to_quat(R0, q)
    for i in range(4):
        q_out[0, i] = q[i]
    for i in range(3):
        p_out[0, i] = p0[i]
        v_out[0, i] = v0[i]
    _quat_to_matrix(q, R)
    for i in range(3):
        a_prev[i] = gravity_world[i]
        for j in range(3):
            a_prev[i] += R[i, j] * (accel[0, j] - accel_bias[j])
    for k in range(n):
        h = dt_s[k]
        w0x = gyro[k, 0] - gyro_bias[0]
        w0y = gyro[k, 1] - gyro_bias[1]
        w0z = gyro[k, 2] - gyro_bias[2]
        w1x = gyro[k + 1, 0] - gyro_bias[0]
        w1y = gyro[k + 1, 1] - gyro_bias[1]
        w1z = gyro[k + 1, 2] - gyro_bias[2]
        c = h * h / 12.0
        phx = 0.5 * h * (w0x + w1x) + c * (w0y * w1z - w0z * w1y)
        phy = 0.5 * h * (w0y + w1y) + c * (w0z * w1x - w0x * w1z)
        phz = 0.5 * h * (w0z + w1z) + c * (w0x * w1y - w0y * w1x)
        _quat_exp(phx, phy, phz, dq)
        _quat_mul(q, dq, qn)
        norm = np.sqrt(qn[0] ** 2 + qn[1] ** 2 + qn[2] ** 2 + qn[3] ** 2)
        for i in range(4):
            q[i] = qn[i] / norm
            q_out[k + 1, i] = q[i]
        _quat_to_matrix(q, R)
        for i in range(3):
            a_next[i] = gravity_world[i]
            for j in range(3):
                a_next[i] += R[i, j] * (accel[k + 1, j] - accel_bias[j])
        for i in range(3):
            p_out[k + 1, i] = (
                p_out[k, i] + h * v_out[k, i] + h * h * (2.0 * a_prev[i] + a_next[i]) / 6.0
            )
            v_out[k + 1, i] = v_out[k, i] + 0.5 * h * (a_prev[i] + a_next[i])
            a_prev[i] = a_next[i]
    for i in range(3):
        for j in range(3):
            R_end[i, j] = R[i, j]


@numba.njit(cache=True)
def paper_kernel(
    angles0: np.ndarray,
    gyro_bias: np.ndarray,
    accel_bias: np.ndarray,
    dt_s: np.ndarray,
    gyro: np.ndarray,
    accel: np.ndarray,
    angles_out: np.ndarray,
    pos_body_out: np.ndarray,
    vel_body_out: np.ndarray,
) -> None:
    """The paper's eqs. (3)-(4) taken literally.

    Angles (u, v, w) of eq. (3) rotate about z, y, x; each is the time integral (trapezoid) of the
    bias-corrected body rate about that axis, as if body rates were Euler-angle rates. Eq. (4): the
    body-axis acceleration (bias-corrected specific force, gravity not removed) integrated twice
    from zero velocity, per axis, with no rotation between samples.
    """
    n = dt_s.shape[0]
    for i in range(3):
        angles_out[0, i] = angles0[i]
        pos_body_out[0, i] = 0.0
        vel_body_out[0, i] = 0.0
    # angle index -> gyro axis: u about z, v about y, w about x
    for k in range(n):
        h = dt_s[k]
        for i in range(3):
            axis = 2 - i
            w0 = gyro[k, axis] - gyro_bias[axis]
            w1 = gyro[k + 1, axis] - gyro_bias[axis]
            angles_out[k + 1, i] = angles_out[k, i] + 0.5 * h * (w0 + w1)
            a0 = accel[k, i] - accel_bias[i]
            a1 = accel[k + 1, i] - accel_bias[i]
            pos_body_out[k + 1, i] = (
                pos_body_out[k, i] + h * vel_body_out[k, i] + h * h * (2.0 * a0 + a1) / 6.0
            )
            vel_body_out[k + 1, i] = vel_body_out[k, i] + 0.5 * h * (a0 + a1)
