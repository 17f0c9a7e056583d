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


@dataclass(frozen=True)
class TrackScore:
    """Track-level figures of one flight (ours, beside the paper's per-scene F1).

    Attributes:
        counts: per scene, the confirmed tracks judged like detections (`score_scene`; the most
            supported track is the hypothesis): TP, FP, FN, TN totals.
        false_tracks: confirmed tracks that never lay within the TP bound of the target.
        scenes_to_confirm: scenes from the first scene with the target to the first TP, counting both
            (1: confirmed on the first scene; NaN: never, or no scene has the target).
        t_error_median_m: median position error of the TP scenes' tracks, metres (NaN without a TP).
        held_while_hidden: scenes counted TN whose best track held the target's true position while the
            target was hidden (below the visibility rule): a FP by the per-scene rule, a right claim
            for a track.

    """

    counts: Counts
    false_tracks: int
    scenes_to_confirm: float
    t_error_median_m: float
    held_while_hidden: int = 0


def score_tracks(
    true_positions_m: Sequence[Sequence[np.ndarray]],
    tracks: Sequence[Sequence[tuple[int, np.ndarray]]],
    *,
    hidden_positions_m: Sequence[Sequence[np.ndarray]] | None = None,
    max_error_m: float = MAX_TRANSLATION_ERROR_M,
) -> TrackScore:
    """Judge a flight's confirmed tracks scene by scene.

    The per-scene rule asks a scene to find only a target it sees (§III-C's "present"). A track claims
    where the vehicle *is*, and holds that place through occlusion: a scene whose best track lies within
    the TP bound of a target that is there but hidden is not a false positive but a TN
    (`held_while_hidden` counts them), and such a track is not a false track.

    Args:
        true_positions_m: per scene, (3,) positions of the target instances present (as `score_scene`).
        tracks: per scene, (track id, (3,) fused position) of the confirmed tracks for the target, most
            supported first.
        hidden_positions_m: per scene, (3,) positions of the target instances in the world but not
            present (below the visibility rule); None: none.
        max_error_m: translation error bound of a TP, metres (§III-C: 2 m).

    Returns:
        The flight's track-level figures.

    Raises:
        InputError: the sequences have different numbers of scenes.

    """
    hidden = hidden_positions_m if hidden_positions_m is not None else [[] for _ in tracks]
    if not len(true_positions_m) == len(tracks) == len(hidden):
        raise InputError(
            f"{len(true_positions_m)} scenes of truth, {len(hidden)} of hidden targets but "
            f"{len(tracks)} of tracks"
        )

    def near(p: np.ndarray, targets: Sequence[np.ndarray]) -> bool:
        return any(np.linalg.norm(np.asarray(p) - np.asarray(t)) < max_error_m for t in targets)

    scores, confirmed, true_ids = [], set(), set()
    first_target = first_tp = None
    held = 0
    for k, (truth, scene_tracks, scene_hidden) in enumerate(
        zip(true_positions_m, tracks, hidden, strict=True)
    ):
        score = score_scene(truth, [p for _, p in scene_tracks], max_error_m=max_error_m)
        if score.outcome == "fp" and not truth and near(scene_tracks[0][1], scene_hidden):
            score = SceneScore("tn", float("nan"), False)
            held += 1
        scores.append(score)
        if truth and first_target is None:
            first_target = k
        if score.outcome == "tp" and first_tp is None:
            first_tp = k
        for track_id, p in scene_tracks:
            confirmed.add(track_id)
            if near(p, [*truth, *scene_hidden]):
                true_ids.add(track_id)
    errors = [s.translation_error_m for s in scores if s.outcome == "tp"]
    return TrackScore(
        counts=count(scores),
        false_tracks=len(confirmed - true_ids),
        scenes_to_confirm=float(first_tp - first_target + 1)
        if first_target is not None and first_tp is not None
        else float("nan"),
        t_error_median_m=float(np.median(errors)) if errors else float("nan"),
        held_while_hidden=held,
    )
