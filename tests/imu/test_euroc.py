"""Against REAL data: EuRoC MAV V1_01_easy (ADIS16448 IMU at 200 Hz, Vicon-based ground truth).

Windows of 0.05 s, 0.5 s and 1 s start from the ground-truth state and biases at ~490 instants of
the flight; the integrated pose at the window's end is compared with the ground truth's. The allowed
error is derived in atr.imu.evaluate.error_bound from the IMU's noise densities (imu0/sensor.yaml)
plus the ground truth's own errors measured at rest (docs/imu.md); we allow the median 1.5x and the
worst window 4x that one-sigma-scale figure.
"""

from pathlib import Path

import numpy as np
import pytest

from atr.imu import ImuConfig
from atr.imu.evaluate import error_bound, ground_truth_errors, window_errors
from atr.io.euroc import read_groundtruth, read_imu, read_imu_noise, read_T_body_sensor

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"
EUROC = SHARED / "data" / "euroc_v1_01_easy_micro"
pytestmark = pytest.mark.skipif(
    not (EUROC / "mav0" / "imu0" / "data.csv").is_file(),
    reason=f"EuRoC V1_01_easy micro set not found at {EUROC} (shared data folder absent)",
)
WINDOWS_S = (0.05, 0.5, 1.0)
MEDIAN_FACTOR, MAX_FACTOR = 1.5, 4.0
IN_FLIGHT_MPS = 0.2  # windows start where the ground-truth speed exceeds this
STATIC_DISPLACEMENT_M = 0.005  # the first rows within this of the start are "at rest" (SOURCE.md)


@pytest.fixture(scope="module")
def euroc():
    imu = read_imu(EUROC)
    gt = read_groundtruth(EUROC / "groundtruth" / "V1_01_easy.csv")
    noise = read_imu_noise(EUROC)
    moved = np.linalg.norm(gt.p_world_m - gt.p_world_m[0], axis=1) > STATIC_DISPLACEMENT_M
    static_until_ns = int(gt.t_ns[int(np.argmax(moved)) - 1])
    gt_err = ground_truth_errors(imu, gt, static_until_ns)
    speed = np.linalg.norm(gt.v_world_mps, axis=1)
    starts = np.nonzero(speed > IN_FLIGHT_MPS)[0][::5]
    return (imu, gt), noise, gt_err, starts


def test_reader_gives_the_documented_stream():
    imu = read_imu(EUROC)
    assert imu.t_ns.dtype == np.int64 and imu.gyro_radps.shape == (29120, 3)
    assert np.median(np.diff(imu.t_ns)) == pytest.approx(5e6, rel=1e-3)  # 200 Hz
    # at the start the vehicle sits still: |specific force| is gravity
    assert np.linalg.norm(imu.accel_mps2[:100].mean(axis=0)) == pytest.approx(9.81, abs=0.05)
    noise = read_imu_noise(EUROC)
    assert noise.gyro_noise_density == pytest.approx(1.6968e-04)
    assert noise.accel_noise_density == pytest.approx(2.0e-3)
    np.testing.assert_allclose(noise.T_body_imu, np.eye(4))
    T_body_cam = read_T_body_sensor(EUROC, "cam0")
    np.testing.assert_allclose(T_body_cam[:3, :3].T @ T_body_cam[:3, :3], np.eye(3), atol=1e-6)


def test_ground_truth_own_errors_are_small(euroc):
    _, _, gt_err, _ = euroc
    assert gt_err.world_tilt_rad < np.radians(1.0)
    assert gt_err.gyro_bias_error_radps < 0.01
    assert gt_err.velocity_error_mps < 0.05


@pytest.mark.parametrize("window_s", WINDOWS_S)
def test_strapdown_errors_stay_within_noise_prediction(euroc, window_s):
    (imu, gt), noise, gt_err, starts = euroc
    cfg = ImuConfig()
    e = window_errors(imu, gt, starts, window_s, config=cfg)
    assert len(e.start_ns) > 400
    rot_bound, trans_bound = error_bound(
        window_s, noise.gyro_noise_density, noise.accel_noise_density, gt_err, cfg.gravity_mps2
    )
    assert np.median(e.rotation_error_rad) <= MEDIAN_FACTOR * rot_bound
    assert e.rotation_error_rad.max() <= MAX_FACTOR * rot_bound
    assert np.median(e.translation_error_m) <= MEDIAN_FACTOR * trans_bound
    assert e.translation_error_m.max() <= MAX_FACTOR * trans_bound


@pytest.mark.parametrize("window_s", (0.5, 1.0))
def test_literal_paper_eq4_is_far_outside_the_prediction(euroc, window_s):
    (imu, gt), noise, gt_err, starts = euroc
    cfg = ImuConfig(integration="paper")
    e = window_errors(imu, gt, starts, window_s, config=cfg)
    _, trans_bound = error_bound(
        window_s, noise.gyro_noise_density, noise.accel_noise_density, gt_err, cfg.gravity_mps2
    )
    # gravity integrated twice: ~ g T^2 / 2
    assert np.median(e.translation_error_m) > 10.0 * MAX_FACTOR * trans_bound
    assert np.median(e.translation_error_m) == pytest.approx(0.5 * 9.81 * window_s**2, rel=0.2)
