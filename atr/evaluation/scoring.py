"""Score SceneRecords with the paper's metric (§III-C, `atr.evaluation.metrics`); summarise runs.

The rules are the demo's (cli/flight_report.py): a scene has the target when the target's visible fraction
reaches `SimConfig.present_min_visible_fraction`; only detections labelled with the target's name are
hypotheses, and the best-scoring one is judged. Positions are compared relative to the sensor
(`SceneRecord.sensor_relative`): the navigation error of the pipeline's camera pose is reported apart
(`RunSummary.nav_error_median_m`), not counted as translation error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from atr.evaluation.metrics import Counts, SceneScore, count, score_scene
from atr.evaluation.runner import SceneRecord
from atr.sim.config import SimConfig


def score_record(
    record: SceneRecord,
    target: str,
    present_min_visible_fraction: float | None = None,
) -> SceneScore:
    """Judge one scene.

    Args:
        record: the scene's truth and detections.
        target: the target's name.
        present_min_visible_fraction: visibility at which a scene has the target (default: the simulator's).

    """
    present = (
        SimConfig().present_min_visible_fraction
        if present_min_visible_fraction is None
        else present_min_visible_fraction
    )
    true_positions = [
        np.asarray(t["position_m"], np.float64)
        for t in record.truth
        if t["name"] == target and t["visible_fraction"] >= present
    ]
    hypotheses = sorted(
        (d for d in record.detections if d["target"] == target), key=lambda d: -d["score"]
    )
    return score_scene(
        true_positions, [record.sensor_relative(d["position_m"]) for d in hypotheses]
    )


@dataclass(frozen=True)
class RunSummary:
    """TP/FP/FN/TN, F1, translation errors and time of one run of one arm.

    Attributes:
        counts: the outcome totals; counts.f1 is eq. (5).
        t_errors_m: translation errors of the TP scenes, metres (T_error of §III-D-4, Fig. 9).
        t_error_median_m: their median (NaN without a TP).
        time_per_scene_ms: median processing time per scene, milliseconds.
        stages_ms: median per-stage time, milliseconds.
        scenes: scenes scored.
        scenes_with_target: scenes that have the target.
        errors: scenes where a stage raised a typed error (no answer).
        nav_error_median_m: median distance between the pipeline's and the true camera position
            (0 for the baselines, which use the true pose; NaN when unknown).
        outcomes: every scene's outcome ("tp", "fp", "fn", "tn"), in scene order (what the report's
            bootstrap intervals resample).

    """

    counts: Counts
    t_errors_m: tuple[float, ...]
    t_error_median_m: float
    time_per_scene_ms: float
    stages_ms: dict[str, float]
    scenes: int
    scenes_with_target: int
    errors: int
    nav_error_median_m: float = float("nan")
    outcomes: tuple[str, ...] = ()


def summarise(
    records: Sequence[SceneRecord], target: str, present_min_visible_fraction: float | None = None
) -> RunSummary:
    """Score every scene of a run and summarise it."""
    scores = [score_record(r, target, present_min_visible_fraction) for r in records]
    t_errors = tuple(float(s.translation_error_m) for s in scores if s.outcome == "tp")
    stage_names = sorted({name for r in records for name in r.stages_ms})
    return RunSummary(
        counts=count(scores),
        t_errors_m=t_errors,
        t_error_median_m=float(np.median(t_errors)) if t_errors else float("nan"),
        time_per_scene_ms=float(np.median([r.time_ms for r in records]))
        if records
        else float("nan"),
        stages_ms={
            n: float(np.median([r.stages_ms.get(n, 0.0) for r in records])) for n in stage_names
        },
        scenes=len(records),
        scenes_with_target=sum(s.has_target for s in scores),
        errors=sum(r.error is not None for r in records),
        nav_error_median_m=float(np.median([r.nav_error_m for r in records]))
        if records
        else float("nan"),
        outcomes=tuple(s.outcome for s in scores),
    )
