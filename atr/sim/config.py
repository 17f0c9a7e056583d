"""Simulator parameters: camera, platform, IMU, LIDAR, lighting and noise.

Every field has its units and where its value comes from. The paper (Kechagias-Stamatis & Aouf) does
not give its OpenFlight camera or IMU; values it does give are cited by section, the others are
chosen and explained in docs/sim.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from atr.errors import ConfigError

# Camera axes (OpenCV: x right, y down, z forward) expressed in the IMU body frame (x forward along
# the optical axis, y left, z up): columns are the camera's x, y, z axes.
_R_IMU_CAM_NOMINAL = ((0.0, 0.0, 1.0), (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0))


def _default_T_imu_cam() -> tuple[tuple[float, ...], ...]:
    # Nominal axis swap plus a small mounting misalignment (0.2 deg about each axis) and a 4 cm
    # lever arm: an integrator that forgets the extrinsic shows it.
    a = np.deg2rad(0.2)
    c, s = np.cos(a), np.sin(a)
    Rx = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    T = np.eye(4)
    T[:3, :3] = Rz @ Ry @ Rx @ np.array(_R_IMU_CAM_NOMINAL)
    T[:3, 3] = (0.04, 0.0, -0.02)
    return tuple(tuple(float(x) for x in row) for row in T)


_NAV_SIGMA_FIELDS = (
    "nav_position_sigma_m",
    "nav_altitude_sigma_m",
    "nav_velocity_sigma_mps",
    "nav_tilt_sigma_deg",
    "nav_heading_sigma_deg",
)


@dataclass(frozen=True)
class SimConfig:
    """All simulator settings. Defaults reproduce the documented set-up (docs/sim.md)."""

    # --- camera (pinhole, RGB8) -----------------------------------------------------------------
    width_px: int = 1280  # image width, pixels (issue: 1280x960 default)
    height_px: int = 960  # image height, pixels
    # focal length, pixels: a 6.9 m T-72 hull spans 69 px at 200 m (>= 50 px)
    focal_px: float = 2000.0
    # lens distortion, OpenCV order (k1, k2, p1, p2, k3); zeros: an ideal pinhole (the default)
    dist_coeffs: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    # --- platform ---------------------------------------------------------------------------------
    speed_mps: float = 15.0  # ground speed on the orbit, m/s (small UAV, 10-20 m/s)
    # frame interval x speed / range: ~4.3 deg of parallax per frame pair
    baseline_to_range: float = 0.075
    # lowest camera height above the target's ground (makes 0 deg obliquity flyable)
    min_altitude_m: float = 4.0
    # amplitude of gust-driven position wander, metres (per axis)
    position_disturbance_m: float = 0.6
    roll_disturbance_deg: float = 2.5  # amplitude of camera-head roll wobble, degrees
    pointing_bias_deg: float = 0.6  # std of the constant gimbal pointing error per run, degrees
    pointing_jitter_deg: float = 0.25  # amplitude of the slow gimbal pointing wobble, degrees
    # std of orbit-centre offset from the target, as a fraction of range
    aim_offset_frac: float = 0.03
    # --- IMU on the camera head (defaults: ADIS16448, EuRoC sensor.yaml) --------------------------
    imu_rate_hz: float = 200.0  # sample rate, Hz (EuRoC imu0 rate_hz)
    gyro_noise_density: float = 1.6968e-04  # rad/s/sqrt(Hz) (EuRoC imu0 gyroscope_noise_density)
    gyro_random_walk: float = 1.9393e-05  # rad/s^2/sqrt(Hz) (EuRoC imu0 gyroscope_random_walk)
    accel_noise_density: float = 2.0e-3  # m/s^2/sqrt(Hz) (EuRoC imu0 accelerometer_noise_density)
    accel_random_walk: float = 3.0e-3  # m/s^3/sqrt(Hz) (EuRoC imu0 accelerometer_random_walk)
    # turn-on bias std, rad/s (ADIS16448 in-run stability 14.5 deg/h)
    gyro_bias_sigma_radps: float = 7.0e-5
    # turn-on bias std, m/s^2 (ADIS16448 in-run stability 0.25 mg)
    accel_bias_sigma_mps2: float = 2.5e-3
    # magnitude of gravity, m/s^2, world -z (standard gravity, CGPM 1901)
    gravity_mps2: float = 9.80665
    T_imu_cam: tuple[tuple[float, ...], ...] = field(default_factory=_default_T_imu_cam)
    """IMU-from-camera 4x4: the camera's pose in the IMU frame (rigid, both on the gimbal head)."""
    # --- LIDAR (baseline sensor, paper Table II) --------------------------------------------------
    # returns per scan line and lines per scan: 512^2 = 262k points (paper: ~260k)
    lidar_grid: int = 512
    # full-angle beam divergence, mrad: 7.5 cm spot at 50 m, 30 cm at 200 m
    lidar_divergence_mrad: float = 1.5
    lidar_aperture_m: float = 0.02  # spot diameter at the exit aperture, metres
    lidar_sub_rays: int = 7  # sub-rays averaged per return over the spot footprint (mixed pixels)
    lidar_range_noise_m: float = 0.02  # 1-sigma range noise, metres
    lidar_max_range_m: float = 1500.0  # no return beyond, metres
    # shot noise: range = q * Poisson(range / q), metres (§III-D-6)
    lidar_shot_quantum_m: float = 1e-3
    # --- lighting and atmosphere ------------------------------------------------------------------
    # range the world's sun elevation is drawn from
    sun_elevation_deg: tuple[float, float] = (35.0, 60.0)
    haze_visibility_m: float | None = 8000.0  # meteorological visibility, metres (None: no haze)
    exposure: float = 1.7  # linear radiance to [0, 1] scale before the sRGB curve
    # photo-electrons at full scale (Poisson shot noise, §III-D-6)
    shot_noise_full_well: float = 600.0
    # --- truth ------------------------------------------------------------------------------------
    target_samples: int = 1200  # surface samples used for visible_fraction
    # a frame 'has the target' at or above this visible fraction
    present_min_visible_fraction: float = 0.1
    # Navigation: False = the UAV's INS is aligned once before take-off (the first ImuBatch's `init`) and the
    # pose integrator dead-reckons from there; True = an aided navigation fix (e.g. GNSS/INS) comes with every
    # frame, so each pair's relative motion is integrated from a correct state over one frame interval only
    # (the paper's premise: the IMU measures the camera motion between the two frames).
    nav_fix_every_frame: bool = False
    # Errors of the navigation fix (the INS alignment and, with nav_fix_every_frame, every aided fix), each a
    # first-order Gauss-Markov process along the flight with this correlation time: a GNSS/INS's errors
    # wander slowly rather than jump from fix to fix. Zeros (the default): the fix is the true state.
    nav_position_sigma_m: float = 0.0  # std per horizontal axis, metres
    nav_altitude_sigma_m: float = 0.0  # std of the height, metres
    nav_velocity_sigma_mps: float = 0.0  # std per axis, m/s
    nav_tilt_sigma_deg: float = 0.0  # std of roll and of pitch (about the world's x and y), degrees
    nav_heading_sigma_deg: float = 0.0  # std of heading (about the world's z), degrees
    nav_error_correlation_s: float = 60.0  # correlation time of every error above, seconds

    def __post_init__(self) -> None:
        for name in ("width_px", "height_px", "lidar_grid", "lidar_sub_rays", "target_samples"):
            if getattr(self, name) <= 0:
                raise ConfigError(f"{name} {getattr(self, name)} must be > 0")
        for name in (
            "focal_px",
            "speed_mps",
            "baseline_to_range",
            "imu_rate_hz",
            "gravity_mps2",
            "exposure",
            "shot_noise_full_well",
            "lidar_max_range_m",
            "lidar_shot_quantum_m",
        ):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} {getattr(self, name)} must be > 0")
        for name in _NAV_SIGMA_FIELDS:
            if not 0.0 <= getattr(self, name) < np.inf:
                raise ConfigError(f"{name} {getattr(self, name)} must be a finite number >= 0")
        if not 0.0 < self.nav_error_correlation_s < np.inf:
            raise ConfigError(
                f"nav_error_correlation_s {self.nav_error_correlation_s} must be a finite number > 0"
            )
        if self.haze_visibility_m is not None and self.haze_visibility_m <= 0:
            raise ConfigError(f"haze_visibility_m {self.haze_visibility_m} must be > 0 or None")
        if len(self.dist_coeffs) not in (4, 5, 8) or not np.all(np.isfinite(self.dist_coeffs)):
            raise ConfigError(
                f"dist_coeffs {self.dist_coeffs} must be 4, 5 or 8 finite numbers "
                "(OpenCV order k1, k2, p1, p2[, k3[, k4, k5, k6]])"
            )
        T = np.asarray(self.T_imu_cam, dtype=np.float64)
        if T.shape != (4, 4) or not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9):
            raise ConfigError("T_imu_cam must be a 4x4 rigid transform")
        if not 0.0 <= self.present_min_visible_fraction <= 1.0:
            raise ConfigError(
                f"present_min_visible_fraction {self.present_min_visible_fraction} "
                "must be in [0, 1]"
            )

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float64 pinhole intrinsics, principal point at the image centre."""
        return np.array(
            [
                [self.focal_px, 0.0, (self.width_px - 1) / 2.0],
                [0.0, self.focal_px, (self.height_px - 1) / 2.0],
                [0.0, 0.0, 1.0],
            ]
        )

    @property
    def T_imu_cam_matrix(self) -> np.ndarray:
        """IMU-from-camera as a (4, 4) float64 array."""
        return np.array(self.T_imu_cam, dtype=np.float64)

    @property
    def nav_fix_noisy(self) -> bool:
        """The navigation fix has errors (any nav_*_sigma above 0)."""
        return any(getattr(self, n) > 0.0 for n in _NAV_SIGMA_FIELDS)

    def frame_interval_s(self, range_m: float) -> float:
        """Frame interval for a UAV-target range: baseline = baseline_to_range x range, seconds.

        Rounded to whole IMU samples so frame times coincide with IMU sample times.
        """
        dt = self.baseline_to_range * range_m / self.speed_mps
        n = max(1, round(dt * self.imu_rate_hz))
        return n / self.imu_rate_hz
