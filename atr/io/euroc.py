"""Reader of an EuRoC MAV dataset folder (ASL format; Burri et al. 2016).

Reads what pose integration needs: imu0 samples, imu0 noise model, sensor extrinsics (T_BS) and the
ground-truth state (pose, velocity, biases) in the `groundtruth/<seq>.csv` layout
(`#time(ns),px,py,pz,qw,qx,qy,qz,vx,vy,vz,bwx,bwy,bwz,bax,bay,baz`, the pose of the body/IMU in the
world).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from atr.errors import InputError


@dataclass(frozen=True)
class EurocImu:
    """IMU samples: t_ns (N,) int64 ns; gyro_radps (N, 3) rad/s; accel_mps2 (N, 3) m/s^2."""

    t_ns: np.ndarray
    gyro_radps: np.ndarray
    accel_mps2: np.ndarray


@dataclass(frozen=True)
class EurocImuNoise:
    """Continuous-time noise model of imu0/sensor.yaml (Kalibr convention).

    Attributes:
        gyro_noise_density: rad/s/sqrt(Hz) (angle random walk).
        gyro_random_walk: rad/s^2/sqrt(Hz) (gyro bias diffusion).
        accel_noise_density: m/s^2/sqrt(Hz) (velocity random walk).
        accel_random_walk: m/s^3/sqrt(Hz) (accel bias diffusion).
        rate_hz: sample rate, Hz.
        T_body_imu: (4, 4) IMU pose in the body frame (T_BS).

    """

    gyro_noise_density: float
    gyro_random_walk: float
    accel_noise_density: float
    accel_random_walk: float
    rate_hz: float
    T_body_imu: np.ndarray


@dataclass(frozen=True)
class EurocGroundTruth:
    """Ground-truth states of the body (= IMU) in the world frame.

    Attributes:
        t_ns: (M,) int64 ns.
        p_world_m: (M, 3) metres.
        R_world_body: (M, 3, 3).
        v_world_mps: (M, 3) m/s.
        gyro_bias_radps: (M, 3) rad/s.
        accel_bias_mps2: (M, 3) m/s^2.

    """

    t_ns: np.ndarray
    p_world_m: np.ndarray
    R_world_body: np.ndarray
    v_world_mps: np.ndarray
    gyro_bias_radps: np.ndarray
    accel_bias_mps2: np.ndarray


def read_imu(root: Path) -> EurocImu:
    """Read `<root>/mav0/imu0/data.csv` (timestamp [ns], w_x,y,z [rad/s], a_x,y,z [m/s^2])."""
    path = Path(root) / "mav0" / "imu0" / "data.csv"
    t, data = _read_csv(path, 7)
    return EurocImu(t, data[:, 0:3].copy(), data[:, 3:6].copy())


def read_groundtruth(path: Path) -> EurocGroundTruth:
    """Read a ground-truth csv: time(ns), p, q (w, x, y, z), v, gyro bias, accel bias."""
    t, d = _read_csv(Path(path), 17)
    q_wxyz = d[:, 3:7]
    R = Rotation.from_quat(q_wxyz[:, [1, 2, 3, 0]]).as_matrix()
    return EurocGroundTruth(t, d[:, 0:3].copy(), R, d[:, 7:10].copy(), d[:, 10:13].copy(),
                            d[:, 13:16].copy())  # fmt: skip


def read_imu_noise(root: Path) -> EurocImuNoise:
    """Read `<root>/mav0/imu0/sensor.yaml`."""
    y = read_sensor_yaml(Path(root) / "mav0" / "imu0" / "sensor.yaml")
    try:
        return EurocImuNoise(
            float(y["gyroscope_noise_density"]),
            float(y["gyroscope_random_walk"]),
            float(y["accelerometer_noise_density"]),
            float(y["accelerometer_random_walk"]),
            float(y["rate_hz"]),
            _matrix(y["T_BS"]),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"imu0/sensor.yaml under {root} lacks a noise field: {exc}") from exc


def read_T_body_sensor(root: Path, sensor: str) -> np.ndarray:
    """T_BS (sensor pose in the body frame, 4x4) of `<root>/mav0/<sensor>/sensor.yaml`."""
    y = read_sensor_yaml(Path(root) / "mav0" / sensor / "sensor.yaml")
    if "T_BS" not in y:
        raise InputError(f"{sensor}/sensor.yaml has no T_BS")
    return _matrix(y["T_BS"])


def read_sensor_yaml(path: Path) -> dict:
    """Parse an EuRoC sensor.yaml (OpenCV-style, with a `%YAML:1.0` directive PyYAML rejects)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"EuRoC sensor file {path} does not exist")
    text = "\n".join(line for line in path.read_text().splitlines() if not line.startswith("%YAML"))
    y = yaml.safe_load(text)
    if not isinstance(y, dict):
        raise InputError(f"{path} is not a YAML mapping")
    return y


def _matrix(node: dict) -> np.ndarray:
    rows, cols = int(node["rows"]), int(node["cols"])
    m = np.asarray(node["data"], dtype=np.float64)
    if m.size != rows * cols:
        raise InputError(f"matrix of {rows}x{cols} has {m.size} values")
    return m.reshape(rows, cols)


def _read_csv(path: Path, ncols: int) -> tuple[np.ndarray, np.ndarray]:
    if not path.is_file():
        raise InputError(f"EuRoC file {path} does not exist")
    t = np.loadtxt(path, delimiter=",", comments="#", usecols=0, dtype=np.int64, ndmin=1)
    data = np.loadtxt(path, delimiter=",", comments="#", usecols=range(1, ncols),
                      dtype=np.float64, ndmin=2)  # fmt: skip
    if t.shape[0] == 0 or data.shape[1] < ncols - 1:
        raise InputError(f"{path} has no rows with {ncols} columns")
    if not np.all(np.isfinite(data)):
        raise InputError(f"{path} contains non-finite values")
    if np.any(np.diff(t) <= 0):
        i = int(np.argmax(np.diff(t) <= 0))
        raise InputError(f"{path}: timestamps not increasing at row {i + 1} ({int(t[i + 1])} ns)")
    return t, data
