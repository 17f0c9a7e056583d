"""atr_matcher: the online 3D ATR module (§II-B-2) — a scene cloud in, the recognised targets and poses out.

For each PointCloud (SfM by default, or the LIDAR baseline with `pipeline.cloud_source=lidar`): uniform
subsampling at 0.3 m, smooth-surface filtering, description with the templates' descriptor, kNNDR matching,
geometric-consistency grouping, RANSAC per group, ICP verification (with `tracking.guided_search`, between
whole-cloud searches it only confirms the targets it already tracks: atr.tracking.guided_search; after each
cloud it publishes on atr/{uav}/guidance the regions around the tracks it holds, and a cloud that says where
the sfm matched it, in such regions or whole, is searched there; with `tracking.whole_search_lag_frames`
the whole searches run in a worker process of their own and their detections join a later scene's,
atr.tracking.lane). One Detections
message per cloud, stamped with the cloud's stamp_ns (an empty list when nothing is accepted). RANSAC is seeded from the cloud's last
frame_seq, so a replay gives byte-identical detections (whatever clouds were lost before). A cloud put again
(the same seq from the same sfm, after a restart elsewhere) gets no second answer. Templates come from
template_store over the bus (fetched once).
A restarted process reports the cloud a killed one had in hand (its frame is answered) and goes on.

Example:
    atr service atr_matcher --uav uav1 --set recognition.descriptor=fpfh
    atr service atr_matcher --set pipeline.cloud_source=lidar

"""

from __future__ import annotations

import logging
from collections import deque
from contextlib import nullcontext

import numpy as np

from atr.recognition import Template, warm_up
from atr.recognition.template import template_from_message
from atr.regions import regions_from_array, regions_to_array
from atr.tracking.guided_search import GuidedSearch
from atr.tracking.lane import ProcessLane
from bus import keys
from bus.clouds import cloud_points
from bus.service import effective_config, service_arguments, start_node

log = logging.getLogger("atr")


def _detection(detection: object) -> dict:
    return detection.to_dict() | {
        "T_world_target": np.asarray(detection.T_world_target, np.float64)
    }


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    args = service_arguments("atr_matcher", __doc__, keeps="journal").parse_args(argv)
    config = effective_config(args)
    pipeline, recognition = config.pipeline, config.recognition
    source_key = (
        keys.sfm_cloud(args.uav) if pipeline.cloud_source == "sfm" else keys.lidar(args.uav)
    )
    targets = list(pipeline.targets) + [
        p.rsplit("/", 1)[-1].rsplit(".", 1)[0] for p in pipeline.target_meshes
    ]
    templates: list[Template] = []
    search: GuidedSearch | None = (
        None  # recognize, with track-guided search when tracking.guided_search
    )
    answered: deque[tuple[str | None, int]] = deque(maxlen=64)  # (source, seq) of the last clouds
    tracking = config.tracking
    # whole searches that answer late run in a process of their own, so guided scenes never wait
    lagged = tracking.guided_search and tracking.whole_search_lag_frames > 0
    with (
        start_node("atr_matcher", args, inputs=[source_key]) as node,
        ProcessLane() if lagged else nullcontext() as lane,
    ):
        if lane is not None:
            # before the first scene: warming beside it took a core from the flight's first whole searches
            lane.warm(recognition).result()
        warm_up(recognition)  # the first scene would pay for it: its latency, and every next one's
        node.ready()
        for message in node.events():
            with node.handling(message):
                if (
                    not templates
                ):  # a failed fetch is reported for this cloud and retried on the next
                    templates = [
                        template_from_message(
                            node.get(
                                keys.template(t, recognition.descriptor),
                                pipeline.template_timeout_s,
                            )
                        )
                        for t in targets
                    ]
                cloud = message.data
                if (message.source, message.seq) in answered:
                    # a cloud sent again after a restart: its answer again, the same message
                    node.republish(keys.detections(args.uav), message.stamp_ns)
                    continue
                if search is None:
                    search = GuidedSearch(templates, recognition, tracking, lane)
                sigma = cloud.get("sigma_m")
                result = search(
                    cloud_points(cloud).astype(np.float64),
                    seed=int(cloud["frame_seqs"][-1]),  # the frame, whatever clouds were lost
                    stamp_ns=message.stamp_ns,
                    frame_seq=int(cloud["frame_seqs"][-1]),
                    viewpoint_m=cloud.get("viewpoint_m"),
                    scene_sigma_m=None if sigma is None else np.asarray(sigma, np.float64),
                    # where the sfm matched the pair, when it decided (it keeps the schedule then)
                    cloud_regions=regions_from_array(cloud["regions_m"])
                    if "regions_m" in cloud
                    else None,
                )
                if tracking.guided_search:
                    # before the Detections: in lock-step the sfm has it before the next frame
                    node.publish(
                        keys.guidance(args.uav),
                        {
                            "stamp_ns": message.stamp_ns,
                            "regions_m": regions_to_array(search.held_regions() or []),
                        },
                    )
                answer = {
                    "stamp_ns": message.stamp_ns,
                    "cloud_seq": message.seq,
                    "frame_seqs": list(cloud["frame_seqs"]),
                    "source": cloud["source"],
                    "detections": [_detection(d) for d in result.detections],
                }
                if "viewpoint_m" in cloud:  # where the tracker sees each detection from
                    answer["viewpoint_m"] = cloud["viewpoint_m"]
                node.publish(keys.detections(args.uav), answer)
                answered.append((message.source, message.seq))
                node.timing(message.seq, message.stamp_ns, result.stage_times_ms)
                if (waited_ms := result.stage_times_ms.get("join_wait", 0.0)) > 0.0:
                    log.warning(
                        "the scene of frame %d waited %.0f ms for the whole search of frame %d; "
                        "at the camera's pace (not in a lock-step replay, whose frames wait for "
                        "every answer) tracking.whole_search_lag_frames=%d is too short for this "
                        "machine at this frame rate (docs/performance.md, the service graph)",
                        int(cloud["frame_seqs"][-1]),
                        waited_ms,
                        result.stats["joined_whole_search_of_frame"],
                        tracking.whole_search_lag_frames,
                    )
    return 0
