"""pose_integrator: gyroscope + accelerometer -> the camera's pose per frame and R*_cam per frame pair.

The paper's §II-B-1, eqs. (1)-(4): the camera's motion between two frames comes from the IMU, not the images.
Each ImuBatch ends at a camera frame; the first batch of a flight carries the initial navigation state
(`init`). For frame k it publishes the CameraPose, and for the pair (k - gap, k) the RelativePose
(gap = sfm.pair_gap_frames), both stamped with the frame's stamp_ns. A later batch's `init` is an aided
navigation fix at its frame (`sim.nav_fix_every_frame`): that frame's pose is still the integrated one (the
pair ending there used it), and the next pair starts from the fix.

A restarted process goes on where a killed one stopped: the track (atr/imu/pose_track.py) is checkpointed
after every batch in `--state-dir`, and the batch the killed process had in hand is handled again first.
A batch of a frame already done is not integrated again: the last frame's messages are put again, as they were
(its inputs are sent again when a service restarts while the frame is in flight); after lost batches the track waits for the next
navigation fix and every batch until then is reported (docs/architecture.md, "Recovery").

Example:
    atr service pose_integrator --uav uav1 --set imu.integration=paper

"""

from __future__ import annotations

import time

from atr.imu import relative_camera_pose, warm_up
from atr.imu.pose_track import FramePose, PoseTrack, nav_state
from bus import keys
from bus.node import Node
from bus.service import effective_config, service_arguments, start_node


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    args = service_arguments("pose_integrator", __doc__, keeps="checkpoint").parse_args(argv)
    config = effective_config(args)
    with start_node("pose_integrator", args, inputs=[keys.imu(args.uav)], replay_lost=True) as node:
        saved = node.load_state()
        track = (
            PoseTrack(config.imu, config.sfm.pair_gap_frames)
            if saved is None
            else PoseTrack.from_state_dict(config.imu, saved)
        )
        warm_up(config.imu)  # the first frame would pay for it: its latency, and every next one's
        node.ready()
        for message in node.events():
            with node.handling(message):
                batch = message.data
                t0 = time.perf_counter()
                stamp = int(batch["stamp_ns"])
                init = batch.get("init")
                try:
                    pose = track.add_batch(
                        int(batch["frame_seq"]),
                        stamp,
                        batch["t_ns"],
                        batch["gyro_radps"],
                        batch["accel_mps2"],
                        None if init is None else nav_state(stamp, init),
                    )
                finally:
                    node.save_state(track.state_dict())
                if pose is None:
                    # a repeated batch (sent again after a restart downstream): the same answer again;
                    # a process restarted from a checkpoint has not sent it yet, so it answers anew
                    sent = node.republish(keys.camera_pose(args.uav), stamp)
                    sent = node.republish(keys.relative_pose(args.uav), stamp) or sent
                    last = track.last_answer(int(batch["frame_seq"]), stamp)
                    if not sent and last is not None:
                        _publish(node, args.uav, config.imu.integration, last)
                    continue
                _publish(node, args.uav, config.imu.integration, pose)
                node.timing(message.seq, stamp, {"integrate": 1e3 * (time.perf_counter() - t0)})
    return 0


def _publish(node: Node, uav: str, integration: str, pose: FramePose) -> None:
    node.publish(
        keys.camera_pose(uav),
        {
            "stamp_ns": pose.stamp_ns,
            "frame_seq": pose.frame_seq,
            "T_world_cam": pose.T_world_cam,
            "integration": integration,
        },
    )
    if pose.frame_seq_t is not None:
        node.publish(
            keys.relative_pose(uav),
            {
                "stamp_ns": pose.stamp_ns,
                "frame_seq_t": pose.frame_seq_t,
                "frame_seq_t1": pose.frame_seq,
                "stamp_ns_t": pose.stamp_ns_t,
                "T_camt1_camt": relative_camera_pose(pose.T_world_cam_t, pose.T_world_cam),
                "T_world_cam_t": pose.T_world_cam_t,
                "T_world_cam_t1": pose.T_world_cam,
            },
        )
