"""Which template a scene place belongs to: templates compete for the scene vertices they contest (ours).

The paper matches one template and accepts a hypothesis on its overlap alone (§II-B-2). With a family of
templates, several verified hypotheses of different vehicles sit on one place, and the place must go to
the template that fits it best. Counting the overlapping vertices favours the larger template (more
vertices land near a vehicle-sized blob); the share of its own vertices the scene supports favours the
smaller one (a car fits inside a tank). PCL's global hypothesis verification weighs both sides, the model
explained by the scene and the scene explained by the model; this is that idea per place:

- the place is the candidates whose centres lie within ``nms_m`` (or half the larger target's extent) of
  the strongest candidate, and the contested scene vertices are those inside any of their boxes (above
  the ground slab);
- *support*: the share of the template's visible vertices with a scene vertex near them (the overlap
  ``verify_with_icp`` measured);
- *explanation*: the share of the contested scene vertices within the overlap distance of the template's
  surface. Not widened by the vertices' sigma as the clutter measure is: at 100 m that reach lets any
  vehicle-sized template explain any vehicle-sized blob, and the shape's detail is what tells them apart;
- the place goes to the candidate with the highest harmonic mean of the two (an F-measure).

Measured in docs/recognition.md ("Which template a place belongs to") and docs/evaluation/targets.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from atr.recognition.steps import PointSet, inside_model_box


@dataclass(frozen=True)
class Candidate:
    """One verified, accepted hypothesis, as the place competition sees it.

    Attributes:
        target: the template's target name.
        model: the template's whole model in its own frame (its kd-tree answers "near the surface").
        box_lo_m, box_hi_m: (3,) corners of the model's box in its own frame.
        T_scene_model: (4, 4) pose after ICP.
        centre_m: (3,) the placed model's centroid, scene frame.
        extent_m: the model's extent (``model_extent_m``), metres.
        support: share of the hypothesis's visible model vertices the scene supports (its overlap).
        strength: supported vertices x (1 - clutter): orders the places, strongest first.

    """

    target: str
    model: PointSet
    box_lo_m: np.ndarray
    box_hi_m: np.ndarray
    T_scene_model: np.ndarray
    centre_m: np.ndarray
    extent_m: float
    support: float
    strength: float


@dataclass(frozen=True)
class CompetitionSettings:
    """Distances of the place competition (``compete_for_places``).

    Attributes:
        nms_m: candidates closer than max(this, half the larger extent) are at one place, metres.
        overlap_m: a scene vertex is explained within this distance of the model's surface, metres.
        ground_slab_m: the bottom of each box ignored (the ground is never part of a model), metres.

    """

    nms_m: float
    overlap_m: float
    ground_slab_m: float


def compete_for_places(
    candidates: Sequence[Candidate], scene: PointSet, settings: CompetitionSettings
) -> list[tuple[int, float]]:
    """Give each place to the candidate that explains it best.

    Args:
        candidates: the accepted hypotheses of every template.
        scene: the scene vertices the hypotheses were verified on.
        settings: place and explanation distances.

    Returns:
        (candidate index, score) of each place's winner, strongest place first; score is the F-measure
        of support and explanation, in [0, 1].

    """
    order = sorted(range(len(candidates)), key=lambda i: -candidates[i].strength)
    taken = np.zeros(len(candidates), bool)
    winners: list[tuple[int, float]] = []
    for seed in order:
        if taken[seed]:
            continue
        members = [
            i
            for i in order
            if not taken[i] and _same_place(candidates[seed], candidates[i], settings)
        ]
        taken[members] = True
        idx = np.unique(
            np.concatenate([_inside(candidates[i], scene, settings.ground_slab_m) for i in members])
        )
        # each template's strongest pose here enters (the paper's overlap picks among one template's poses)
        entrants: list[int] = []
        for i in members:  # strongest first
            if all(candidates[j].target != candidates[i].target for j in entrants):
                entrants.append(i)
        scores = [_f_measure(candidates[i], scene, idx, settings) for i in entrants]
        best = int(np.argmax(scores))  # the first of equals: the stronger candidate
        winners.append((entrants[best], scores[best]))
    return winners


def _same_place(a: Candidate, b: Candidate, settings: CompetitionSettings) -> bool:
    return same_place(a.centre_m, b.centre_m, max(a.extent_m, b.extent_m), settings.nms_m)


def same_place(a_m: np.ndarray, b_m: np.ndarray, extent_m: float, nms_m: float) -> bool:
    """Whether two vehicles placed at these points are at one place: closer than ``nms_m`` or half the
    larger one's extent, whichever is more.
    """
    return bool(np.linalg.norm(np.asarray(a_m) - np.asarray(b_m)) < max(nms_m, 0.5 * extent_m))


def _inside(c: Candidate, scene: PointSet, ground_slab_m: float) -> np.ndarray:
    """Indices of the scene vertices inside the candidate's box, above its ground slab."""
    lo, hi = c.box_lo_m, c.box_hi_m
    R, t = c.T_scene_model[:3, :3], c.T_scene_model[:3, 3]
    near = scene.tree.query_ball_point(
        R @ (0.5 * (lo + hi)) + t, 0.5 * float(np.linalg.norm(hi - lo))
    )
    near = np.asarray(sorted(near), np.int64)
    inside = inside_model_box(scene.points_m[near], c.T_scene_model, lo, hi, ground_slab_m)
    return near[inside]


def _f_measure(
    c: Candidate, scene: PointSet, idx: np.ndarray, settings: CompetitionSettings
) -> float:
    """Harmonic mean of the candidate's support and its share of the contested vertices explained."""
    explanation = 0.0
    if len(idx):
        R, t = c.T_scene_model[:3, :3], c.T_scene_model[:3, 3]
        local = (scene.points_m[idx] - t) @ R  # R^T (p - t): into the model frame
        d, _ = c.model.tree.query(local, distance_upper_bound=settings.overlap_m)
        explanation = float(np.mean(np.isfinite(d)))
    total = c.support + explanation
    return 2.0 * c.support * explanation / total if total > 0 else 0.0
