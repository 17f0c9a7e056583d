import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from atr.errors import ConfigError, InputError
from atr.imu import ImuConfig, NavState, PoseIntegrator, integrate

G = 9.80665
PERIOD_NS = 5_000_000  # 200 Hz


def _at_rest_batch(n: int, start_ns: int = PERIOD_NS):
    t = start_ns + np.arange(n, dtype=np.int64) * PERIOD_NS
    return t, np.zeros((n, 3)), np.tile([0.0, 0.0, G], (n, 1))


def test_constant_rate_reproduces_closed_form_rotation():
    omega = np.array([0.3, -0.5, 0.8])  # rad/s, body frame
    n = 400
    t = np.arange(1, n + 1, dtype=np.int64) * PERIOD_NS
    s = NavState.at_rest(0)
    cfg = ImuConfig(gravity_mps2=0.0)
    out = integrate(s, t, np.tile(omega, (n, 1)), np.zeros((n, 3)), config=cfg)
    R_ref = Rotation.from_rotvec(omega * t[-1] / 1e9).as_matrix()
    err = Rotation.from_matrix(R_ref.T @ out.R_world_imu).magnitude()
    assert err < 1e-10


def test_at_rest_stays_put_and_gravity_is_removed():
    t, g, a = _at_rest_batch(200)
    out = integrate(NavState.at_rest(0), t, g, a, config=ImuConfig())
    assert np.abs(out.p_world_m).max() < 1e-12
    assert np.abs(out.v_world_mps).max() < 1e-12


def test_paper_mode_integrates_gravity_at_rest():
    # Literal eq. (4) has no gravity term: at rest it "falls upward" by g T^2 / 2.
    t, g, a = _at_rest_batch(200)
    out = integrate(NavState.at_rest(0), t, g, a, config=ImuConfig(integration="paper"))
    T = t[-1] / 1e9
    assert out.p_world_m[2] == pytest.approx(0.5 * G * T**2, rel=1e-9)


def test_constant_world_acceleration_with_initial_velocity():
    accel_world = np.array([0.5, -0.2, 0.1])
    v0 = np.array([2.0, 1.0, 0.0])
    R = Rotation.from_euler("xyz", [0.2, -0.4, 1.0]).as_matrix()
    f_body = R.T @ (accel_world + [0.0, 0.0, G])
    n = 400
    t = np.arange(1, n + 1, dtype=np.int64) * PERIOD_NS
    s = NavState(0, R, np.zeros(3), v0, np.zeros(3), np.zeros(3))
    out = integrate(s, t, np.zeros((n, 3)), np.tile(f_body, (n, 1)), config=ImuConfig())
    T = 2.0
    np.testing.assert_allclose(out.p_world_m, v0 * T + 0.5 * accel_world * T**2, atol=1e-9)
    np.testing.assert_allclose(out.v_world_mps, v0 + accel_world * T, atol=1e-9)


def test_biases_are_subtracted():
    bg = np.array([0.01, -0.02, 0.03])
    ba = np.array([0.1, 0.2, -0.3])
    t, g, a = _at_rest_batch(100)
    s = NavState(0, np.eye(3), np.zeros(3), np.zeros(3), bg, ba)
    out = integrate(s, t, g + bg, a + ba, config=ImuConfig())
    np.testing.assert_allclose(out.R_world_imu, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(out.p_world_m, 0.0, atol=1e-12)


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda t, g, a: (t[::-1].copy(), g, a), "strictly increasing"),
        (
            lambda t, g, a: (t, np.where(np.arange(10)[:, None] == 4, np.nan, g), a),
            r"gyro_radps\[4\]",
        ),
        (lambda t, g, a: (t, g, a[:, :2]), "accel_mps2 must have shape"),
        (lambda t, g, a: (np.concatenate((t[:5], t[5:] + 100 * PERIOD_NS)), g, a), "gap"),
        (lambda t, g, a: (t[:0], g[:0], a[:0]), "non-empty"),
        (lambda t, g, a: (t.astype(float), g, a), "integer"),
    ],
)
def test_bad_batches_raise_input_error(mutate, match):
    t, g, a = mutate(*_at_rest_batch(10))
    with pytest.raises(InputError, match=match):
        integrate(NavState.at_rest(0), t, g, a, config=ImuConfig())
    with pytest.raises(InputError, match=match):
        PoseIntegrator(ImuConfig(), NavState.at_rest(0)).add_imu(t, g, a)


def test_sample_before_state_raises():
    t, g, a = _at_rest_batch(10)
    with pytest.raises(InputError, match="before the state"):
        integrate(NavState.at_rest(int(t[3])), t, g, a, config=ImuConfig())


def test_pose_integrator_frame_errors_name_the_stamp():
    pi = PoseIntegrator(ImuConfig(), NavState.at_rest(0))
    with pytest.raises(InputError, match="123 ns is before the first IMU sample"):
        pi.camera_pose(123)
    t, g, a = _at_rest_batch(10, start_ns=1000)
    pi.add_imu(t, g, a)
    with pytest.raises(InputError, match="999 ns is before the first IMU sample"):
        pi.camera_pose(999)
    with pytest.raises(InputError, match="after the last IMU sample"):
        pi.camera_pose(int(t[-1]) + 3 * PERIOD_NS)
    pi.camera_pose(int(t[5]))
    with pytest.raises(InputError, match="frames must come in time order"):
        pi.camera_pose(int(t[2]))
    with pytest.raises(InputError, match="not after the previous batch"):
        pi.add_imu(t, g, a)


def test_pose_integrator_applies_extrinsic():
    T_imu_cam = np.eye(4)
    T_imu_cam[:3, :3] = Rotation.from_euler("x", -90, degrees=True).as_matrix()
    T_imu_cam[:3, 3] = [0.1, 0.0, -0.05]
    pi = PoseIntegrator(ImuConfig(T_imu_cam=T_imu_cam), NavState.at_rest(0))
    pi.add_imu(*_at_rest_batch(20))
    np.testing.assert_allclose(pi.camera_pose(50 * 1_000_000), T_imu_cam, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"integration": "euler"},
        {"gravity_mps2": -1.0},
        {"imu_rate_hz": 0.0},
        {"max_gap_samples": 0},
        {"T_imu_cam": np.diag([1.0, 1.0, -1.0, 1.0])},
        {"T_imu_cam": np.eye(3)},
    ],
)
def test_config_rejects_bad_values(kwargs):
    with pytest.raises(ConfigError):
        ImuConfig(**kwargs)


@pytest.mark.parametrize("integration", ["strapdown", "paper"])
def test_warm_up_loads_the_kernel_the_configuration_integrates_with(integration: str) -> None:
    """In a fresh process (this one may have run either kernel): warm_up loads the configured kernel
    only, at the argument types a pose's integration calls it with, so the first frame loads nothing."""
    code = f"""
import numpy as np
from atr.imu import ImuConfig, NavState, PoseIntegrator, warm_up
from atr.imu._kernels import paper_kernel, strapdown_kernel
config = ImuConfig(integration={integration!r})
warm_up(config)
print(len(strapdown_kernel.signatures), len(paper_kernel.signatures))
pi = PoseIntegrator(config, NavState.at_rest(0))
t_ns = np.arange(1, 40, dtype=np.int64) * int(config.sample_period_ns)
pi.add_imu(t_ns, np.full((39, 3), 0.01), np.tile([0.1, 0.0, 9.81], (39, 1)))
pi.camera_pose(int(t_ns[-1]))
print(len(strapdown_kernel.signatures), len(paper_kernel.signatures))
"""
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    ).stdout.split()
    loaded = ["1", "0"] if integration == "strapdown" else ["0", "1"]
    assert out == loaded + loaded  # and a frame's pose compiled no other signature
