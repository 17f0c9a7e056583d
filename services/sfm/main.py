"""sfm: two frames and the IMU's relative pose -> a sparse 3D cloud of the scene, in the world frame.

The paper's SfM module (§II-B-1) with a known pose: keypoints of frame t (GFTT+KLT or SURF+NNDR) are matched in
frame t + gap and triangulated with the camera poses from pose_integrator (no essential matrix); or, with
`sfm.matcher=sgm` (ours), every textured pixel is matched by semi-global matching of the pair rectified with
those poses, a dense cloud. One PointCloud per camera frame, stamped with that frame's stamp_ns: the cloud of
the pair (k - gap, k), or an empty cloud with a `note` while no pair exists yet — so every frame gets exactly
one answer downstream.

Example:
    atr service sfm --uav uav1 --set sfm.matcher=surf --set sfm.pair_gap_frames=2

"""

from __future__ import annotations

import numpy as np

from atr.sfm import reconstruct
from bus import keys
from bus.clouds import compact_points
from bus.node import Message
from bus.service import effective_config, service_arguments, start_node


def _cloud(
    stamp_ns: int,
    source: str,
    frames: list[int],
    points: np.ndarray,
    sigma: np.ndarray,
    viewpoint: np.ndarray,
    note: str | None = None,
) -> dict:
    message = {
        "stamp_ns": stamp_ns,
        "source": source,
        "frame_seqs": frames,
        "points_m": np.ascontiguousarray(points, np.float32),
        "sigma_m": np.ascontiguousarray(sigma, np.float32),
        "viewpoint_m": np.asarray(viewpoint, np.float64),
    }
    return message | ({"note": note} if note else {})


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    args = service_arguments("sfm", __doc__).parse_args(argv)
    full_config = effective_config(args)
    config, compact = full_config.sfm, full_config.pipeline.compact_clouds
    gap, source = config.pair_gap_frames, f"sfm-{config.matcher}"
    images: dict[int, dict] = {}  # frame_seq -> Image message
    pairs: dict[int, dict] = {}  # frame_seq_t1 -> RelativePose message
    inputs = [keys.image(args.uav), keys.relative_pose(args.uav)]
    with start_node("sfm", args, inputs=inputs) as node:
        node.ready()

        def publish_cloud(message: dict) -> None:
            if compact:  # the radio link's form (bus/clouds.py)
                points = message.pop("points_m")
                message |= compact_points(points)
            node.publish(keys.sfm_cloud(args.uav), message)

        def reconstruct_pair(frame: int, trigger: Message) -> None:
            image_b, pose = images[frame], pairs.pop(frame)
            image_a = images.get(pose["frame_seq_t"])
            if image_a is None:
                note = f"image of frame {pose['frame_seq_t']} never arrived"
                empty = np.zeros((0, 3))
                publish_cloud(
                    _cloud(
                        image_b["stamp_ns"],
                        source,
                        [pose["frame_seq_t"], frame],
                        empty,
                        empty[:, 0],
                        pose["T_world_cam_t1"][:3, 3],
                        note,
                    ),
                )
                return
            cloud = reconstruct(
                image_a["data"],
                image_b["data"],
                image_b["K"],
                pose["T_world_cam_t"],
                pose["T_world_cam_t1"],
                config,
                image_b.get("distortion"),
            )
            publish_cloud(
                _cloud(
                    image_b["stamp_ns"],
                    source,
                    [pose["frame_seq_t"], frame],
                    cloud.points_world_m,
                    cloud.sigma_m,
                    pose["T_world_cam_t1"][:3, 3],
                    cloud.reason or None,
                ),
            )
            stages = {k[5:-2]: 1e3 * v for k, v in cloud.stats.items() if k.startswith("time_")}
            node.timing(trigger.seq, image_b["stamp_ns"], stages)

        for message in node.events():
            with node.handling(message):
                if message.type_name == "Image":
                    frame = int(message.data["frame_seq"])
                    images[frame] = message.data
                    for stale in [f for f in images if f < frame - 4 * gap - 4]:
                        del images[stale]  # its pose never came (reported upstream)
                    if frame < gap:
                        empty = np.zeros((0, 3))
                        publish_cloud(
                            _cloud(
                                message.stamp_ns,
                                source,
                                [frame],
                                empty,
                                empty[:, 0],
                                np.zeros(3),
                                f"frame {frame} has no partner {gap} frames earlier yet",
                            ),
                        )
                else:
                    frame = int(message.data["frame_seq_t1"])
                    pairs[frame] = message.data
                if frame in images and frame in pairs:
                    try:
                        reconstruct_pair(frame, message)
                    finally:
                        # Keep only the images a later pair can still use.
                        for old in [f for f in images if f <= frame - gap]:
                            del images[old]
    return 0
