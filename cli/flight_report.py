"""Per-scene lines and the F1 of a simulated flight, for `atr demo` and `atr run` users (no bus logic).

A scene is judged exactly as `atr eval` judges it (`atr.evaluation.scoring.score_record`): relative to the
sensor, so that the pose integrator's drift over a long flight is not counted as recognition error.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from atr.evaluation.metrics import Counts, SceneScore, TrackScore, count, score_tracks
from atr.evaluation.scoring import score_record
from bus.evaluation import scene_record

TARGET = "t72"


def score(
    truth: dict | None, detections: dict, camera_pose: dict | None = None, target: str = TARGET
) -> SceneScore:
    """Judge one scene from its Truth, Detections and (SfM) CameraPose messages, as `atr eval` does."""
    # The truth lists only the targets present in the scene (sensor_source applies the visibility rule
    # with the flight's own threshold), so every listed target counts here.
    return score_record(
        scene_record(truth, detections, camera_pose), target, present_min_visible_fraction=0.0
    )


def scene_line(
    truth: dict | None, detections: dict, camera_pose: dict | None = None, target: str = TARGET
) -> str:
    """One human line: frames, what was recognised where, and the verdict against truth."""
    frames = "-".join(str(f) for f in detections.get("frame_seqs", []))
    found = (
        ", ".join(
            f"{d['target']} at ({d['T_world_target'][0][3]:.1f}, {d['T_world_target'][1][3]:.1f}) "
            f"overlap {d['overlap']:.2f}"
            for d in detections["detections"]
        )
        or "nothing"
    )
    verdict = score(truth, detections, camera_pose, target)
    visible = max((t["visible_fraction"] for t in (truth or {}).get("targets", [])), default=0.0)
    error = (
        f", error {verdict.translation_error_m:.2f} m"
        if np.isfinite(verdict.translation_error_m)
        else ""
    )
    return f"scene {frames:>7}: {found:<58} | target visible {visible:4.0%} -> {verdict.outcome.upper()}{error}"


def is_scene(detections: dict[str, Any]) -> bool:
    """A Detections message answers a scene when its cloud came from a pair (a first frame has none)."""
    return len(detections.get("frame_seqs", [])) == 2


class FlightPrinter:
    """Prints a line per scene as detections arrive, judged for the flight's target."""

    def __init__(self, target: str = TARGET) -> None:
        self._watch = None
        self._target = target

    def attach(self, session: object) -> None:
        """Start printing from a bus session."""
        from bus.pipeline import FlightWatch

        print("flying; one line per scene:", flush=True)
        self._watch = FlightWatch(session, "uav1", self._print)

    def _print(self, truth: dict | None, detections: dict, camera_pose: dict | None) -> None:
        if is_scene(detections):
            print(scene_line(truth, detections, camera_pose, self._target), flush=True)

    def detach(self) -> None:
        """Stop printing."""
        if self._watch is not None:
            self._watch.close()


def flight_target(scenes: list[tuple[dict | None, dict, dict | None]]) -> str:
    """The target of a recorded simulated flight: the vehicle its Truth messages list (T-72 if none)."""
    names = [t["name"] for truth, _, _ in scenes for t in (truth or {}).get("targets", [])]
    return names[0] if names else TARGET


def summarise(path: Path, target: str | None = None) -> Counts | None:
    """TP/FP/FN/TN of a recorded simulated flight; None when there is nothing to judge: no scene was
    answered, or the recording carries no truth (a real flight). The target is the one the truth
    lists unless given.

    Scenes without a pair (empty first clouds) are not scenes.
    """
    from bus.pipeline import flight_scenes

    scenes = [(t, d, c) for t, d, c in flight_scenes(path) if is_scene(d)]
    if not scenes:
        print("no scene was answered; see the logs", file=sys.stderr)
        return None
    if all(t is None for t, _, _ in scenes):
        return None
    target = target or flight_target(scenes)
    return count([score(t, d, c, target) for t, d, c in scenes])


def summarise_tracks(path: Path, target: str | None = None) -> TrackScore | None:
    """The track-level figures of a recorded simulated flight (its tracker's Tracks messages), judged as
    `atr eval` judges tracks (`atr.evaluation.metrics.score_tracks`): per scene the target's confirmed and
    lost tracks, placed relative to the sensor as detections are; None without truth or without tracks.
    """
    from bus.pipeline import flight_scenes, flight_tracks

    tracks_by_stamp = flight_tracks(path)
    scenes = [(t, d, c) for t, d, c in flight_scenes(path) if is_scene(d) and t is not None]
    if not scenes or not tracks_by_stamp:
        return None
    target = target or flight_target(scenes)
    truth, tracks = [], []
    for t, d, c in scenes:
        record = scene_record(t, d, c)
        truth.append([np.asarray(p["position_m"]) for p in record.truth if p["name"] == target])
        established = [
            track
            for track in tracks_by_stamp.get(d["stamp_ns"], {}).get("tracks", [])
            if track["target"] == target and track["state"] != "tentative"
        ]
        established.sort(key=lambda track: (-track["hits"], track["id"]))
        tracks.append(
            [
                (track["id"], record.sensor_relative(np.asarray(track["T_world_target"])[:3, 3]))
                for track in established
            ]
        )
    return score_tracks(truth, tracks)


def track_line(score: TrackScore) -> str:
    """The flight's confirmed tracks in one line, beside the paper's per-scene F1."""
    counts = score.counts
    confirm = (
        f"confirmed on the target's scene {score.scenes_to_confirm:.0f}"
        if np.isfinite(score.scenes_to_confirm)
        else "the target never confirmed"
    )
    error = (
        f", fused error {score.t_error_median_m:.2f} m (median)"
        if np.isfinite(score.t_error_median_m)
        else ""
    )
    return (
        f"tracks: F1 {counts.f1:.3f} (TP {counts.tp}, FP {counts.fp}, FN {counts.fn}), "
        f"{score.false_tracks} false confirmed tracks, {confirm}{error}"
    )


def f1_line(counts: Counts) -> str:
    """The flight's result in one line: F1 (eq. 5) and its counts."""
    return (
        f"F1 {counts.f1:.3f} (TP {counts.tp}, FP {counts.fp}, FN {counts.fn}, TN {counts.tn}) over "
        f"{counts.tp + counts.fp + counts.fn + counts.tn} scenes"
    )
