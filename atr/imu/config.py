"""Configuration of the pose integrator (paper §II-B-1, eqs. 1-4)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from atr.errors import ConfigError

_IDENTITY_4x4: tuple[tuple[float, ...], ...] = tuple(
    tuple(float(x) for x in row) for row in np.eye(4)
)

#: Tolerance on R^T R = I and on the bottom row of a configured extrinsic (a 4x4 parsed from text).
_RIGID_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ImuConfig:
    """How gyro and accelerometer samples become camera poses.

    Attributes:
        integration: "strapdown" (quaternion attitude from the gyro, specific force rotated to the
            world, gravity removed, velocity carried across frames) or "paper" (the literal eqs.
            (3)-(4) of §II-B-1: attitude angles integrated per axis and fed to eq. (3); translation
            = double integral of the body-frame acceleration between two frames from zero velocity,
            no gravity term).
        gravity_mps2: magnitude of gravity, m/s^2; the world frame is z up, so gravity is (0, 0,
            -g). Default: standard gravity (CGPM 1901), the paper gives no value.
        T_imu_cam: camera pose in the IMU frame (IMU-from-camera 4x4, metres), the camera-IMU
            extrinsic. Default identity: the paper puts the camera at the UAV's centre of gravity
            (§II-B-1, eq. 4).
        imu_rate_hz: nominal IMU sample rate, Hz, used only to size the gap check. Default 200 Hz,
            the ADIS16448 of the EuRoC MAV dataset (imu0/sensor.yaml); the paper does not state one.
        max_gap_samples: largest allowed spacing between consecutive samples, in nominal sample
            periods; a larger gap is a lost batch and raises InputError. Default 5 (25 ms at 200
            Hz): EuRoC's spacing varies by 1 us only, so 5 periods means samples were really lost.
        max_extrapolation_samples: how far past the last IMU sample a frame may be, in nominal
            sample periods (the last sample is held). Default 1: a camera and IMU on one clock
            differ by less than one IMU period; more would be a guess.

    """

    integration: Literal["strapdown", "paper"] = "strapdown"
    gravity_mps2: float = 9.80665
    T_imu_cam: tuple[tuple[float, ...], ...] = field(default=_IDENTITY_4x4)
    imu_rate_hz: float = 200.0
    max_gap_samples: int = 5
    max_extrapolation_samples: int = 1

    def __post_init__(self) -> None:
        if self.integration not in ("strapdown", "paper"):
            raise ConfigError(f"integration {self.integration!r} must be 'strapdown' or 'paper'")
        if not np.isfinite(self.gravity_mps2) or self.gravity_mps2 < 0.0:
            raise ConfigError(f"gravity_mps2 {self.gravity_mps2} must be finite and >= 0")
        if not np.isfinite(self.imu_rate_hz) or self.imu_rate_hz <= 0.0:
            raise ConfigError(f"imu_rate_hz {self.imu_rate_hz} must be finite and > 0")
        if int(self.max_gap_samples) != self.max_gap_samples or self.max_gap_samples < 1:
            raise ConfigError(f"max_gap_samples {self.max_gap_samples} must be an integer >= 1")
        if (
            int(self.max_extrapolation_samples) != self.max_extrapolation_samples
            or self.max_extrapolation_samples < 0
        ):
            raise ConfigError(
                f"max_extrapolation_samples {self.max_extrapolation_samples} must be an "
                "integer >= 0"
            )
        try:
            T = np.asarray(self.T_imu_cam, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ConfigError(
                f"T_imu_cam {self.T_imu_cam!r} is not a 4x4 matrix of numbers"
            ) from exc
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ConfigError(f"T_imu_cam must be a finite 4x4 matrix, got shape {T.shape}")
        R = T[:3, :3]
        if (
            np.abs(R.T @ R - np.eye(3)).max() > _RIGID_TOLERANCE
            or np.linalg.det(R) < 0.0
            or np.abs(T[3] - (0.0, 0.0, 0.0, 1.0)).max() > _RIGID_TOLERANCE
        ):
            raise ConfigError(
                f"T_imu_cam {T.tolist()} is not a rigid transform (rotation + translation)"
            )
        # Store as nested tuples so the frozen config stays hashable and comparable.
        object.__setattr__(self, "T_imu_cam", tuple(tuple(float(x) for x in row) for row in T))

    @property
    def T_imu_cam_matrix(self) -> np.ndarray:
        """IMU-from-camera extrinsic as a (4, 4) float64 array (a fresh copy)."""
        return np.array(self.T_imu_cam, dtype=np.float64)

    @property
    def gravity_world_mps2(self) -> np.ndarray:
        """Gravity vector in the world frame (z up), (3,) float64, m/s^2."""
        return np.array([0.0, 0.0, -self.gravity_mps2])

    @property
    def sample_period_ns(self) -> float:
        """Nominal IMU sample period, nanoseconds."""
        return 1e9 / self.imu_rate_hz
