"""sfm: two frames and the IMU's relative pose -> a sparse 3D cloud of the scene, in the world frame.

The paper's SfM module (§II-B-1) with a known pose: keypoints of frame t (GFTT+KLT or SURF+NNDR) are matched in
frame t + gap and triangulated with the camera poses from pose_integrator (no essential matrix); or, with
`sfm.matcher=sgm` (ours), every textured pixel is matched by semi-global matching of the pair rectified with
those poses, a dense cloud. One PointCloud per camera frame, stamped with that frame's stamp_ns: the cloud of
the pair (k - gap, k), or an empty cloud with a `note` while no pair exists yet — so every frame gets exactly
one answer downstream (atr/sfm/pairing.py): a frame without an image `gap` frames earlier gets an empty
cloud, a frame whose IMU batch never arrived an ErrorReport (when a later batch shows it was skipped, or
`IMU_GRACE_S` after its image when nothing later comes). An input of a frame already
answered (sent again after a restart downstream) puts that frame's cloud again, the same message.
A restarted process reports the input a killed one had in hand (its frame is answered) and goes on.
With `tracking.guided_search` and `sgm` it keeps the search's schedule (atr.tracking.guided_search): between
whole pairs it matches only the image window of the regions around atr_matcher's held tracks (its latest
atr/{uav}/guidance), and says in each cloud's `regions_m` where it matched (no rows: whole).

Example:
    atr service sfm --uav uav1 --set sfm.matcher=surf --set sfm.pair_gap_frames=2

"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from atr.errors import InputError
from atr.regions import SearchRegion, regions_from_array, regions_to_array
from atr.sfm import reconstruct
from atr.sfm.pairing import Answer, FramePairer, Missing, NoPartner
from atr.tracking.guided_search import SearchSchedule
from bus import keys
from bus.clouds import compact_cloud
from bus.node import Message
from bus.service import effective_config, service_arguments, start_node

# How long an image waits for its own frame's IMU batch before the batch is taken as lost. The batch is
# sent before the image and normally arrives within milliseconds of it (on another key, so possibly after
# it); lock-step sends nothing later until this frame is answered, so only a time can end the wait.
IMU_GRACE_S = 2.0


def _cloud(
    stamp_ns: int,
    source: str,
    frames: list[int],
    points: np.ndarray,
    sigma: np.ndarray,
    viewpoint: np.ndarray,
    note: str | None = None,
    regions: Sequence[SearchRegion] | None = None,
) -> dict:
    message = {
        "stamp_ns": stamp_ns,
        "source": source,
        "frame_seqs": frames,
        "points_m": np.ascontiguousarray(points, np.float32),
        "sigma_m": np.ascontiguousarray(sigma, np.float32),
        "viewpoint_m": np.asarray(viewpoint, np.float64),
    }
    if regions is not None:  # where it was matched when guided search decides here ([]: whole)
        message["regions_m"] = regions_to_array(regions)
    return message | ({"note": note} if note else {})


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    args = service_arguments("sfm", __doc__, keeps="journal").parse_args(argv)
    full_config = effective_config(args)
    config, compact = full_config.sfm, full_config.pipeline.compact_clouds
    leaf_m = full_config.recognition.template.resolution_m  # the matcher's subsampling
    source = f"sfm-{config.matcher}"
    pairer = FramePairer(config.pair_gap_frames)
    inputs = [keys.imu(args.uav), keys.image(args.uav), keys.relative_pose(args.uav)]
    tracking = full_config.tracking
    guided = tracking.guided_search and tracking.guided_sfm and config.matcher == "sgm"
    if guided:
        inputs.append(keys.guidance(args.uav))
    # track-guided search decides here, before the matcher sees the pair: the regions around the
    # matcher's held tracks (its latest guidance) and which pairs are matched whole
    held: list[SearchRegion] = []
    schedule = SearchSchedule(tracking.full_search_every_frames)
    # the guidance goes ahead of queued images: sfm behind the camera matches its next pair where
    # the matcher now looks, not where it looked when that image was queued
    urgent = [keys.guidance(args.uav)] if guided else []
    with start_node("sfm", args, inputs=inputs, urgent=urgent) as node:
        node.ready()

        def publish_cloud(message: dict) -> None:
            if compact:  # the radio link's form: what the matcher uses, quantised (bus/clouds.py)
                points, sigma = message.pop("points_m"), message.pop("sigma_m")
                message |= compact_cloud(points, sigma, leaf_m)
            node.publish(keys.sfm_cloud(args.uav), message)

        def empty(image: dict, frames: list[int], viewpoint: np.ndarray, note: str) -> None:
            none = np.zeros((0, 3))
            publish_cloud(
                _cloud(image["stamp_ns"], source, frames, none, none[:, 0], viewpoint, note)
            )

        def answer(result: Answer, trigger: Message) -> None:
            if isinstance(result, Missing):
                raise InputError(result.reason)
            if isinstance(result, NoPartner):
                empty(result.image, [result.frame_seq], np.zeros(3), result.reason)
                return
            pose, image_b = result.pose, result.image_t1
            frames = [int(pose["frame_seq_t"]), result.frame_seq]
            if result.image_t is None:
                note = f"no image of frame {frames[0]} was accepted (never arrived, or rejected)"
                empty(image_b, frames, pose["T_world_cam_t1"][:3, 3], note)
                return
            regions = (schedule.regions(held, result.frame_seq) or []) if guided else None
            cloud = reconstruct(
                result.image_t["data"],
                image_b["data"],
                image_b["K"],
                pose["T_world_cam_t"],
                pose["T_world_cam_t1"],
                config,
                image_b.get("distortion"),
                regions or (),
            )
            schedule.searched(whole=not regions, frame_seq=result.frame_seq)
            publish_cloud(
                _cloud(
                    image_b["stamp_ns"],
                    source,
                    frames,
                    cloud.points_world_m,
                    cloud.sigma_m,
                    pose["T_world_cam_t1"][:3, 3],
                    cloud.reason or None,
                    regions,
                ),
            )
            stages = {k[5:-2]: 1e3 * v for k, v in cloud.stats.items() if k.startswith("time_")}
            node.timing(trigger.seq, image_b["stamp_ns"], stages)

        # images whose frame's IMU batch has not arrived: frame -> (monotonic arrival s, stamp_ns)
        waiting: dict[int, tuple[float, int]] = {}

        def report_missing(missing: Missing, stamp_ns: int | None) -> None:
            node.report_error(
                keys.image(args.uav), InputError(missing.reason), input_stamp_ns=stamp_ns
            )

        def give_up_overdue() -> None:
            now = time.monotonic()
            for k, (arrived, stamp_ns) in list(waiting.items()):
                if not pairer.lacks_imu(k):
                    del waiting[k]
                elif now - arrived > IMU_GRACE_S:
                    del waiting[k]
                    if (missing := pairer.give_up(k)) is not None:
                        report_missing(missing, stamp_ns)

        sensor: str | None = None  # the publisher of the flight's images and IMU batches
        while not node.stopping:
            for message in node.events(timeout_s=IMU_GRACE_S / 4):
                with node.handling(message):
                    if message.type_name == "SearchGuidance":
                        held = regions_from_array(message.data["regions_m"])
                        continue
                    if message.type_name != "RelativePose" and message.source != sensor:
                        # another sensor source (or replay): a new flight, whose frame numbers start
                        # again; a re-send comes from the same publisher and is a repeat
                        if sensor is not None:
                            pairer, waiting = FramePairer(config.pair_gap_frames), {}
                            held = []
                            schedule.reset()
                        sensor = message.source
                    if message.type_name == "ImuBatch":
                        for missing in pairer.add_imu(int(message.data["frame_seq"])):
                            report_missing(missing, waiting.pop(missing.frame_seq, (0.0, None))[1])
                        continue
                    k = int(message.data.get("frame_seq", message.data.get("frame_seq_t1", -1)))
                    if message.type_name == "Image":
                        result = pairer.add_image(k, message.data)
                        if result is None and pairer.lacks_imu(k):
                            waiting[k] = (time.monotonic(), message.stamp_ns)
                    else:
                        result = pairer.add_pair(message.data)
                    if result is not None:
                        answer(result, message)
                    elif pairer.answered(k):
                        # sent again after a restart downstream: the frame's cloud again, as it was
                        node.republish(keys.sfm_cloud(args.uav), message.stamp_ns)
                give_up_overdue()
            give_up_overdue()
    return 0
