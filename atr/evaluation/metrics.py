"""The paper's performance metric (§III-C): F1 with the translation-error constraint.

- TP: a hypothesis for the target in a scene that has the target, with translation error < 2 m.
- FP: a hypothesis in a scene without the target, or with translation error >= 2 m.
- FN: no hypothesis in a scene that has the target.
A scene "has the target" when its visible fraction reaches `present_min_visible_fraction` (the simulator's
rule, docs/sim.md). A hypothesis is a detection labelled with the target's name; detections of other vehicles
(confusers recognised as what they are) are not hypotheses for the target.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

MAX_TRANSLATION_ERROR_M = 2.0  # §III-C

Outcome = Literal["tp", "fp", "fn", "tn"]


@dataclass(frozen=True)
class SceneScore:
    """How one scene was judged.

    Attributes:
        outcome: "tp", "fp" (a hypothesis without target, or >= 2 m off the target), "fn", or "tn".
        translation_error_m: distance between the true and estimated target positions (NaN without both).
        has_target: the scene has the target.

    """

    outcome: Outcome
    translation_error_m: float
    has_target: bool


def score_scene(
    true_positions_m: Sequence[np.ndarray],
    hypothesis_positions_m: Sequence[np.ndarray],
    *,
    max_error_m: float = MAX_TRANSLATION_ERROR_M,
) -> SceneScore:
    """Judge one scene.

    Args:
        true_positions_m: (3,) positions of the target instances present in the scene (empty: no target).
        hypothesis_positions_m: (3,) positions of the hypotheses for the target, best first; the best one
            is judged (the matcher reports at most one per location).
        max_error_m: translation error bound of a TP, metres (§III-C: 2 m).

    Returns:
        The scene's score.

    """
    has_target = len(true_positions_m) > 0
    if not hypothesis_positions_m:
        return SceneScore("fn" if has_target else "tn", float("nan"), has_target)
    if not has_target:
        return SceneScore("fp", float("nan"), False)
    best = np.asarray(hypothesis_positions_m[0], np.float64)
    error = min(float(np.linalg.norm(best - np.asarray(t, np.float64))) for t in true_positions_m)
    return SceneScore("tp" if error < max_error_m else "fp", error, True)


@dataclass(frozen=True)
class Counts:
    """TP, FP, FN totals over scenes, and the F1 score of eq. (5)."""

    tp: int = 0
    fp: int = 0
    fn: int = 0
    tn: int = 0

    @property
    def f1(self) -> float:
        """F1 = 2TP / (2TP + FP + FN); NaN when there is nothing to score."""
        denominator = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / denominator if denominator else float("nan")


def count(scores: Sequence[SceneScore]) -> Counts:
    """Totals of a list of scene scores."""
    outcomes = [s.outcome for s in scores]
    return Counts(*(outcomes.count(o) for o in ("tp", "fp", "fn", "tn")))
