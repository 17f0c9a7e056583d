"""sensor_source: the simulated UAV's sensors on the bus — camera images, IMU batches, LIDAR scans, truth.

It flies one scenario run of Table II in the simulated world (atr/sim) and publishes, per frame, in this
order: the ImuBatch (samples since the previous frame; the first carries the initial navigation state, as a
GNSS/INS alignment before take-off would), the LIDAR cloud (with --lidar), the truth, and the Image.
`atr simulate` writes the same messages straight into a recording.

Pacing: `--pace realtime` (the frame interval of the flight), `--pace fast` (as fast as it renders), or
`--pace lock-step` (the next frame only after the pipeline answered the last: a Detections or an ErrorReport
stamped with the frame's stamp_ns; nothing is ever dropped).

Example:
    atr service sensor_source --scenario 1 --run 3 --frames 20 --pace lock-step

"""

from __future__ import annotations

import argparse
import logging
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from bus import keys
from bus.answers import AnswerWatch
from bus.service import effective_config, service_arguments, start_node

if TYPE_CHECKING:  # the simulator (Open3D) loads only when a flight is flown, not for `atr --help`
    from atr.config import AtrConfig
    from atr.sim.flight import SensorFrame

log = logging.getLogger("atr")


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
    (ARCHITECTURE.md §4: an empty list when no target is in the scene).
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
        imu["init"] = {"T_world_imu": frame.T_world_imu, "v_world_mps": frame.v_world_imu_mps}
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
    from atr.evaluation.runner import Flight  # noqa: PLC0415 - loads Open3D
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


def main(argv: list[str] | None = None) -> int:
    """Fly the run, then exit."""
    parser = service_arguments("sensor_source", __doc__)
    add_flight_arguments(parser)
    parser.add_argument("--pace", choices=["realtime", "fast", "lock-step"], default="lock-step")
    parser.add_argument(
        "--answer-timeout", type=float, default=600.0, help="lock-step wait per frame, s"
    )
    args = parser.parse_args(argv)
    config = effective_config(args)
    frames = flight_frames(config, args)
    with start_node("sensor_source", args, inputs=[]) as node:
        watch = AnswerWatch(node.session, node.service)
        node.ready()
        time.sleep(1.0)  # let gossip connect every peer before the first frame
        last_stamp: int | None = None
        for index, frame in enumerate(frames):
            if node.stopping:
                break
            if args.pace == "realtime" and last_stamp is not None:
                time.sleep(max(0.0, (frame.stamp_ns - last_stamp) * 1e-9))
            for key, message in frame_messages(
                frame,
                args.uav,
                args.scenario,
                args.run,
                args.seed,
                index == 0 or config.sim.nav_fix_every_frame,
                config.sim.present_min_visible_fraction,
            ):
                node.publish(key, message)
            last_stamp = frame.stamp_ns
            if args.pace == "lock-step" and not watch.wait(
                args.uav, frame.stamp_ns, args.answer_timeout
            ):
                node.report_error(
                    keys.detections(args.uav),
                    TimeoutError(f"no answer to frame {frame.seq} within {args.answer_timeout} s"),
                    frame.seq,
                    frame.stamp_ns,
                )
            log.info("frame %d published", frame.seq)
    return 0
