"""The evaluation through the real service graph, and a recorded run read back as SceneRecords.

`run_via_services` writes a flight's recording (`atr simulate`'s messages) and replays it through the services
per 3D arm (`atr run`); `recorded_scenes` reads the recorded truth, detections, camera poses and timings back
into the SceneRecords the in-process evaluation gives, so both paths are scored alike.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from atr.errors import AtrError
from atr.evaluation.runner import (
    Arm,
    Flight,
    SceneRecord,
    arm_overrides,
    detection_dict,
    flight_frames,
    run_flight,
)
from atr.sim.flight import SensorFrame, TargetTruth
from bus import codec, keys
from bus.clouds import cloud_points
from bus.flight_messages import frame_messages
from bus.mcap_tools import iter_messages
from bus.pipeline import run_recording
from bus.recording import write_messages

if TYPE_CHECKING:
    from atr.evaluation.experiment import Plan


def scene_record(
    truth: dict | None,
    detections: dict | None,
    camera_pose: dict | None,
    *,
    time_ms: float = float("nan"),
    stages_ms: dict[str, float] | None = None,
    cloud_points: int = 0,
) -> SceneRecord:
    """A SceneRecord from one frame's bus messages (decoded Truth, Detections and CameraPose).

    An SfM cloud is placed with the estimated camera pose, so its detections are judged relative to it;
    a LIDAR cloud, or a scene without a CameraPose, is placed with the true pose.
    """
    truth = truth or {}
    found = [
        detection_dict(d["target"], d["T_world_target"], d["score"])
        for d in (detections or {}).get("detections", [])
    ]
    T_true = np.asarray(truth["T_world_cam"]).tolist() if "T_world_cam" in truth else None
    from_sfm = str((detections or {}).get("source", "")).startswith("sfm")
    T_est = (
        np.asarray(camera_pose["T_world_cam"]).tolist()
        if from_sfm and camera_pose is not None
        else T_true
    )
    return SceneRecord(
        frame=int(truth.get("frame_seq", -1)),
        stamp_ns=int((detections or truth).get("stamp_ns", 0)),
        truth=[
            {
                "name": t["name"],
                "position_m": [float(v) for v in np.asarray(t["T_world_target"])[:3, 3]],
                "visible_fraction": float(t["visible_fraction"]),
            }
            for t in truth.get("targets", [])
        ],
        detections=found,
        time_ms=time_ms,
        stages_ms=stages_ms or {},
        cloud_points=cloud_points,
        error=None if detections is not None else "no answer",
        T_world_cam_true=T_true,
        T_world_cam_est=T_est,
    )


def run_via_services(
    flight: Flight, arms: list[Arm], plan_: Plan, workdir: Path
) -> dict[Arm, list[SceneRecord]]:
    """Run one flight: `atr simulate`, then `atr run` per 3D arm; 2D arms in-process on it."""
    workdir.mkdir(parents=True, exist_ok=True)
    stem = f"s{flight.scenario}r{flight.run}-{flight.noise.replace(':', '')}-seed{flight.seed}"
    recording = workdir / f"{stem}.mcap"
    lidar = any(a.pipeline == "lidar" for a in arms)
    frames = flight_frames(flight, plan_.config, lidar)

    def messages() -> Iterator[tuple[str, dict]]:
        for index, frame in enumerate(frames):
            yield from frame_messages(
                frame,
                "uav1",
                flight.scenario,
                flight.run,
                flight.seed,
                index == 0 or plan_.config.sim.nav_fix_every_frame,
                plan_.config.sim.present_min_visible_fraction,
            )

    write_messages(recording, messages())
    out: dict[Arm, list[SceneRecord]] = {}
    for arm in arms:
        if arm.is_2d:
            continue
        result_path = workdir / f"{stem}-{arm.pipeline}-{arm.descriptor}.mcap"
        result = run_recording(
            recording, result_path, overrides=plan_.overrides + arm_overrides(arm)
        )
        if result.failures:
            raise AtrError(
                f"service graph failed on {stem} ({arm.pipeline}/{arm.descriptor}): "
                f"{result.failures}; logs in {result.log_dir}"
            )
        out[arm] = recorded_scenes(result_path, plan_.config.sfm.pair_gap_frames)
    two_d = [a for a in arms if a.is_2d]
    if two_d:
        out |= run_flight(
            flight,
            two_d,
            plan_.config,
            plan_.templates_3d,
            plan_.templates_2d,
            plan_.b2d,
            frames=recorded_frames(recording),
        )
    return out


def recorded_scenes(path: Path, gap: int, uav: str = "uav1") -> list[SceneRecord]:
    """Read a recorded run's SceneRecords: truth, Detections and CameraPose by stamp_ns, Timing times."""
    truth: dict[int, dict] = {}
    detections: dict[int, dict] = {}
    stages: dict[int, dict[str, float]] = {}
    clouds: dict[int, int] = {}
    camera_pose: dict[int, dict] = {}
    for topic, message in iter_messages(path):  # every segment of the recording
        if topic == keys.truth(uav):
            data = codec.unpack(message.data)
            truth[data["stamp_ns"]] = data
        elif topic == keys.detections(uav):
            data = codec.unpack(message.data)
            detections[data["stamp_ns"]] = data
        elif topic in (keys.sfm_cloud(uav), keys.lidar(uav)):
            data = codec.unpack(message.data)
            clouds[data["stamp_ns"]] = len(cloud_points(data))
        elif topic == keys.camera_pose(uav):
            data = codec.unpack(message.data)
            camera_pose.setdefault(data["stamp_ns"], data)
        elif topic.endswith("/timing") and ("/sfm/" in topic or "/atr_matcher/" in topic):
            data = codec.unpack(message.data)
            prefix = "sfm_" if "/sfm/" in topic else ""
            into = stages.setdefault(data["stamp_ns"], {})
            for name, ms in data["stages_ms"].items():
                if name != "total":
                    into[prefix + name] = float(ms)
    records = []
    for stamp in sorted(truth):
        if truth[stamp]["frame_seq"] < gap:
            continue
        st = stages.get(stamp, {})
        records.append(
            scene_record(
                truth[stamp],
                detections.get(stamp),
                camera_pose.get(stamp),
                time_ms=sum(st.values()) if st else float("nan"),
                stages_ms=st,
                cloud_points=clouds.get(stamp, 0),
            )
        )
    return records


def recorded_frames(path: Path, uav: str = "uav1") -> list[SensorFrame]:
    """SensorFrames rebuilt from a recording's image and truth messages (for the 2D baseline)."""
    truth: dict[int, dict] = {}
    images: dict[int, dict] = {}
    for topic, message in iter_messages(path, topics=[keys.truth(uav), keys.image(uav)]):
        data = codec.unpack(message.data)
        (truth if topic == keys.truth(uav) else images)[data["stamp_ns"]] = data
    empty = np.zeros((0, 3))
    return [
        SensorFrame(
            seq=int(images[s]["frame_seq"]),
            stamp_ns=s,
            image=np.asarray(images[s]["data"]),
            K=np.asarray(images[s]["K"]),
            T_world_cam=np.asarray(truth[s]["T_world_cam"]),
            imu_t_ns=np.zeros(0, np.int64),
            gyro_radps=empty,
            accel_mps2=empty,
            T_world_imu=np.eye(4),
            v_world_imu_mps=np.zeros(3),
            lidar_points_m=None,
            targets=[
                TargetTruth(t["name"], np.asarray(t["T_world_target"]), t["visible_fraction"])
                for t in truth[s]["targets"]
            ],
        )
        for s in sorted(images)
        if s in truth
    ]
