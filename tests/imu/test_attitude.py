import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from atr.errors import InputError
from atr.imu import attitude_angles, attitude_matrix, invert_pose, relative_camera_pose


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.normal(scale=50.0, size=3)
    return T


def test_pose_times_inverse_is_identity():
    rng = np.random.default_rng(1)
    for _ in range(20):
        T = _random_pose(rng)
        np.testing.assert_allclose(T @ invert_pose(T), np.eye(4), atol=1e-12)
        np.testing.assert_allclose(invert_pose(T), np.linalg.inv(T), atol=1e-12)


def test_relative_pose_of_identical_poses_is_identity():
    T = _random_pose(np.random.default_rng(2))
    np.testing.assert_allclose(relative_camera_pose(T, T), np.eye(4), atol=1e-12)


def test_relative_poses_compose_and_map_points_between_camera_frames():
    rng = np.random.default_rng(3)
    T0, T1, T2 = (_random_pose(rng) for _ in range(3))
    R10 = relative_camera_pose(T0, T1)
    R21 = relative_camera_pose(T1, T2)
    np.testing.assert_allclose(R21 @ R10, relative_camera_pose(T0, T2), atol=1e-9)
    # a world point seen from camera t maps to its coordinates in camera t+1
    X_world = np.array([3.0, -4.0, 10.0, 1.0])
    X_cam0 = np.linalg.inv(T0) @ X_world
    X_cam1 = np.linalg.inv(T1) @ X_world
    np.testing.assert_allclose(R10 @ X_cam0, X_cam1, atol=1e-9)


def test_eq3_is_the_zyx_matrix_with_u_about_z():
    # Eq. (3) as printed equals Rz(u) Ry(v) Rx(w) (scipy's intrinsic 'ZYX').
    rng = np.random.default_rng(4)
    for u, v, w in rng.uniform(-1.5, 1.5, size=(10, 3)):
        R_ref = Rotation.from_euler("ZYX", [u, v, w]).as_matrix()
        np.testing.assert_allclose(attitude_matrix(u, v, w), R_ref, atol=1e-12)
        np.testing.assert_allclose(attitude_angles(attitude_matrix(u, v, w)), (u, v, w), atol=1e-9)


def test_eq3_is_a_rotation():
    R = attitude_matrix(0.3, -0.7, 2.1)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_bad_pose_raises_naming_it():
    T = np.eye(4)
    T[0, 3] = np.nan
    with pytest.raises(InputError, match="T_world_cam_t"):
        relative_camera_pose(T, np.eye(4))
    with pytest.raises(InputError, match="shape"):
        relative_camera_pose(np.eye(3), np.eye(4))
