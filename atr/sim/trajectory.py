"""The UAV's camera-head trajectory as closed-form functions of time, and its exact IMU readings.

Position is a circular orbit plus a sum of sinusoidal disturbances; attitude is yaw/pitch aimed at
the orbit centre (from the position, by atan2) plus sinusoidal pointing error and roll wobble.
Velocity, acceleration and body angular rate are the analytic derivatives of these functions (never
finite differences), so integrating the noise-free IMU reproduces the pose to integration error
only.

Frames: the trajectory is that of the IMU body (x forward along the optical axis, y left, z up),
world z up; attitude R_world_imu = Rz(yaw) @ Ry(pitch) @ Rx(roll) (paper eq. 3 with u = yaw, v =
pitch, w = roll).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from atr.sim.config import SimConfig
from atr.sim.scenarios import Scenario

_N_WAVES = 3  # sinusoids per disturbed quantity


@dataclass(frozen=True)
class ImuState:
    """Exact kinematic state of the IMU at times t (arrays over the leading axis).

    Attributes:
        p_world: (N, 3) position, metres.
        v_world: (N, 3) velocity, m/s.
        a_world: (N, 3) acceleration, m/s^2 (kinematic, without gravity).
        R_world_imu: (N, 3, 3) attitude.
        omega_imu: (N, 3) angular rate in the IMU frame, rad/s.

    """

    p_world: np.ndarray
    v_world: np.ndarray
    a_world: np.ndarray
    R_world_imu: np.ndarray
    omega_imu: np.ndarray


@dataclass(frozen=True)
class Orbit:
    """A disturbed circular orbit with a gimbal aimed at its centre.

    Attributes:
        center: (3,) aim point (orbit centre on the ground), metres.
        radius_m: horizontal orbit radius, metres.
        height_m: orbit height above the aim point, metres.
        rate_radps: signed angular rate around the centre, rad/s (sign: direction).
        phase0_rad: azimuth of the UAV at t = 0, rad.
        pos_amp: (3, K) disturbance amplitudes, metres; pos_freq (3, K) Hz; pos_phase (3, K) rad.
        att_amp: (3, K) attitude disturbance amplitudes (yaw, pitch, roll), rad; att_freq,
        att_phase alike.
        att_bias: (3,) constant pointing error (yaw, pitch, roll), rad.

    """

    center: np.ndarray
    radius_m: float
    height_m: float
    rate_radps: float
    phase0_rad: float
    pos_amp: np.ndarray
    pos_freq: np.ndarray
    pos_phase: np.ndarray
    att_amp: np.ndarray
    att_freq: np.ndarray
    att_phase: np.ndarray
    att_bias: np.ndarray

    def state(self, t_s: np.ndarray) -> ImuState:
        """Exact position, velocity, acceleration, attitude and body rate at times t_s (N,), s."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        ang = self.phase0_rad + self.rate_radps * t
        w = self.rate_radps
        c, s = np.cos(ang), np.sin(ang)
        p = np.column_stack([self.radius_m * c, self.radius_m * s, np.full_like(t, self.height_m)])
        v = np.column_stack([-self.radius_m * w * s, self.radius_m * w * c, np.zeros_like(t)])
        a = np.column_stack(
            [-self.radius_m * w * w * c, -self.radius_m * w * w * s, np.zeros_like(t)]
        )
        dp, dv, da = _waves(t, self.pos_amp, self.pos_freq, self.pos_phase)
        p = p + dp + self.center
        v = v + dv
        a = a + da
        # gimbal aim: yaw/pitch of the line of sight to the centre, plus pointing error
        d = self.center - p
        dd = -v
        hxy2 = d[:, 0] ** 2 + d[:, 1] ** 2
        hxy = np.sqrt(hxy2)
        yaw = np.arctan2(d[:, 1], d[:, 0])
        yaw_d = (d[:, 0] * dd[:, 1] - d[:, 1] * dd[:, 0]) / hxy2
        pitch = np.arctan2(-d[:, 2], hxy)
        hxy_d = (d[:, 0] * dd[:, 0] + d[:, 1] * dd[:, 1]) / hxy
        pitch_d = (hxy * (-dd[:, 2]) - (-d[:, 2]) * hxy_d) / (hxy2 + d[:, 2] ** 2)
        e, e_d, _ = _waves(t, self.att_amp, self.att_freq, self.att_phase)
        yaw = yaw + e[:, 0] + self.att_bias[0]
        pitch = pitch + e[:, 1] + self.att_bias[1]
        roll = e[:, 2] + self.att_bias[2]
        yaw_d = yaw_d + e_d[:, 0]
        pitch_d = pitch_d + e_d[:, 1]
        roll_d = e_d[:, 2]
        R = euler_zyx(yaw, pitch, roll)
        # body rates of the ZYX Euler sequence
        sr, cr = np.sin(roll), np.cos(roll)
        sp, cp = np.sin(pitch), np.cos(pitch)
        omega = np.column_stack(
            [
                roll_d - yaw_d * sp,
                pitch_d * cr + yaw_d * cp * sr,
                -pitch_d * sr + yaw_d * cp * cr,
            ]
        )
        return ImuState(p, v, a, R, omega)

    def T_world_imu(self, t_s: float) -> np.ndarray:
        """(4, 4) world-from-IMU pose at time t_s, seconds."""
        st = self.state(np.array([t_s]))
        T = np.eye(4)
        T[:3, :3] = st.R_world_imu[0]
        T[:3, 3] = st.p_world[0]
        return T


def euler_zyx(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations Rz(yaw) @ Ry(pitch) @ Rx(roll) (paper eq. 3)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    R = np.empty((np.size(yaw), 3, 3))
    R[:, 0, 0] = cy * cp
    R[:, 0, 1] = cy * sp * sr - sy * cr
    R[:, 0, 2] = cy * sp * cr + sy * sr
    R[:, 1, 0] = sy * cp
    R[:, 1, 1] = sy * sp * sr + cy * cr
    R[:, 1, 2] = sy * sp * cr - cy * sr
    R[:, 2, 0] = -sp
    R[:, 2, 1] = cp * sr
    R[:, 2, 2] = cp * cr
    return R


def _waves(
    t: np.ndarray, amp: np.ndarray, freq: np.ndarray, phase: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sum of sinusoids per axis and its first two derivatives: (N, 3) each."""
    w = 2 * np.pi * freq  # (3, K)
    arg = t[:, None, None] * w[None] + phase[None]  # (N, 3, K)
    x = np.sum(amp * np.sin(arg), axis=2)
    xd = np.sum(amp * w * np.cos(arg), axis=2)
    xdd = np.sum(-amp * w * w * np.sin(arg), axis=2)
    return x, xd, xdd


def make_orbit(
    sc: Scenario,
    target_xyz: np.ndarray,
    rng: np.random.Generator,
    config: SimConfig,
    aim_height_m: float = 1.1,
) -> Orbit:
    """The orbit of one run: range and obliquity from the scenario, disturbances drawn from rng.

    The orbit centre (the gimbal's aim point) is the target's centre offset by a small random
    error; the
    camera height is range x sin(obliquity) above the aim point but at least config.min_altitude_m
    above
    the target's ground.
    """
    ob = np.deg2rad(sc.obliquity_deg)
    offset = rng.normal(0.0, config.aim_offset_frac * sc.range_m, 2)
    center = np.array(
        [target_xyz[0] + offset[0], target_xyz[1] + offset[1], target_xyz[2] + aim_height_m]
    )
    height = max(sc.range_m * np.sin(ob), config.min_altitude_m - aim_height_m)
    radius = np.sqrt(max(sc.range_m**2 - height**2, 1.0))
    direction = 1.0 if rng.random() < 0.5 else -1.0
    rate = direction * config.speed_mps / radius
    pos_amp = (
        rng.uniform(0.3, 1.0, (3, _N_WAVES)) * config.position_disturbance_m / np.sqrt(_N_WAVES)
    )
    pos_freq = rng.uniform(0.05, 0.4, (3, _N_WAVES))
    pos_phase = rng.uniform(0, 2 * np.pi, (3, _N_WAVES))
    jit = np.deg2rad(config.pointing_jitter_deg)
    rol = np.deg2rad(config.roll_disturbance_deg)
    att_amp = rng.uniform(0.3, 1.0, (3, _N_WAVES)) / np.sqrt(_N_WAVES)
    att_amp[:2] *= jit
    att_amp[2] *= rol
    att_freq = rng.uniform(0.05, 0.6, (3, _N_WAVES))
    att_phase = rng.uniform(0, 2 * np.pi, (3, _N_WAVES))
    att_bias = rng.normal(0.0, np.deg2rad(config.pointing_bias_deg), 3)
    att_bias[2] = 0.0
    phase0 = float(rng.uniform(0, 2 * np.pi))
    return Orbit(
        center,
        float(radius),
        float(height),
        float(rate),
        phase0,
        pos_amp,
        pos_freq,
        pos_phase,
        att_amp,
        att_freq,
        att_phase,
        att_bias,
    )
