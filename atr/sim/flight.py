"""A simulated flight: frames of camera image, IMU samples, optional LIDAR scan and truth.

Timing: frames come every `SimConfig.frame_interval_s(range)` seconds (0.25 s at 50 m, 0.5 s at 100
m, 1 s at 200 m: the baseline between consecutive frames is 7.5 % of the range, ~4.3 deg of
parallax). IMU samples come at 200 Hz on a grid that contains every frame time. stamp_ns = 1e9 + t x
1e9, with t the seconds since the first frame (sensor time of the simulated flight; the first frame
is at 1 s).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from atr.errors import ConfigError
from atr.sim.config import SimConfig
from atr.sim.noise import (
    NoiseSpec,
    noisy_cloud,
    noisy_image,
    parse_noise,
    with_navigation_errors,
)
from atr.sim.render import Renderer, to_srgb8
from atr.sim.scenarios import Scenario
from atr.sim.trajectory import Orbit
from atr.sim.world import World, build_world

STAMP0_NS = 1_000_000_000  # stamp of the first frame, ns (positive and clear of zero)


@dataclass
class TargetTruth:
    """A target vehicle in the world.

    Attributes:
        name: target name ("t72" unless a custom mesh replaced it).
        T_world_target: (4, 4) world-from-target pose (target frame: origin on the ground, x
        forward).
        visible_fraction: share of its camera-facing surface seen in this frame (0..1).

    """

    name: str
    T_world_target: np.ndarray
    visible_fraction: float


@dataclass
class SensorFrame:
    """Everything the sensors give at one frame, plus truth. Shapes and units in the field names."""

    seq: int
    stamp_ns: int
    image: np.ndarray  # (H, W, 3) uint8 RGB
    K: np.ndarray  # (3, 3) float64 intrinsics
    T_world_cam: np.ndarray  # (4, 4) true camera pose (OpenCV camera axes)
    imu_t_ns: np.ndarray  # (N,) int64 sample times in (previous frame, this frame]
    gyro_radps: np.ndarray  # (N, 3) float64, IMU frame
    accel_mps2: np.ndarray  # (N, 3) float64 specific force, IMU frame, gravity included
    T_world_imu: np.ndarray  # (4, 4) true IMU pose at stamp_ns
    v_world_imu_mps: np.ndarray  # (3,) true IMU velocity at stamp_ns
    lidar_points_m: np.ndarray | None  # (P, 3) float64 world frame, when lidar=True
    targets: list[TargetTruth] = field(default_factory=list)
    dist_coeffs: np.ndarray = field(default_factory=lambda: np.zeros(5))  # OpenCV lens distortion
    # what a navigation fix at this frame reports (sim.nav_*_sigma errors on the true state; None: the truth)
    nav_T_world_imu: np.ndarray | None = None  # (4, 4)
    nav_v_world_imu_mps: np.ndarray | None = None  # (3,)

    def nav_fix(self) -> tuple[np.ndarray, np.ndarray]:
        """The navigation fix at this frame: IMU pose (4, 4) and velocity (3,) m/s, as the UAV's GNSS/INS
        reports them.
        """
        if self.nav_T_world_imu is None or self.nav_v_world_imu_mps is None:
            return self.T_world_imu, self.v_world_imu_mps
        return self.nav_T_world_imu, self.nav_v_world_imu_mps


@dataclass(frozen=True)
class ImuSamples:
    """IMU samples of a whole run.

    Attributes:
        t_s: (N,) seconds since the first frame; gyro_radps (N, 3); accel_mps2 (N, 3), IMU frame.

    """

    t_s: np.ndarray
    gyro_radps: np.ndarray
    accel_mps2: np.ndarray


def imu_samples(
    orbit: Orbit, t_s: np.ndarray, cfg: SimConfig, rng: np.random.Generator | None
) -> ImuSamples:
    """Gyro and accelerometer readings at times t_s, from the analytic trajectory.

    Specific force f = R_world_imu^T (a_world - g_world), g_world = (0, 0, -g). With rng, adds the
    turn-on bias, the bias random walk and white noise (discrete-time: sigma_d = density x
    sqrt(rate)).
    """
    st = orbit.state(t_s)
    g = np.array([0.0, 0.0, -cfg.gravity_mps2])
    accel = np.einsum("nji,nj->ni", st.R_world_imu, st.a_world - g)
    gyro = st.omega_imu.copy()
    if rng is not None:
        n = t_s.size
        dt = 1.0 / cfg.imu_rate_hz
        bg = rng.normal(0, cfg.gyro_bias_sigma_radps, 3) + np.cumsum(
            rng.normal(0, cfg.gyro_random_walk * np.sqrt(dt), (n, 3)), axis=0
        )
        ba = rng.normal(0, cfg.accel_bias_sigma_mps2, 3) + np.cumsum(
            rng.normal(0, cfg.accel_random_walk * np.sqrt(dt), (n, 3)), axis=0
        )
        gyro = gyro + bg + rng.normal(0, cfg.gyro_noise_density / np.sqrt(dt), (n, 3))
        accel = accel + ba + rng.normal(0, cfg.accel_noise_density / np.sqrt(dt), (n, 3))
    return ImuSamples(np.asarray(t_s, dtype=np.float64), gyro, accel)


def nav_fix_errors(
    n_frames: int, frame_interval_s: float, cfg: SimConfig, rng: np.random.Generator
) -> np.ndarray:
    """The navigation fix's errors at every frame, (n_frames, 9): position (3) m, velocity (3) m/s and a
    small rotation (3) rad about the world's x, y, z (tilt, tilt, heading).

    Each is a first-order Gauss-Markov process with the configured std and ``nav_error_correlation_s``:
    stationary from the first frame, so the errors wander along the flight as a GNSS/INS's do.
    """
    sigma = np.array(
        [cfg.nav_position_sigma_m] * 2
        + [cfg.nav_altitude_sigma_m]
        + [cfg.nav_velocity_sigma_mps] * 3
        + list(np.radians([cfg.nav_tilt_sigma_deg] * 2 + [cfg.nav_heading_sigma_deg]))
    )
    a = np.exp(-frame_interval_s / cfg.nav_error_correlation_s)
    white = rng.normal(0.0, 1.0, (n_frames, 9))
    errors = np.empty((n_frames, 9))
    errors[0] = sigma * white[0]
    for k in range(1, n_frames):
        errors[k] = a * errors[k - 1] + np.sqrt(1.0 - a * a) * sigma * white[k]
    return errors


def _with_error(
    T_world_imu: np.ndarray, v_world_imu: np.ndarray, error: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A true pose and velocity with one frame's navigation errors (``nav_fix_errors``) applied."""
    T = T_world_imu.copy()
    T[:3, :3] = Rotation.from_rotvec(error[6:9]).as_matrix() @ T_world_imu[:3, :3]
    T[:3, 3] = T_world_imu[:3, 3] + error[0:3]
    return T, v_world_imu + error[3:6]


def true_imu_pose(orbit: Orbit, t_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The true IMU pose T_world_imu (4, 4) and velocity v_world_imu (3,), m/s, t_s seconds into the run."""
    st = orbit.state(np.array([t_s]))
    T_world_imu = np.eye(4)
    T_world_imu[:3, :3] = st.R_world_imu[0]
    T_world_imu[:3, 3] = st.p_world[0]
    return T_world_imu, st.v_world[0]


class FlightSimulator:
    """The sensors of one scenario run over a built world, frame by frame.

    The whole run's IMU samples are drawn at construction, so that neither the number of frames nor which
    frames are rendered changes any value; each frame's image and LIDAR noise come from generators seeded
    by (seed, scenario, run, sensor, frame).
    """

    def __init__(
        self,
        scenario: Scenario,
        world: World,
        config: SimConfig,
        *,
        seed: int,
        frames: int | None = None,
        imu_noise: bool = True,
    ) -> None:
        """Draw the run's IMU samples.

        Args:
            scenario: the run (Table II preset from `scenario()` or a custom one).
            world: the world built for this scenario and seed (`build_world`).
            config: simulator settings.
            seed: noise seed (the world's seed in `simulate_flight`).
            frames: the flight stops after this many frames (default: the run's n_frames).
            imu_noise: add IMU bias, bias random walk and white noise (False: exact readings).

        Raises:
            ConfigError: frames < 1.

        """
        if frames is not None and frames < 1:
            raise ConfigError(f"frames {frames} must be >= 1")
        self.n_frames = scenario.n_frames if frames is None else int(frames)
        """Frames of the flight."""
        self._scenario, self._world, self._cfg = scenario, world, config
        self._renderer = Renderer(world, config)
        self._per_frame = int(round(config.frame_interval_s(scenario.range_m) * config.imu_rate_hz))
        # the whole run's IMU noise is drawn up front so that `frames` does not change any value
        n_imu = (scenario.n_frames - 1) * self._per_frame + 1
        t_imu = (
            np.arange(max(n_imu, (self.n_frames - 1) * self._per_frame + 1)) / config.imu_rate_hz
        )
        # generator seeds: stream + [tag, ...] (1: IMU, 2: image noise, 3: LIDAR, 4: navigation fix)
        self._stream = [seed, scenario.scenario, scenario.run]
        imu_rng = np.random.default_rng(self._stream + [1]) if imu_noise else None
        self._imu = imu_samples(world.orbit, t_imu, config, imu_rng)
        self._nav_errors = None
        if config.nav_fix_noisy:  # its own generator: the other streams keep their values
            self._nav_errors = nav_fix_errors(
                max(scenario.n_frames, self.n_frames),
                self._per_frame / config.imu_rate_hz,
                config,
                np.random.default_rng(self._stream + [4]),
            )
        self._T_imu_cam = config.T_imu_cam_matrix
        self._K = config.K

    def frame(
        self,
        seq: int,
        *,
        lidar: bool = False,
        noise: NoiseSpec = NoiseSpec(),
        rendered: bool = True,
    ) -> SensorFrame:
        """Frame seq of the flight.

        Args:
            seq: frame index, 0 .. n_frames - 1.
            lidar: also scan the scene with the LIDAR.
            noise: image and LIDAR noise (atr.sim.noise).
            rendered: False gives an empty (0, 0, 3) image and no LIDAR scan, only the frame's IMU
                samples and truth (an evaluation that samples scenes still integrates every IMU batch).

        """
        k1 = seq * self._per_frame
        k0 = 0 if seq == 0 else (seq - 1) * self._per_frame + 1
        t = k1 / self._cfg.imu_rate_hz
        T_world_imu, v_world_imu = true_imu_pose(self._world.orbit, t)
        T_world_cam = T_world_imu @ self._T_imu_cam
        image = np.zeros((0, 0, 3), np.uint8)
        if rendered:
            image = self._image(seq, T_world_cam, noise)
        cloud = None
        if lidar and rendered:
            cloud = self._lidar_scan(seq, T_world_cam, noise)
        truth = [
            TargetTruth(
                self._world.target_name,
                self._world.T_world_target.copy(),
                self._renderer.visible_fraction(T_world_cam),
            )
        ]
        imu = self._imu
        nav_T, nav_v = None, None
        if self._nav_errors is not None:
            nav_T, nav_v = _with_error(T_world_imu, v_world_imu, self._nav_errors[seq])
        return SensorFrame(
            seq=seq,
            stamp_ns=STAMP0_NS + int(round(t * 1e9)),
            image=image,
            K=self._K.copy(),
            T_world_cam=T_world_cam,
            imu_t_ns=STAMP0_NS + np.round(imu.t_s[k0 : k1 + 1] * 1e9).astype(np.int64),
            gyro_radps=imu.gyro_radps[k0 : k1 + 1].copy(),
            accel_mps2=imu.accel_mps2[k0 : k1 + 1].copy(),
            T_world_imu=T_world_imu,
            v_world_imu_mps=v_world_imu.copy(),
            lidar_points_m=cloud,
            targets=truth,
            dist_coeffs=np.asarray(self._cfg.dist_coeffs, dtype=np.float64),
            nav_T_world_imu=nav_T,
            nav_v_world_imu_mps=nav_v,
        )

    def _image(self, seq: int, T_world_cam: np.ndarray, noise: NoiseSpec) -> np.ndarray:
        lin, _ = self._renderer.render(T_world_cam)
        image = to_srgb8(lin)
        if noise.active:
            rng = np.random.default_rng(self._stream + [2, seq])
            image = noisy_image(lin, image, noise, self._cfg.shot_noise_full_well, rng)
        return image

    def _lidar_scan(self, seq: int, T_world_cam: np.ndarray, noise: NoiseSpec) -> np.ndarray:
        rng = np.random.default_rng(self._stream + [3, seq])
        sc = self._scenario
        cloud = self._renderer.lidar_scan(T_world_cam, sc.lidar_resolution_m, sc.range_m, rng)
        if noise.active:
            cloud = noisy_cloud(
                cloud, T_world_cam[:3, 3], noise, self._cfg.lidar_shot_quantum_m, rng
            )
        return cloud


def simulate_flight(
    scenario: Scenario,
    *,
    seed: int = 0,
    frames: int | None = None,
    lidar: bool = False,
    noise: str | None = None,
    config: SimConfig | None = None,
    world: World | None = None,
) -> Iterator[SensorFrame]:
    """Fly one scenario run and yield its frames in order.

    Args:
        scenario: the run (Table II preset from `scenario()` or a custom one).
        seed: world and noise seed; the same arguments give byte-identical frames.
        frames: stop after this many frames (default: the run's n_frames = n_scenes + 1).
        lidar: also produce a LIDAR scan per frame.
        noise: noise spec ("shot", "gaussian:10", "gaussian:30", "shot,gaussian:10"; see
            atr.sim.noise).
        config: simulator settings.
        world: the world to fly over (default: `build_world(scenario, seed)`, the T-72 and no
            confusers); a custom target or confusers come in through `build_world`'s arguments.

    Yields:
        SensorFrame per frame (`FlightSimulator.frame`, every frame rendered, the IMU noisy).

    Raises:
        ConfigError: frames < 1, or a bad noise spec.

    """
    cfg = config or SimConfig()
    if frames is not None and frames < 1:
        raise ConfigError(f"frames {frames} must be >= 1")
    spec = parse_noise(noise)
    if world is None:
        world = build_world(scenario, seed, config=cfg)
    sim = FlightSimulator(
        scenario, world, with_navigation_errors(cfg, spec), seed=seed, frames=frames
    )
    for seq in range(sim.n_frames):
        yield sim.frame(seq, lidar=lidar, noise=spec)
