"""The IMU readings are the exact derivatives of the trajectory: integrating them reproduces it."""

import numpy as np
import pytest

from atr.imu import ImuConfig, NavState, integrate
from atr.sim import SimConfig, imu_samples, scenario
from atr.sim.flight import STAMP0_NS
from atr.sim.trajectory import make_orbit


def _rot_err_deg(Ra, Rb):
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


@pytest.mark.parametrize("number,run", [(1, 1), (1, 4), (2, 2), (3, 1)])
def test_noise_free_imu_integrates_to_true_pose_over_2s(number, run):
    cfg = SimConfig()
    orbit = make_orbit(
        scenario(number, run), np.array([3.0, -2.0, 0.0]), np.random.default_rng(7), cfg
    )
    t = np.arange(0, int(2.0 * cfg.imu_rate_hz) + 1) / cfg.imu_rate_hz
    imu = imu_samples(orbit, t, cfg, rng=None)
    st0 = orbit.state(t[:1])
    state = NavState(
        STAMP0_NS, st0.R_world_imu[0], st0.p_world[0], st0.v_world[0], np.zeros(3), np.zeros(3)
    )
    t_ns = STAMP0_NS + np.round(t * 1e9).astype(np.int64)
    icfg = ImuConfig(gravity_mps2=cfg.gravity_mps2, imu_rate_hz=cfg.imu_rate_hz)
    out = integrate(state, t_ns[1:], imu.gyro_radps[1:], imu.accel_mps2[1:], config=icfg)
    true = orbit.state(t[-1:])
    assert np.linalg.norm(out.p_world_m - true.p_world[0]) < 0.01
    assert _rot_err_deg(out.R_world_imu, true.R_world_imu[0]) < 0.01
    # the motion is not trivial: the UAV moved and turned
    assert np.linalg.norm(true.p_world[0] - st0.p_world[0]) > 20.0
    assert _rot_err_deg(true.R_world_imu[0], st0.R_world_imu[0]) > 5.0


def test_gravity_at_level_hover_direction():
    """Specific force points up in the world (gravity included): its world z is about +g."""
    cfg = SimConfig()
    orbit = make_orbit(scenario(1, 4), np.zeros(3), np.random.default_rng(1), cfg)
    t = np.linspace(0, 5, 50)
    imu = imu_samples(orbit, t, cfg, rng=None)
    st = orbit.state(t)
    f_world = np.einsum("nij,nj->ni", st.R_world_imu, imu.accel_mps2)
    np.testing.assert_allclose(
        f_world - st.a_world, np.tile([0, 0, cfg.gravity_mps2], (50, 1)), atol=1e-9
    )


def test_imu_noise_statistics():
    cfg = SimConfig()
    orbit = make_orbit(scenario(1, 2), np.zeros(3), np.random.default_rng(1), cfg)
    t = np.arange(4000) / cfg.imu_rate_hz
    clean = imu_samples(orbit, t, cfg, rng=None)
    noisy = imu_samples(orbit, t, cfg, rng=np.random.default_rng(3))
    dg = np.diff(noisy.gyro_radps - clean.gyro_radps, axis=0)  # differencing removes the slow bias
    sigma_g = cfg.gyro_noise_density * np.sqrt(cfg.imu_rate_hz)
    assert np.std(dg) == pytest.approx(np.sqrt(2) * sigma_g, rel=0.1)
    da = np.diff(noisy.accel_mps2 - clean.accel_mps2, axis=0)
    sigma_a = cfg.accel_noise_density * np.sqrt(cfg.imu_rate_hz)
    assert np.std(da) == pytest.approx(np.sqrt(2) * sigma_a, rel=0.1)


def test_camera_looks_at_orbit_centre():
    cfg = SimConfig()
    sc = scenario(2, 3)
    orbit = make_orbit(sc, np.zeros(3), np.random.default_rng(5), cfg)
    for t in (0.0, 3.0, 11.0):
        T = orbit.T_world_imu(t) @ cfg.T_imu_cam_matrix
        to_c = orbit.center - T[:3, 3]
        ang = np.degrees(np.arccos(to_c @ T[:3, 2] / np.linalg.norm(to_c)))
        assert ang < 3.0  # pointing error and mounting misalignment only
        assert np.linalg.norm(to_c) == pytest.approx(sc.range_m, rel=0.05)
        elev = np.degrees(np.arcsin(-to_c[2] / np.linalg.norm(to_c)))
        assert elev == pytest.approx(sc.obliquity_deg, abs=1.5)
