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
from scipy.stats import bootstrap

from atr.errors import InputError

MAX_TRANSLATION_ERROR_M = 2.0  # §III-C
INTERVAL_CONFIDENCE = 0.95
# bootstrap replicates; on 155 scenes the ends move by <= 0.004 across seeds
INTERVAL_RESAMPLES = 5000

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


def vehicle_under(
    position_m: np.ndarray,
    names: Sequence[str],
    vehicle_positions_m: np.ndarray,
    radii_m: np.ndarray,
) -> str:
    """The non-target vehicle a hypothesis sits on: what a false positive mistook for the target.

    Args:
        position_m: (3,) hypothesis position, metres.
        names: the V vehicles' names.
        vehicle_positions_m: (V, 3) their positions, metres.
        radii_m: (V,) their horizontal bounding radii, metres.

    Returns:
        The name of the nearest vehicle whose radius holds the position (horizontal distance), or "" when
        none does (a building, a tree, bare ground).

    """
    if len(names) == 0:
        return ""
    xy = np.asarray(vehicle_positions_m, np.float64).reshape(-1, 3)[:, :2]
    distance_m = np.linalg.norm(xy - np.asarray(position_m, np.float64)[:2], axis=1)
    nearest = int(np.argmin(distance_m))
    return str(names[nearest]) if distance_m[nearest] <= float(radii_m[nearest]) else ""


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


def f1_interval(
    outcomes: Sequence[Outcome],
    versus: Sequence[Outcome] | None = None,
    *,
    confidence: float = INTERVAL_CONFIDENCE,
    resamples: int = INTERVAL_RESAMPLES,
    seed: int = 0,
) -> tuple[float, float]:
    """Bootstrap interval of F1 over the scenes (percentile method, `scipy.stats.bootstrap`).

    The scenes are what varies: another world would give other scenes of the same flights. With
    `versus`, the interval of F1(outcomes) - F1(versus) for two arms that judged the same scenes,
    paired (each replicate draws the same scenes for both), so the scenes both find or both miss do
    not widen it. An interval of a difference that excludes 0 says the arms really differ on such
    scenes. Consecutive scenes of a flight are alike, so the intervals are if anything too narrow.

    Args:
        outcomes: one outcome per scene ("tp", "fp", "fn", "tn").
        versus: the other arm's outcomes on the same scenes, in the same order, or None.
        confidence: two-sided confidence level.
        resamples: bootstrap replicates.
        seed: seed of the replicates (the same seed gives the same interval).

    Returns:
        (low, high); (nan, nan) without scenes.

    Raises:
        InputError: `versus` has another number of scenes.

    """
    arms = [outcomes] if versus is None else [outcomes, versus]
    if versus is not None and len(versus) != len(outcomes):
        raise InputError(
            f"paired F1 interval needs the same scenes: {len(outcomes)} against {len(versus)}"
        )
    if len(outcomes) == 0:
        return float("nan"), float("nan")
    data = [
        (np.asarray(arm) == name).astype(np.float64) for arm in arms for name in ("tp", "fp", "fn")
    ]

    def statistic(*indicators: np.ndarray, axis: int = -1) -> np.ndarray:
        f1 = [_f1(*indicators[i : i + 3], axis=axis) for i in range(0, len(indicators), 3)]
        return f1[0] if len(f1) == 1 else f1[0] - f1[1]

    if all(np.ptp(d) == 0 for d in data):  # every scene alike: nothing to resample
        value = float(statistic(*data))
        return value, value
    result = bootstrap(
        data,
        statistic,
        paired=True,
        vectorized=True,
        method="percentile",
        confidence_level=confidence,
        n_resamples=resamples,
        rng=np.random.default_rng(seed),
    )
    return float(result.confidence_interval.low), float(result.confidence_interval.high)


def _f1(tp: np.ndarray, fp: np.ndarray, fn: np.ndarray, axis: int = -1) -> np.ndarray:
    """Eq. (5) of per-scene indicator arrays, along `axis`; NaN where nothing is scored."""
    t = tp.sum(axis=axis)
    denominator = 2 * t + fp.sum(axis=axis) + fn.sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(denominator > 0, 2 * t / denominator, np.nan)
