"""tracker: per-scene detections fused along the orbit into confirmed targets with fused poses (ours).

For each Detections message (one per scene): associate its detections with the tracks in the world frame
(gated on position and heading), confirm a track after M hits in N scenes, fuse its position and heading
with a covariance, age and delete tracks (atr.tracking, docs/tracking.md). One Tracks message per
Detections message, stamped with its stamp_ns, listing every live track (an empty list when none lives).
No randomness: a replay gives byte-identical tracks. A scene it refuses (a stamp not after the previous
one) is reported on the errors key and leaves the tracks as they were — unless it is the first scene of a
flight (its pair starts at frame 0): a new flight, or a replay, whose clock starts again, gets a new
tracker. The Detections of the scene last
answered, sent again after a restart upstream, get that scene's Tracks again (the same message).

Example:
    atr service tracker --uav uav1 --set tracking.confirm_hits=3 --set tracking.confirm_window=5

"""

from __future__ import annotations

import logging
import time

from atr.tracking import Track, Tracker, TrackInput
from bus import keys
from bus.service import effective_config, service_arguments, start_node

log = logging.getLogger("atr")


def track_message(track: Track) -> dict:
    """One track as the Tracks schema lists it."""
    return {
        "id": track.id,
        "target": track.target,
        "state": track.state,
        "T_world_target": track.T_world_target,
        "covariance": track.covariance,
        "yaw_ambiguous": track.yaw_ambiguous,
        "hits": track.hits,
        "supporting_stamps_ns": list(track.supporting_stamps_ns),
        "first_seen_ns": track.first_seen_ns,
        "last_seen_ns": track.last_seen_ns,
    }


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    args = service_arguments("tracker", __doc__).parse_args(argv)
    tracker = Tracker(effective_config(args).tracking)
    with start_node("tracker", args, inputs=[keys.detections(args.uav)]) as node:
        node.ready()
        last_stamp_ns: int | None = None
        for message in node.events():
            with node.handling(message):
                if message.stamp_ns == last_stamp_ns:
                    node.republish(keys.tracks(args.uav), message.stamp_ns)
                    continue
                first_scene = list(message.data.get("frame_seqs", [])[:1]) == [0]
                if first_scene and last_stamp_ns is not None and message.stamp_ns < last_stamp_ns:
                    log.info(
                        "a new flight (its first scene, stamp %d ns): tracks start again",
                        message.stamp_ns,
                    )
                    tracker = Tracker(tracker.config)
                t0 = time.perf_counter()
                tracks = tracker.update(
                    [
                        TrackInput.from_pose(
                            d["target"],
                            d["T_world_target"],
                            d["score"],
                            message.data.get("viewpoint_m"),
                        )
                        for d in message.data["detections"]
                    ],
                    message.stamp_ns,
                )
                last_stamp_ns = message.stamp_ns
                elapsed_ms = 1e3 * (time.perf_counter() - t0)
                node.publish(
                    keys.tracks(args.uav),
                    {
                        "stamp_ns": message.stamp_ns,
                        "detections_seq": message.seq,
                        "tracks": [track_message(t) for t in tracks],
                    },
                )
                node.timing(message.seq, message.stamp_ns, {"update": elapsed_ms})
    return 0
