"""A circle flown with sinusoidal pitch and roll: gyro and specific force are derived analytically
here (not by the code under test) and integrated back into poses."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from atr.imu import ImuConfig, NavState, PoseIntegrator, integrate, relative_camera_pose

G = 9.80665
RADIUS_M, OMEGA = 30.0, 0.4  # orbit: 12 m/s
BOB_M, BOB_RATE = 2.0, 0.9  # vertical oscillation
PITCH0, PITCH_RATE = 0.15, 1.3
ROLL0, ROLL_RATE = 0.25, 2.1
GYRO_BIAS = np.array([0.004, -0.002, 0.003])
ACCEL_BIAS = np.array([0.05, -0.08, 0.02])


def truth(t: np.ndarray):
    """Pose, velocity, body rate and specific force at times t (s), in closed form."""
    c, s = np.cos(OMEGA * t), np.sin(OMEGA * t)
    p = np.stack([RADIUS_M * c, RADIUS_M * s, 50.0 + BOB_M * np.sin(BOB_RATE * t)], axis=-1)
    v = np.stack([-RADIUS_M * OMEGA * s, RADIUS_M * OMEGA * c,
                  BOB_M * BOB_RATE * np.cos(BOB_RATE * t)], -1)  # fmt: skip
    acc = np.stack([-RADIUS_M * OMEGA**2 * c, -RADIUS_M * OMEGA**2 * s,
                    -BOB_M * BOB_RATE**2 * np.sin(BOB_RATE * t)], -1)  # fmt: skip
    # z-y-x Euler angles: yaw along the tangent, sinusoidal pitch and roll
    yaw, yaw_d = OMEGA * t + np.pi / 2, np.full_like(t, OMEGA)
    pitch, pitch_d = PITCH0 * np.sin(PITCH_RATE * t), PITCH0 * PITCH_RATE * np.cos(PITCH_RATE * t)
    roll, roll_d = ROLL0 * np.cos(ROLL_RATE * t), -ROLL0 * ROLL_RATE * np.sin(ROLL_RATE * t)
    R = Rotation.from_euler("ZYX", np.stack([yaw, pitch, roll], -1)).as_matrix()
    # body rate of z-y-x Euler angles (standard kinematic relation)
    w = np.stack([
        roll_d - yaw_d * np.sin(pitch),
        pitch_d * np.cos(roll) + yaw_d * np.cos(pitch) * np.sin(roll),
        -pitch_d * np.sin(roll) + yaw_d * np.cos(pitch) * np.cos(roll),
    ], -1)  # fmt: skip
    f = np.einsum("nji,nj->ni", R, acc + [0.0, 0.0, G])
    return R, p, v, w, f


def test_analytic_rates_match_finite_differences():
    # guards the test's own derivation: Rdot = R [w]x and pdot = v
    t = np.array([0.3, 1.1, 1.7])
    h = 1e-6
    R, p, v, w, _ = truth(t)
    Rp, pp, *_ = truth(t + h)
    Rm, pm, *_ = truth(t - h)
    w_fd = (Rotation.from_matrix(np.einsum("nji,njk->nik", Rm, Rp)).as_rotvec()) / (2 * h)
    np.testing.assert_allclose(w_fd, w, atol=1e-6)
    np.testing.assert_allclose((pp - pm) / (2 * h), v, atol=1e-5)


def _start_state(t0_s: float) -> NavState:
    R, p, v, _, _ = truth(np.array([t0_s]))
    return NavState(int(round(t0_s * 1e9)), R[0], p[0], v[0], GYRO_BIAS, ACCEL_BIAS)


def _samples(t0_s: float, duration_s: float, rate_hz: float = 200.0):
    t_ns = int(round(t0_s * 1e9)) + np.arange(0, int(duration_s * rate_hz) + 2) * int(1e9 / rate_hz)
    _, _, _, w, f = truth(t_ns / 1e9)
    return t_ns.astype(np.int64), w + GYRO_BIAS, f + ACCEL_BIAS


def _errors(R_est, p_est, t_s):
    R, p, *_ = truth(np.array([t_s]))
    rot_deg = np.degrees(Rotation.from_matrix(R[0].T @ R_est).magnitude())
    return rot_deg, float(np.linalg.norm(p_est - p[0]))


def test_strapdown_reproduces_the_trajectory_within_1cm_and_0p01deg_over_2s():
    t0 = 0.7
    t_ns, gyro, accel = _samples(t0, 2.0)
    cfg = ImuConfig()
    pi = PoseIntegrator(cfg, _start_state(t0))
    pi.add_imu(t_ns[:250], gyro[:250], accel[:250])
    # 20 Hz frames, offset by 1.3 ms from the IMU clock, second batch arrives halfway
    frames_ns = int(t0 * 1e9) + 1_300_000 + np.arange(1, 40) * 50_000_000
    worst = (0.0, 0.0)
    for k, stamp in enumerate(frames_ns):
        if k == 20:
            pi.add_imu(t_ns[250:], gyro[250:], accel[250:])
        T = pi.camera_pose(int(stamp))
        rot_deg, trans_m = _errors(T[:3, :3], T[:3, 3], stamp / 1e9)
        worst = (max(worst[0], rot_deg), max(worst[1], trans_m))
    assert frames_ns[-1] / 1e9 - t0 > 1.9
    assert worst[0] < 0.01
    assert worst[1] < 0.01


def test_integrate_batch_matches_truth_and_relative_pose_matches():
    t0 = 2.0
    t_ns, gyro, accel = _samples(t0, 2.0)
    keep = t_ns <= int((t0 + 2.0) * 1e9)
    t_ns, gyro, accel = t_ns[keep], gyro[keep], accel[keep]
    s0 = _start_state(t0)
    s1 = integrate(s0, t_ns[1:], gyro[1:], accel[1:], config=ImuConfig())
    assert s1.stamp_ns == t_ns[-1]
    rot_deg, trans_m = _errors(s1.R_world_imu, s1.p_world_m, t_ns[-1] / 1e9)
    assert rot_deg < 0.01 and trans_m < 0.01
    # eq. (1) from integrated poses equals eq. (1) from true poses
    R, p, *_ = truth(np.array([t0, t_ns[-1] / 1e9]))
    T_true = [np.eye(4), np.eye(4)]
    for i in range(2):
        T_true[i][:3, :3], T_true[i][:3, 3] = R[i], p[i]
    rel_true = relative_camera_pose(*T_true)
    rel_est = relative_camera_pose(s0.T_world_imu, s1.T_world_imu)
    assert np.linalg.norm(rel_est[:3, 3] - rel_true[:3, 3]) < 0.01


def test_paper_mode_is_far_off_in_flight():
    # the literal eq. (4) forgets the initial velocity (12 m/s) and gravity: metres off in 0.5 s
    t0 = 1.0
    t_ns, gyro, accel = _samples(t0, 0.5)
    cfg = ImuConfig(integration="paper")
    s1 = integrate(_start_state(t0), t_ns[1:], gyro[1:], accel[1:], config=cfg)
    _, trans_m = _errors(s1.R_world_imu, s1.p_world_m, t_ns[-1] / 1e9)
    assert trans_m > 12.0 * 0.5 * 0.5


@pytest.mark.parametrize("rate_hz", [100.0, 400.0])
def test_error_shrinks_with_rate(rate_hz):
    # second-order scheme at least: halving the step cuts the position error by >= 3x
    def err(rate):
        t0 = 0.5
        t_ns, gyro, accel = _samples(t0, 2.0, rate)
        s1 = integrate(_start_state(t0), t_ns[1:], gyro[1:], accel[1:],
                       config=ImuConfig(imu_rate_hz=rate))  # fmt: skip
        return _errors(s1.R_world_imu, s1.p_world_m, t_ns[-1] / 1e9)[1]

    coarse, fine = err(rate_hz), err(2 * rate_hz)
    assert fine < coarse / 3.0
