"""pose_integrator: gyroscope + accelerometer -> the camera's pose per frame and R*_cam per frame pair.

The paper's §II-B-1, eqs. (1)-(4): the camera's motion between two frames comes from the IMU, not the images.
Each ImuBatch ends at a camera frame; the first batch of a flight carries the initial navigation state
(`init`). For frame k it publishes the CameraPose, and for the pair (k - gap, k) the RelativePose
(gap = sfm.pair_gap_frames), both stamped with the frame's stamp_ns. A later batch's `init` is an aided
navigation fix at its frame (`sim.nav_fix_every_frame`): that frame's pose is still the integrated one (the
pair ending there used it), and the next pair starts from the fix.

Example:
    atr service pose_integrator --uav uav1 --set imu.integration=paper

"""

from __future__ import annotations

import time

import numpy as np

from atr.errors import InputError
from atr.imu import NavState, PoseIntegrator, relative_camera_pose
from bus import keys
from bus.service import effective_config, service_arguments, start_node


def initial_state(stamp_ns: int, init: dict) -> NavState:
    """The navigation state an ImuBatch's `init` field describes."""
    T = np.asarray(init["T_world_imu"], np.float64)
    return NavState(
        stamp_ns=stamp_ns,
        R_world_imu=T[:3, :3].copy(),
        p_world_m=T[:3, 3].copy(),
        v_world_mps=np.asarray(init["v_world_mps"], np.float64).copy(),
        gyro_bias_radps=np.asarray(init.get("gyro_bias_radps", np.zeros(3)), np.float64).copy(),
        accel_bias_mps2=np.asarray(init.get("accel_bias_mps2", np.zeros(3)), np.float64).copy(),
    )


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    args = service_arguments("pose_integrator", __doc__).parse_args(argv)
    config = effective_config(args)
    gap = config.sfm.pair_gap_frames
    integrator: PoseIntegrator | None = None
    poses: dict[int, tuple[int, np.ndarray]] = {}  # frame_seq -> (stamp_ns, T_world_cam)
    with start_node("pose_integrator", args, inputs=[keys.imu(args.uav)]) as node:
        node.ready()
        for message in node.events():
            with node.handling(message):
                batch = message.data
                t0 = time.perf_counter()
                frame, stamp = int(batch["frame_seq"]), int(batch["stamp_ns"])
                fix = batch.get("init")
                if fix is not None and (integrator is None or frame - gap not in poses):
                    # a flight starts: the INS alignment before take-off
                    integrator = PoseIntegrator(config.imu, initial_state(stamp, fix))
                    poses.clear()
                    fix = None
                if integrator is None:
                    raise InputError(
                        f"IMU batch for frame {batch['frame_seq']} arrived before any initialisation (`init`)"
                    )
                if len(batch["t_ns"]):
                    integrator.add_imu(batch["t_ns"], batch["gyro_radps"], batch["accel_mps2"])
                T_world_cam = integrator.camera_pose(stamp)
                poses[frame] = (stamp, T_world_cam)
                node.publish(
                    keys.camera_pose(args.uav),
                    {
                        "stamp_ns": stamp,
                        "frame_seq": frame,
                        "T_world_cam": T_world_cam,
                        "integration": config.imu.integration,
                    },
                )
                if frame - gap in poses:
                    stamp_t, T_world_cam_t = poses[frame - gap]
                    node.publish(
                        keys.relative_pose(args.uav),
                        {
                            "stamp_ns": stamp,
                            "frame_seq_t": frame - gap,
                            "frame_seq_t1": frame,
                            "stamp_ns_t": stamp_t,
                            "T_camt1_camt": relative_camera_pose(T_world_cam_t, T_world_cam),
                            "T_world_cam_t": T_world_cam_t,
                            "T_world_cam_t1": T_world_cam,
                        },
                    )
                if fix is not None:
                    # an aided navigation fix at this frame: the next pair starts from it
                    integrator = PoseIntegrator(config.imu, initial_state(stamp, fix))
                    poses[frame] = (stamp, integrator.camera_pose(stamp))
                for old in [f for f in poses if f <= frame - gap]:
                    del poses[old]
                node.timing(message.seq, stamp, {"integrate": 1e3 * (time.perf_counter() - t0)})
    return 0
