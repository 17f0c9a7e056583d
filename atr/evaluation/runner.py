"""In-process evaluation of one simulated flight: the services' computations, without the bus.

Each frame goes through the same functions, in the same order, with the same seeds as the service graph
(services/pose_integrator, services/sfm, services/atr_matcher), so the detections are identical to a lock-step
`atr run` of the same recording (tests/evaluation/test_services_identity.py proves it on a short flight):
- the pose integrator starts from the first frame's true navigation state (ImuBatch.init) and integrates the
  noisy IMU samples; SfM triangulates the pair (k - gap, k) with those integrated poses;
- the matcher sees the cloud as it crosses the bus (float32 points) and seeds RANSAC with the cloud's seq,
  which is the frame index k (sfm publishes one cloud per frame; the LIDAR scan's seq is its frame index);
- the LIDAR baseline is the same matcher on the frame's LIDAR scan, oriented from the true sensor position.
The 2D baseline (atr.baselines2d) runs on the frame's image with the known (true) camera pose.

A scene is a frame k >= gap (a frame that has an SfM partner); every pipeline is scored on the same scenes.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from atr.baselines2d import Baseline2dConfig, Template2d, recognize_2d
from atr.baselines2d.config import PAIRS
from atr.config import AtrConfig, apply_overrides
from atr.errors import AtrError, ConfigError, InputError
from atr.imu import NavState
from atr.imu.pose_track import FramePose, PoseTrack
from atr.recognition import DESCRIPTORS, Template
from atr.regions import SearchRegion, regions_to_array
from atr.sfm import reconstruct
from atr.sfm.pairing import FramePairer, Pair
from atr.sim.config import SimConfig
from atr.sim.flight import FlightSimulator, SensorFrame
from atr.sim.noise import parse_noise, with_navigation_errors
from atr.sim.scenarios import scenario as scenario_preset
from atr.sim.world import World, build_world
from atr.tracking.guided_search import GuidedSearch

SFM_PIPELINES: dict[str, str] = {"gftt-sfm": "gftt", "surf-sfm": "surf", "sgm-sfm": "sgm"}
"""SfM pipelines and their `sfm.matcher`."""

PIPELINES: tuple[str, ...] = ("gftt-sfm", "surf-sfm", "sgm-sfm", "lidar", *PAIRS)
"""Every pipeline `atr eval` knows: three SfM variants, the LIDAR baseline, the four 2D pairs."""

DEFAULT_TARGET = "t72"


@dataclass(frozen=True)
class Flight:
    """One simulated flight to evaluate.

    Attributes:
        scenario: Table II scenario (1, 2, 3).
        run: run within the scenario, 1-based.
        frames: only the first N frames (None: the whole run); scenes are frames 1..N-1.
        every: only every K-th scene (frames k with k % K == 0): a sample of the whole run, the scenes
            without target included, at 1/K of the rendering cost. The IMU is integrated over every
            frame, so each sampled scene's poses are the ones the full run gives it.
        seed: world seed (0 is reported; other seeds are for tuning).
        noise: noise spec ("none", "shot", "gaussian:10", "gaussian:30").
        target_mesh: mesh file replacing the T-72 (its template is built from the same file).
        clutter_meshes: extra confuser mesh files.

    """

    scenario: int
    run: int
    frames: int | None = None
    seed: int = 0
    noise: str = "none"
    target_mesh: str | None = None
    clutter_meshes: tuple[str, ...] = ()
    every: int = 1

    def __post_init__(self) -> None:
        if self.every < 1:
            raise ConfigError(f"every = {self.every} must be >= 1 (1 evaluates every scene)")

    def is_scene(self, seq: int, gap: int) -> bool:
        """Whether frame seq closes an evaluated scene (the pair (seq - gap, seq))."""
        return seq >= gap and seq % self.every == 0

    @property
    def target(self) -> str:
        """Name of the target in the truth and in the hypotheses."""
        from atr.io.mesh import mesh_name

        return mesh_name(self.target_mesh) if self.target_mesh else DEFAULT_TARGET


@dataclass(frozen=True)
class Arm:
    """One way of processing a flight: a pipeline and its descriptor.

    Attributes:
        pipeline: one of `PIPELINES`.
        descriptor: 3D descriptor (Table III) for the 3D pipelines; the pair's descriptor for the 2D ones.

    """

    pipeline: str
    descriptor: str

    def __post_init__(self) -> None:
        if self.pipeline not in PIPELINES:
            raise ConfigError(f"pipeline {self.pipeline!r} must be one of {PIPELINES}")
        if self.is_2d:
            if self.descriptor != pair_descriptor(self.pipeline):
                raise ConfigError(
                    f"pipeline {self.pipeline} uses descriptor {pair_descriptor(self.pipeline)!r}, "
                    f"not {self.descriptor!r}"
                )
        elif self.descriptor not in DESCRIPTORS:
            raise ConfigError(f"descriptor {self.descriptor!r} must be one of {DESCRIPTORS}")

    @property
    def is_2d(self) -> bool:
        """A 2D ATR pair (Table IV)."""
        return self.pipeline in PAIRS


def pair_descriptor(pipeline: str) -> str:
    """The descriptor name a 2D pipeline reports ("gftt+freak", ...)."""
    detector, descriptor = PAIRS[pipeline]
    return f"{detector}+{descriptor}"


def arm_overrides(arm: Arm) -> list[str]:
    """The `--set` overrides that make the service graph run this arm (empty for 2D). The paper's
    arms decide each scene alone, as the paper does; ours (sgm-sfm) runs as the configuration says
    (track-guided search by default).
    """
    if arm.is_2d:
        return []
    source = "lidar" if arm.pipeline == "lidar" else "sfm"
    out = [f"pipeline.cloud_source={source}", f"recognition.descriptor={arm.descriptor}"]
    if arm.pipeline in SFM_PIPELINES:
        out.append(f"sfm.matcher={SFM_PIPELINES[arm.pipeline]}")
    if arm.pipeline != "sgm-sfm":
        out.append("tracking.guided_search=false")
    return out


def arm_config(config: AtrConfig, arm: Arm) -> AtrConfig:
    """The configuration the service graph runs this arm with."""
    return apply_overrides(config, arm_overrides(arm))


@dataclass
class SceneRecord:
    """What one pipeline made of one scene, with the scene's truth (JSON-friendly through to_dict).

    Attributes:
        frame: frame index k (the scene is the pair (k - gap, k) for SfM, frame k otherwise).
        stamp_ns: the frame's stamp.
        truth: per target instance {"name", "position_m": [x, y, z], "visible_fraction"}.
        detections: per detection {"target", "position_m", "score"} in the matcher's order (best first).
        time_ms: processing time of the scene (SfM + matcher, matcher alone, or 2D), milliseconds.
        stages_ms: per-stage times, milliseconds.
        cloud_points: points in the scene cloud (0 for 2D).
        error: the typed error a stage raised (the services would report it instead of answering).
        T_world_cam_true: (4x4 nested lists) the frame's true camera pose.
        T_world_cam_est: the camera pose the pipeline placed its cloud with (SfM: IMU-integrated; the
            LIDAR and 2D baselines use the true pose). Scoring carries the detections from this frame
            into the true one (``sensor_relative``).

    """

    frame: int
    stamp_ns: int
    truth: list[dict[str, Any]]
    detections: list[dict[str, Any]]
    time_ms: float
    stages_ms: dict[str, float] = field(default_factory=dict)
    cloud_points: int = 0
    error: str | None = None
    T_world_cam_true: list[list[float]] | None = None
    T_world_cam_est: list[list[float]] | None = None

    def sensor_relative(self, position_m: Sequence[float]) -> np.ndarray:
        """A detected world position carried into the true world frame through the camera: the target's
        position relative to the sensor, as estimated, placed where the true camera is. The pipeline's
        navigation error (inertial drift over the flight) then does not count as ATR error; the paper's
        setup (two frames and the IMU's relative motion) has no absolute navigation to bound it.
        """
        p = np.asarray(position_m, np.float64)
        if self.T_world_cam_true is None or self.T_world_cam_est is None:
            return p
        T_true = np.asarray(self.T_world_cam_true, np.float64)
        T_est = np.asarray(self.T_world_cam_est, np.float64)
        p_cam = T_est[:3, :3].T @ (p - T_est[:3, 3])
        return T_true[:3, :3] @ p_cam + T_true[:3, 3]

    def sensor_relative_yaw(self, yaw_rad: float) -> float:
        """A detected world heading carried into the true world frame through the camera, as
        `sensor_relative` carries a position (the heading error of the navigation removed).
        """
        if self.T_world_cam_true is None or self.T_world_cam_est is None:
            return yaw_rad
        R = np.asarray(self.T_world_cam_true)[:3, :3] @ np.asarray(self.T_world_cam_est)[:3, :3].T
        return float(yaw_rad + math.atan2(R[1, 0], R[0, 0]))

    @property
    def nav_error_m(self) -> float:
        """Distance between the estimated and the true camera position, metres (NaN when unknown)."""
        if self.T_world_cam_true is None or self.T_world_cam_est is None:
            return float("nan")
        d = np.asarray(self.T_world_cam_true)[:3, 3] - np.asarray(self.T_world_cam_est)[:3, 3]
        return float(np.linalg.norm(d))

    def to_dict(self) -> dict[str, Any]:
        """Plain data."""
        return {
            "frame": self.frame,
            "stamp_ns": self.stamp_ns,
            "truth": self.truth,
            "detections": self.detections,
            "time_ms": self.time_ms,
            "stages_ms": self.stages_ms,
            "cloud_points": self.cloud_points,
            "error": self.error,
            "T_world_cam_true": self.T_world_cam_true,
            "T_world_cam_est": self.T_world_cam_est,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SceneRecord:
        """Inverse of to_dict."""
        return cls(
            **{k: d[k] for k in ("frame", "stamp_ns", "truth", "detections", "time_ms")},
            stages_ms=dict(d.get("stages_ms", {})),
            cloud_points=int(d.get("cloud_points", 0)),
            error=d.get("error"),
            T_world_cam_true=d.get("T_world_cam_true"),
            T_world_cam_est=d.get("T_world_cam_est"),
        )


def truth_of(frame: SensorFrame) -> list[dict[str, Any]]:
    """The frame's truth as SceneRecord.truth."""
    return [
        {
            "name": t.name,
            "position_m": [float(x) for x in t.T_world_target[:3, 3]],
            "visible_fraction": float(t.visible_fraction),
        }
        for t in frame.targets
    ]


def detection_dict(target: str, T_world_target: np.ndarray, score: float) -> dict[str, Any]:
    """One detection as SceneRecord.detections holds it: position, heading about z (what the tracker
    gates and fuses, as `TrackInput.from_pose` reads a Detections message) and score.
    """
    T = np.asarray(T_world_target, np.float64)
    return {
        "target": target,
        "position_m": [float(x) for x in T[:3, 3]],
        "yaw_rad": float(math.atan2(T[1, 0], T[0, 0])),
        "score": float(score),
    }


def initial_nav_state(frame: SensorFrame) -> NavState:
    """Return the state an ImuBatch's `init` carries (the navigation fix's pose and velocity, the truth
    unless sim.nav_*_sigma add errors; zero biases).
    """
    T_world_imu, v_world_mps = frame.nav_fix()
    return NavState(
        stamp_ns=frame.stamp_ns,
        R_world_imu=T_world_imu[:3, :3].copy(),
        p_world_m=T_world_imu[:3, 3].copy(),
        v_world_mps=v_world_mps.copy(),
        gyro_bias_radps=np.zeros(3),
        accel_bias_mps2=np.zeros(3),
    )


def flight_world(flight: Flight, sim_config: SimConfig) -> World:
    """The flight's world (its target and confuser meshes read from their files), as `atr simulate` builds it."""
    from atr.io.mesh import load_mesh, mesh_name  # Open3D file readers only when a file is given

    return build_world(
        scenario_preset(flight.scenario, flight.run),
        flight.seed,
        target_mesh=load_mesh(flight.target_mesh) if flight.target_mesh else None,
        target_name=flight.target,
        clutter_meshes=[(mesh_name(p), load_mesh(p)) for p in flight.clutter_meshes],
        config=sim_config,
    )


def flight_frames(flight: Flight, config: AtrConfig, lidar: bool) -> Iterator[SensorFrame]:
    """The flight's simulated frames (what `atr simulate` records); with ``flight.every`` > 1 only the
    sampled scenes' frames are rendered (the others carry IMU and truth only).
    """
    noise = parse_noise(flight.noise)  # "none": no noise
    sim = FlightSimulator(
        scenario_preset(flight.scenario, flight.run),
        flight_world(flight, config.sim),
        with_navigation_errors(config.sim, noise),
        seed=flight.seed,
        frames=flight.frames,
    )
    gap = config.sfm.pair_gap_frames

    def rendered(seq: int) -> bool:  # a sampled scene's frame or its SfM partner
        return flight.every == 1 or flight.is_scene(seq, gap) or flight.is_scene(seq + gap, gap)

    return (
        sim.frame(seq, lidar=lidar, noise=noise, rendered=rendered(seq))
        for seq in range(sim.n_frames)
    )


def _recognize(
    search: GuidedSearch,
    points: np.ndarray,
    seed: int,
    stamp_ns: int,
    viewpoint: np.ndarray,
    sigma: np.ndarray | None = None,
    cloud_regions: Sequence[SearchRegion] | None = None,
) -> tuple[list[dict[str, Any]], dict[str, float]]:
    # The cloud crosses the bus as float32 (PointCloud points_m, sigma_m); the matcher widens it back.
    scene = np.ascontiguousarray(points, np.float32).astype(np.float64)
    if sigma is not None:
        sigma = np.ascontiguousarray(sigma, np.float32).astype(np.float64)
    result = search(
        scene,
        seed=seed,  # the scene's frame number, which the schedule of whole searches counts
        stamp_ns=stamp_ns,
        frame_seq=seed,
        viewpoint_m=viewpoint,
        scene_sigma_m=sigma,
        cloud_regions=cloud_regions,
    )
    return (
        [detection_dict(d.target, d.T_world_target, d.score) for d in result.detections],
        dict(result.stage_times_ms),
    )


@dataclass(frozen=True)
class _ArmInputs:
    """What each arm needs besides the scene: its configuration, the templates it matches against and,
    for the 3D arms, the matcher as the atr_matcher service holds it over a flight (its search guidance).
    """

    configs: Mapping[Arm, AtrConfig]
    templates_3d: Mapping[str, Sequence[Template]]
    templates_2d: Mapping[str, list[Template2d]]
    baseline2d: Baseline2dConfig
    searches: Mapping[Arm, GuidedSearch]


@dataclass
class _Scene:
    """One scene as every arm sees it: the frame, its truth, its SfM pair and integrated pose, and the
    clouds reconstructed so far (one per SfM matcher and search window, shared by the descriptors).
    """

    frame: SensorFrame
    truth: list[dict[str, Any]]
    pair: Pair | None
    pose: FramePose
    clouds: dict[tuple[str, bytes], tuple[Any, float]] = field(default_factory=dict)


@dataclass
class _Work:
    """What an arm's processing of a scene has measured so far (kept when a stage raises)."""

    t0: float
    stages: dict[str, float] = field(default_factory=dict)
    points: int = 0


def run_flight(
    flight: Flight,
    arms: Sequence[Arm],
    config: AtrConfig,
    templates_3d: Mapping[str, Sequence[Template]],
    templates_2d: Mapping[str, list[Template2d]] | None = None,
    baseline2d: Baseline2dConfig | None = None,
    frames: Iterable[SensorFrame] | None = None,
) -> dict[Arm, list[SceneRecord]]:
    """Run every arm on one flight, simulating it once.

    Args:
        flight: the flight.
        arms: pipelines and descriptors to run.
        config: the effective configuration (each arm applies its own `arm_overrides`).
        templates_3d: descriptor -> templates of every target the matcher looks for (as template_store serves).
        templates_2d: 2D pipeline -> its described templates (needed for 2D arms).
        baseline2d: 2D baseline settings.
        frames: the flight's frames when already simulated (default: simulate them).

    Returns:
        Arm -> one SceneRecord per scene, in frame order.

    Raises:
        ConfigError: a 2D arm without templates, or a 3D arm without templates for its descriptor.

    """
    _check_templates(arms, templates_3d, templates_2d)
    configs = {arm: arm_config(config, arm) for arm in arms}
    inputs = _ArmInputs(
        configs,
        templates_3d,
        templates_2d or {},
        baseline2d or Baseline2dConfig(),
        {
            arm: GuidedSearch(
                templates_3d[arm.descriptor], configs[arm].recognition, configs[arm].tracking
            )
            for arm in arms
            if not arm.is_2d
        },
    )
    gap = config.sfm.pair_gap_frames
    need_lidar = any(a.pipeline == "lidar" for a in arms)
    records: dict[Arm, list[SceneRecord]] = {a: [] for a in arms}
    track = PoseTrack(config.imu, gap)  # what services/pose_integrator runs
    pairer = FramePairer(gap)  # what services/sfm runs
    source = frames if frames is not None else flight_frames(flight, config, need_lidar)
    for index, frame in enumerate(source):
        # the first batch carries the initial state; with nav_fix_every_frame every batch a fix
        fix = index == 0 or config.sim.nav_fix_every_frame
        pose, pair = _pose_and_pair(track, pairer, frame, fix)
        if flight.is_scene(frame.seq, gap):
            scene = _Scene(frame, truth_of(frame), pair, pose)
            for arm in arms:
                records[arm].append(_scene_record(arm, inputs, scene))
    return records


def _check_templates(
    arms: Sequence[Arm],
    templates_3d: Mapping[str, Sequence[Template]],
    templates_2d: Mapping[str, list[Template2d]] | None,
) -> None:
    for arm in arms:
        if arm.is_2d and (templates_2d is None or arm.pipeline not in templates_2d):
            raise ConfigError(f"no 2D templates given for {arm.pipeline}")
        if not arm.is_2d and arm.descriptor not in templates_3d:
            raise ConfigError(f"no 3D templates given for descriptor {arm.descriptor}")


def _pose_and_pair(
    track: PoseTrack, pairer: FramePairer, frame: SensorFrame, fix: bool
) -> tuple[FramePose, Pair | None]:
    """Feed one frame to the pose track and the frame pairer in the service graph's order (the IMU
    batch, its relative pose, then the image); the frame's pose and its complete SfM pair, if any.
    """
    k = frame.seq
    pose = track.add_batch(
        k,
        frame.stamp_ns,
        frame.imu_t_ns.astype(np.int64),
        frame.gyro_radps,
        frame.accel_mps2,
        initial_nav_state(frame) if fix else None,
    )
    pairer.add_imu(k)
    if pose.frame_seq_t is not None:
        pairer.add_pair(
            {
                "frame_seq_t": pose.frame_seq_t,
                "frame_seq_t1": k,
                "T_world_cam_t": pose.T_world_cam_t,
                "T_world_cam_t1": pose.T_world_cam,
            }
        )
    answer = pairer.add_image(k, {"data": frame.image})
    return pose, answer if isinstance(answer, Pair) and answer.image_t is not None else None


def _scene_record(arm: Arm, inputs: _ArmInputs, scene: _Scene) -> SceneRecord:
    """One arm's record of a scene, with the camera poses scoring carries its detections through."""
    work = _Work(time.perf_counter())
    try:
        detections, error = _detect(arm, inputs, scene, work), None
    except (
        AtrError
    ) as exc:  # the service reports it on .../errors and gives no answer for this frame
        detections, error = [], f"{type(exc).__name__}: {exc}"
    frame = scene.frame
    record = SceneRecord(
        frame.seq,
        frame.stamp_ns,
        scene.truth,
        detections,
        1e3 * (time.perf_counter() - work.t0),
        work.stages,
        work.points,
        error,
    )
    # SfM places its cloud with the integrated pose; LIDAR and 2D use the true one
    T_true = np.asarray(frame.T_world_cam, np.float64).tolist()
    uses_imu = not arm.is_2d and arm.pipeline != "lidar"
    T_est = np.asarray(scene.pose.T_world_cam, np.float64).tolist() if uses_imu else T_true
    return replace(record, T_world_cam_true=T_true, T_world_cam_est=T_est)


def _detect(arm: Arm, inputs: _ArmInputs, scene: _Scene, work: _Work) -> list[dict[str, Any]]:
    if arm.is_2d:
        return _detect_2d(arm, inputs, scene, work)
    if arm.pipeline == "lidar":
        return _detect_lidar(arm, inputs, scene, work)
    return _detect_sfm(arm, inputs, scene, work)


def _detect_2d(arm: Arm, inputs: _ArmInputs, scene: _Scene, work: _Work) -> list[dict[str, Any]]:
    frame = scene.frame
    result = recognize_2d(
        frame.image,
        frame.K,
        frame.T_world_cam,
        inputs.templates_2d[arm.pipeline],
        arm.pipeline,
        inputs.baseline2d,
        seed=frame.seq,
    )
    work.stages = {
        f"2d_{name}": ms for name, ms in result.stage_times_ms.items() if name != "total"
    }
    return [detection_dict(d.target, d.T_world_target, d.score) for d in result.detections]


def _detect_lidar(arm: Arm, inputs: _ArmInputs, scene: _Scene, work: _Work) -> list[dict[str, Any]]:
    frame = scene.frame
    work.points = len(frame.lidar_points_m)
    detections, rec = _recognize(
        inputs.searches[arm],
        frame.lidar_points_m,
        frame.seq,
        frame.stamp_ns,
        frame.T_world_cam[:3, 3].astype(np.float64),
    )
    work.stages = {k: v for k, v in rec.items() if k != "total"}
    return detections


def _detect_sfm(arm: Arm, inputs: _ArmInputs, scene: _Scene, work: _Work) -> list[dict[str, Any]]:
    config = inputs.configs[arm]
    search = inputs.searches[arm]
    # with track-guided search the SfM step decides, as the sfm service does: it matches only where
    # the search looks ([]: the whole pair) and the search follows; else the search decides itself
    regions = (search.regions(scene.frame.seq) or []) if config.tracking.guided_sfm else None
    cloud, sfm_ms = _cloud(scene, config, regions or ())
    # the scene's time is its reconstruction (done once, shared by the descriptors) + its matcher
    work.t0 = time.perf_counter() - sfm_ms / 1e3
    work.stages = {
        f"sfm_{n[5:-2]}": 1e3 * v
        for n, v in cloud.stats.items()
        if n.startswith("time_") and n.endswith("_s")
    }
    work.points = len(cloud.points_world_m)
    detections, rec = _recognize(
        search,
        cloud.points_world_m,
        scene.frame.seq,
        scene.frame.stamp_ns,
        scene.pose.T_world_cam[:3, 3],
        cloud.sigma_m,
        regions,
    )
    work.stages |= {k: v for k, v in rec.items() if k != "total"}
    return detections


def _cloud(
    scene: _Scene, config: AtrConfig, regions: Sequence[SearchRegion] = ()
) -> tuple[Any, float]:
    """The scene's SfM cloud with this configuration's matcher in these regions, and its reconstruction
    time, ms (reconstructed once per matcher and regions).
    """
    matcher = config.sfm.matcher
    key = (matcher, regions_to_array(regions).tobytes())
    if key not in scene.clouds:
        pair = scene.pair
        if pair is None:
            raise InputError(
                f"frame {scene.frame.seq} has no pair: no image or pose of its partner"
            )
        t_sfm = time.perf_counter()
        cloud = reconstruct(
            pair.image_t["data"],
            pair.image_t1["data"],
            scene.frame.K,
            pair.pose["T_world_cam_t"],
            pair.pose["T_world_cam_t1"],
            config.sfm,
            scene.frame.dist_coeffs,
            regions,
        )
        scene.clouds[key] = (cloud, 1e3 * (time.perf_counter() - t_sfm))
    return scene.clouds[key]
