"""Track-level scoring: confirmed tracks judged like detections, false tracks, time to confirmation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atr.errors import InputError
from atr.evaluation.metrics import score_tracks
from atr.evaluation.runner import SceneRecord
from atr.evaluation.tables import track_score
from atr.tracking import TrackingConfig

TARGET = np.array([5.0, 5.0, 0.0])


def test_score_tracks_counts_scenes_false_tracks_and_confirmation_time():
    truth = [[], [TARGET], [TARGET], [TARGET], [TARGET], []]
    tracks = [
        [],
        [],  # not confirmed yet: FN
        [(1, TARGET + [0.3, 0, 0])],  # TP, confirmed on the 2nd scene with the target
        [(1, TARGET + [0.1, 0, 0]), (2, TARGET + [40, 0, 0])],  # TP; track 2 a false track
        [(2, TARGET + [40, 0, 0])],  # FP
        [(1, TARGET)],  # no target present: FP
    ]
    s = score_tracks(truth, tracks)
    assert (s.counts.tp, s.counts.fp, s.counts.fn, s.counts.tn) == (2, 2, 1, 1)
    assert s.false_tracks == 1 and s.scenes_to_confirm == 2.0
    assert s.t_error_median_m == pytest.approx(0.2)
    never = score_tracks([[TARGET]], [[]])
    assert math.isnan(never.scenes_to_confirm) and never.false_tracks == 0
    with pytest.raises(InputError, match="scenes"):
        score_tracks([[TARGET]], [])


def _record(k: int, detections: list[list[float]], error: str | None = None) -> SceneRecord:
    return SceneRecord(
        frame=k,
        stamp_ns=1_000_000_000 + k * 500_000_000,
        truth=[{"name": "t72", "position_m": TARGET.tolist(), "visible_fraction": 1.0}],
        detections=[{"target": "t72", "position_m": p, "score": 0.5} for p in detections],
        time_ms=1.0,
        error=error,
    )


def test_track_score_runs_the_tracker_over_a_flight_and_beats_clutter():
    rng = np.random.default_rng(0)
    records = []
    for k in range(40):
        ds = [] if k % 5 == 4 else [(TARGET + rng.normal(0, 0.4, 3)).tolist()]
        ds.append(rng.uniform(-80, 80, 3).tolist())  # clutter every scene, never twice in one place
        records.append(_record(k, ds, "SchemaError: x" if k == 20 else None))
    s = track_score(records, "t72", 0.05, TrackingConfig())
    # clutter never recurs at one place: no false track; the tracks are right from scene 2 on
    assert (s.counts.tp, s.counts.fp, s.counts.fn) == (39, 0, 1)
    assert s.false_tracks == 0 and s.scenes_to_confirm == 2.0
    assert s.t_error_median_m < 0.4


def test_a_track_holding_a_hidden_target_is_a_tn_and_a_track_elsewhere_stays_an_fp():
    truth = [[TARGET], [], [], []]
    hidden = [[], [TARGET], [TARGET], []]  # the target behind a building, then gone from the world
    tracks = [[(1, TARGET)], [(1, TARGET + [0.5, 0, 0])], [(2, TARGET + [9, 0, 0])], [(1, TARGET)]]
    s = score_tracks(truth, tracks, hidden_positions_m=hidden)
    assert (s.counts.tp, s.counts.fp, s.counts.fn, s.counts.tn) == (1, 2, 0, 1)
    assert s.held_while_hidden == 1
    assert s.false_tracks == 1  # track 2 never lay at the target, visible or not
    strict = score_tracks(truth, tracks)  # without the hidden instances: the per-scene rule
    assert (strict.counts.fp, strict.held_while_hidden) == (3, 0)
    with pytest.raises(InputError, match="hidden"):
        score_tracks(truth, tracks, hidden_positions_m=hidden[:2])


def test_track_score_feeds_headings_relative_to_the_sensor_and_holds_an_occluded_target():
    def flight(yaw_of_scene) -> list[SceneRecord]:
        records = []
        for k in range(12):
            visible = 0.0 if 6 <= k < 9 else 1.0  # occluded for three scenes: no detection there
            r = _record(k, [] if visible == 0.0 else [TARGET.tolist()])
            r.truth[0]["visible_fraction"] = visible
            for d in r.detections:
                d["yaw_rad"] = yaw_of_scene(k)
            records.append(r)
        return records

    steady = track_score(flight(lambda k: 0.3), "t72", 0.5, TrackingConfig())
    # confirmed on the 2nd scene; the lost track coasts through the occlusion at the right place
    assert (steady.counts.tp, steady.counts.fp, steady.counts.fn) == (8, 0, 1)
    assert steady.held_while_hidden == 3 and steady.false_tracks == 0
    # the heading reaches the tracker: one 180 degrees off is not associated until the flip evidence
    # folds the track's heading, so confirmation waits a scene (unless such a detection is a hit
    # of the vehicle at its place, as by default)
    flipping = track_score(
        flight(lambda k: 0.3 if k % 2 else 0.3 - np.pi),
        "t72",
        0.5,
        TrackingConfig(place_hits=False),
    )
    assert (flipping.counts.tp, flipping.counts.fp, flipping.counts.fn) == (7, 0, 2)
