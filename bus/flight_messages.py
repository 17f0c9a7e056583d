"""A simulated flight as bus messages: the options that choose it, its frames, and each frame's messages.

What the sensor source publishes and `atr simulate` records.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from bus import keys

if TYPE_CHECKING:  # the simulator (Open3D) loads only when a flight is flown, not for `atr --help`
    from atr.config import AtrConfig
    from atr.sim.flight import SensorFrame


def frame_messages(
    frame: SensorFrame,
    uav: str,
    scenario: int,
    run: int,
    seed: int,
    nav_fix: bool,
    present_min_visible_fraction: float,
) -> Iterator[tuple[str, dict[str, Any]]]:
    """The (key, message) pairs of one simulated frame, in publication order (image last).

    The truth lists the targets in the scene: those at least `present_min_visible_fraction` visible
    (an empty list when no target is in the scene).
    """
    imu = {
        "stamp_ns": frame.stamp_ns,
        "seq": frame.seq,
        "frame_seq": frame.seq,
        "t_ns": frame.imu_t_ns.astype(np.int64),
        "gyro_radps": frame.gyro_radps,
        "accel_mps2": frame.accel_mps2,
    }
    if nav_fix:  # the flight's first frame, or every frame with an aided navigation fix
        T_world_imu, v_world_mps = frame.nav_fix()
        imu["init"] = {"T_world_imu": T_world_imu, "v_world_mps": v_world_mps}
    yield keys.imu(uav), imu
    if frame.lidar_points_m is not None:
        yield (
            keys.lidar(uav),
            {
                "stamp_ns": frame.stamp_ns,
                "seq": frame.seq,
                "source": "lidar",
                "frame_seqs": [frame.seq],
                "points_m": frame.lidar_points_m.astype(np.float32),
                "viewpoint_m": frame.T_world_cam[:3, 3].astype(np.float64),
            },
        )
    yield (
        keys.truth(uav),
        {
            "stamp_ns": frame.stamp_ns,
            "seq": frame.seq,
            "frame_seq": frame.seq,
            "T_world_cam": frame.T_world_cam,
            "scenario": scenario,
            "run": run,
            "seed": seed,
            "targets": [
                {
                    "name": t.name,
                    "T_world_target": t.T_world_target,
                    "visible_fraction": float(t.visible_fraction),
                }
                for t in frame.targets
                if t.visible_fraction >= present_min_visible_fraction
            ],
        },
    )
    yield (
        keys.image(uav),
        {
            "stamp_ns": frame.stamp_ns,
            "seq": frame.seq,
            "frame_seq": frame.seq,
            "encoding": "rgb8",
            "data": frame.image,
            "K": frame.K,
            "distortion": np.asarray(frame.dist_coeffs, np.float64),
        },
    )


def add_flight_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments that choose a simulated flight (shared with `atr simulate`)."""
    parser.add_argument("--scenario", type=int, default=1, help="Table II scenario (1, 2, 3)")
    parser.add_argument(
        "--run", type=int, default=3, help="run within the scenario (1-based; 3 = 30 deg)"
    )
    parser.add_argument("--frames", type=int, help="stop after this many frames")
    parser.add_argument(
        "--seed", type=int, default=0, help="world seed (other seeds build other worlds)"
    )
    parser.add_argument(
        "--lidar", action="store_true", help="also simulate the LIDAR baseline's scans"
    )
    parser.add_argument(
        "--noise", help="noise spec: shot, gaussian:10, gaussian:30, or combined with commas"
    )
    parser.add_argument("--target-mesh", help="mesh file (PLY/OBJ/STL/GLB) replacing the T-72")
    parser.add_argument(
        "--clutter-mesh", action="append", default=[], help="extra confuser mesh (repeatable)"
    )


def flight_frames(config: AtrConfig, args: argparse.Namespace) -> Iterator[SensorFrame]:
    """The simulated frames of the flight the `add_flight_arguments` options describe."""
    from atr.evaluation.runner import Flight  # loads Open3D: only when a flight is flown
    from atr.evaluation.runner import flight_frames as fly

    flight = Flight(
        args.scenario,
        args.run,
        args.frames,
        args.seed,
        args.noise or "none",
        args.target_mesh,
        tuple(args.clutter_mesh),
    )
    return iter(fly(flight, config, args.lidar))


def flight_frame_messages(
    config: AtrConfig, args: argparse.Namespace, frames: Iterator[SensorFrame]
) -> Iterator[tuple[SensorFrame, list[tuple[str, dict[str, Any]]]]]:
    """Each frame of the flight the `add_flight_arguments` options describe with its (key, message)
    pairs in publication order: the first frame's IMU batch (and every one with
    `sim.nav_fix_every_frame`) carries the navigation state.
    """
    for index, frame in enumerate(frames):
        messages = frame_messages(
            frame,
            args.uav,
            args.scenario,
            args.run,
            args.seed,
            index == 0 or config.sim.nav_fix_every_frame,
            config.sim.present_min_visible_fraction,
        )
        yield frame, list(messages)
