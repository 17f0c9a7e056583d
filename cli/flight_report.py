"""Per-scene lines and the F1 of a simulated flight, for `atr demo` and `atr run` users (no bus logic)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from atr.evaluation.metrics import Counts, SceneScore, count, score_scene

TARGET = "t72"


def score(truth: dict | None, detections: dict, target: str = TARGET) -> SceneScore:
    """Judge one scene from its Truth and Detections messages."""
    # The truth lists only the targets present in the scene (sensor_source applies the visibility rule).
    true_positions = [
        np.asarray(t["T_world_target"])[:3, 3]
        for t in (truth or {}).get("targets", [])
        if t["name"] == target
    ]
    hypotheses = sorted(
        (d for d in detections["detections"] if d["target"] == target), key=lambda d: -d["score"]
    )
    return score_scene(true_positions, [np.asarray(d["T_world_target"])[:3, 3] for d in hypotheses])


def scene_line(truth: dict | None, detections: dict) -> str:
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
    verdict = score(truth, detections)
    visible = max((t["visible_fraction"] for t in (truth or {}).get("targets", [])), default=0.0)
    error = (
        f", error {verdict.translation_error_m:.2f} m"
        if np.isfinite(verdict.translation_error_m)
        else ""
    )
    return f"scene {frames:>7}: {found:<58} | target visible {visible:4.0%} -> {verdict.outcome.upper()}{error}"


class FlightPrinter:
    """Prints a line per scene as detections arrive."""

    def __init__(self) -> None:
        self._watch = None

    def attach(self, session: object) -> None:
        """Start printing from a bus session."""
        from bus.pipeline import FlightWatch  # noqa: PLC0415

        print("flying; one line per scene:", flush=True)
        self._watch = FlightWatch(session, "uav1", self._print)

    @staticmethod
    def _print(truth: dict | None, detections: dict) -> None:
        if (
            len(detections.get("frame_seqs", [])) == 2
        ):  # a first frame without a partner is no scene
            print(scene_line(truth, detections), flush=True)

    def detach(self) -> None:
        """Stop printing."""
        if self._watch is not None:
            self._watch.close()


def summarise(path: Path) -> Counts:
    """TP/FP/FN/TN of a recorded flight; scenes without a pair (empty first clouds) are not scenes."""
    from bus.pipeline import flight_scenes  # noqa: PLC0415

    scenes = [(t, d) for t, d in flight_scenes(path) if len(d.get("frame_seqs", [])) == 2]
    if not scenes:
        print("no scene was answered; see the logs", file=sys.stderr)
    return count([score(t, d) for t, d in scenes])
