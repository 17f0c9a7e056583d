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

import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from atr.baselines2d import Baseline2dConfig, Template2d, recognize_2d
from atr.baselines2d.config import PAIRS
from atr.config import AtrConfig, apply_overrides
from atr.errors import AtrError, ConfigError, InputError
from atr.imu import NavState
from atr.imu.pose_track import FramePose, PoseTrack
from atr.recognition import DESCRIPTORS, Template, recognize
from atr.sfm import reconstruct
from atr.sfm.pairing import FramePairer, Pair
from atr.sim.flight import SensorFrame, simulate_flight
from atr.sim.scenarios import scenario as scenario_preset

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
        return Path(self.target_mesh).stem if self.target_mesh else DEFAULT_TARGET


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
    """The `--set` overrides that make the service graph run this arm (empty for 2D)."""
    if arm.is_2d:
        return []
    source = "lidar" if arm.pipeline == "lidar" else "sfm"
    out = [f"pipeline.cloud_source={source}", f"recognition.descriptor={arm.descriptor}"]
    if arm.pipeline in SFM_PIPELINES:
        out.append(f"sfm.matcher={SFM_PIPELINES[arm.pipeline]}")
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
    """One detection as SceneRecord.detections holds it."""
    return {
        "target": target,
        "position_m": [float(x) for x in np.asarray(T_world_target)[:3, 3]],
        "score": float(score),
    }


def initial_nav_state(frame: SensorFrame) -> NavState:
    """Return the state the first ImuBatch's `init` carries (true pose, velocity; zero biases)."""
    return NavState(
        stamp_ns=frame.stamp_ns,
        R_world_imu=frame.T_world_imu[:3, :3].copy(),
        p_world_m=frame.T_world_imu[:3, 3].copy(),
        v_world_mps=frame.v_world_imu_mps.copy(),
        gyro_bias_radps=np.zeros(3),
        accel_bias_mps2=np.zeros(3),
    )


def flight_frames(flight: Flight, config: AtrConfig, lidar: bool) -> Iterable[SensorFrame]:
    """The flight's simulated frames (what `atr simulate` records); with ``flight.every`` > 1 only the
    sampled scenes' frames are rendered (the others carry IMU and truth only).
    """
    from atr.io.mesh import load_mesh  # Open3D file readers only when a file is given

    target = load_mesh(flight.target_mesh) if flight.target_mesh else None
    clutter = [load_mesh(p) for p in flight.clutter_meshes]
    name = Path(flight.target_mesh).stem if flight.target_mesh else None
    noise = None if flight.noise == "none" else flight.noise
    gap = config.sfm.pair_gap_frames
    render = None
    if flight.every > 1:
        render = lambda seq: flight.is_scene(seq, gap) or flight.is_scene(seq + gap, gap)  # noqa: E731
    return simulate_flight(
        scenario_preset(flight.scenario, flight.run),
        seed=flight.seed,
        frames=flight.frames,
        target_mesh=target,
        clutter_meshes=clutter,
        lidar=lidar,
        noise=noise,
        config=config.sim,
        target_name=name,
        render=render,
    )


def _recognize(
    points: np.ndarray,
    templates: Sequence[Template],
    config: AtrConfig,
    seed: int,
    viewpoint: np.ndarray,
    sigma: np.ndarray | None = None,
) -> tuple[list[dict[str, Any]], dict[str, float]]:
    # The cloud crosses the bus as float32 (PointCloud points_m, sigma_m); the matcher widens it back.
    scene = np.ascontiguousarray(points, np.float32).astype(np.float64)
    if sigma is not None:
        sigma = np.ascontiguousarray(sigma, np.float32).astype(np.float64)
    result = recognize(
        scene,
        list(templates),
        config.recognition,
        seed=seed,
        viewpoint_m=viewpoint,
        scene_sigma_m=sigma,
    )
    return (
        [detection_dict(d.target, d.T_world_target, d.score) for d in result.detections],
        dict(result.stage_times_ms),
    )


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
    b2d = baseline2d or Baseline2dConfig()
    for arm in arms:
        if arm.is_2d and (templates_2d is None or arm.pipeline not in templates_2d):
            raise ConfigError(f"no 2D templates given for {arm.pipeline}")
        if not arm.is_2d and arm.descriptor not in templates_3d:
            raise ConfigError(f"no 3D templates given for descriptor {arm.descriptor}")
    configs = {arm: arm_config(config, arm) for arm in arms}
    gap = config.sfm.pair_gap_frames
    need_lidar = any(a.pipeline == "lidar" for a in arms)
    records: dict[Arm, list[SceneRecord]] = {a: [] for a in arms}
    track = PoseTrack(config.imu, gap)  # what services/pose_integrator runs
    pairer = FramePairer(gap)  # what services/sfm runs
    source = frames if frames is not None else flight_frames(flight, config, need_lidar)
    for index, frame in enumerate(source):
        k = frame.seq
        # the first batch carries the initial state; with nav_fix_every_frame every batch a fix
        fix = index == 0 or config.sim.nav_fix_every_frame
        pose = track.add_batch(
            k,
            frame.stamp_ns,
            frame.imu_t_ns.astype(np.int64),
            frame.gyro_radps,
            frame.accel_mps2,
            initial_nav_state(frame) if fix else None,
        )
        # the service graph's order: the IMU batch, its relative pose, then the image
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
        pair = answer if isinstance(answer, Pair) and answer.image_t is not None else None
        if flight.is_scene(k, gap):
            truth = truth_of(frame)
            clouds: dict[
                str, tuple[Any, float]
            ] = {}  # one reconstruction per matcher, shared by descriptors
            T_true = np.asarray(frame.T_world_cam, np.float64).tolist()
            for arm in arms:
                record = _scene(
                    arm,
                    configs[arm],
                    frame,
                    truth,
                    pair,
                    pose,
                    templates_3d,
                    templates_2d,
                    b2d,
                    clouds,
                )
                # SfM places its cloud with the integrated pose; LIDAR and 2D use the true one
                uses_imu = not arm.is_2d and arm.pipeline != "lidar"
                T_est = np.asarray(pose.T_world_cam, np.float64).tolist() if uses_imu else T_true
                records[arm].append(replace(record, T_world_cam_true=T_true, T_world_cam_est=T_est))
    return records


def _scene(
    arm: Arm,
    config: AtrConfig,
    frame: SensorFrame,
    truth: list[dict[str, Any]],
    pair: Pair | None,
    pose: FramePose,
    templates_3d: Mapping[str, Sequence[Template]],
    templates_2d: Mapping[str, list[Template2d]] | None,
    b2d: Baseline2dConfig,
    clouds: dict[str, tuple[Any, float]],
) -> SceneRecord:
    k = frame.seq
    t0 = time.perf_counter()
    stages: dict[str, float] = {}
    points = 0
    try:
        if arm.is_2d:
            result = recognize_2d(
                frame.image,
                frame.K,
                frame.T_world_cam,
                templates_2d[arm.pipeline],
                arm.pipeline,
                b2d,
                seed=k,
            )
            detections = [
                detection_dict(d.target, d.T_world_target, d.score) for d in result.detections
            ]
            stages = {
                f"2d_{name}": ms for name, ms in result.stage_times_ms.items() if name != "total"
            }
        elif arm.pipeline == "lidar":
            points = len(frame.lidar_points_m)
            detections, rec = _recognize(
                frame.lidar_points_m,
                templates_3d[arm.descriptor],
                config,
                k,
                frame.T_world_cam[:3, 3].astype(np.float64),
            )
            stages = {k_: v for k_, v in rec.items() if k_ != "total"}
        else:
            if config.sfm.matcher not in clouds:
                if pair is None:
                    raise InputError(f"frame {k} has no pair: no image or pose of its partner")
                t_sfm = time.perf_counter()
                cloud = reconstruct(
                    pair.image_t["data"],
                    pair.image_t1["data"],
                    frame.K,
                    pair.pose["T_world_cam_t"],
                    pair.pose["T_world_cam_t1"],
                    config.sfm,
                    frame.dist_coeffs,
                )
                clouds[config.sfm.matcher] = (cloud, 1e3 * (time.perf_counter() - t_sfm))
            cloud, sfm_ms = clouds[config.sfm.matcher]
            # the scene's time is its reconstruction (done once, shared by the descriptors) + its matcher
            t0 = time.perf_counter() - sfm_ms / 1e3
            stages = {
                f"sfm_{n[5:-2]}": 1e3 * v
                for n, v in cloud.stats.items()
                if n.startswith("time_") and n.endswith("_s")
            }
            points = len(cloud.points_world_m)
            detections, rec = _recognize(
                cloud.points_world_m,
                templates_3d[arm.descriptor],
                config,
                k,
                pose.T_world_cam[:3, 3],
                cloud.sigma_m,
            )
            stages |= {k_: v for k_, v in rec.items() if k_ != "total"}
    except (
        AtrError
    ) as exc:  # the service reports it on .../errors and gives no answer for this frame
        return SceneRecord(
            k,
            frame.stamp_ns,
            truth,
            [],
            1e3 * (time.perf_counter() - t0),
            stages,
            points,
            f"{type(exc).__name__}: {exc}",
        )
    return SceneRecord(
        k, frame.stamp_ns, truth, detections, 1e3 * (time.perf_counter() - t0), stages, points
    )
