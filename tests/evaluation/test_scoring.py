"""Scoring of scene records follows §III-C: TP needs the target and T_error < 2 m, FP is a hypothesis without
target or >= 2 m off, FN no hypothesis where the target is; only hypotheses named as the target count."""

from __future__ import annotations

import math

from atr.evaluation.runner import SceneRecord
from atr.evaluation.scoring import score_record, summarise

TRUTH = [{"name": "t72", "position_m": [10.0, 5.0, 0.0], "visible_fraction": 0.8}]
HIDDEN = [{"name": "t72", "position_m": [10.0, 5.0, 0.0], "visible_fraction": 0.05}]


def record(truth, detections, time_ms=10.0):
    return SceneRecord(1, 1, truth, detections, time_ms)


def hyp(x, y, target="t72", score=1.0):
    return {"target": target, "position_m": [x, y, 0.0], "score": score}


def test_tp_needs_error_below_two_metres():
    assert score_record(record(TRUTH, [hyp(11.0, 5.0)]), "t72").outcome == "tp"
    assert score_record(record(TRUTH, [hyp(12.5, 5.0)]), "t72").outcome == "fp"


def test_hypothesis_without_visible_target_is_fp_and_silence_is_tn():
    assert score_record(record(HIDDEN, [hyp(10.0, 5.0)]), "t72").outcome == "fp"
    assert score_record(record(HIDDEN, []), "t72").outcome == "tn"
    assert score_record(record([], []), "t72").outcome == "tn"


def test_no_hypothesis_for_present_target_is_fn():
    assert score_record(record(TRUTH, []), "t72").outcome == "fn"


def test_other_vehicle_names_are_not_hypotheses_and_best_score_is_judged():
    assert score_record(record(TRUTH, [hyp(10.0, 5.0, "ifv")]), "t72").outcome == "fn"
    far_best = [hyp(30.0, 5.0, score=5.0), hyp(10.0, 5.0, score=1.0)]
    assert score_record(record(TRUTH, far_best), "t72").outcome == "fp"


def test_summary_f1_and_median_error():
    records = [
        record(TRUTH, [hyp(10.5, 5.0)], 5.0),
        record(TRUTH, [hyp(11.0, 5.0)], 7.0),
        record(TRUTH, []),
        record(HIDDEN, [hyp(0.0, 0.0)], 9.0),
    ]
    s = summarise(records, "t72")
    assert (s.counts.tp, s.counts.fp, s.counts.fn) == (2, 1, 1)
    assert math.isclose(s.counts.f1, 4 / 6)  # eq. (5): 2TP / (2TP + FP + FN)
    assert math.isclose(s.t_error_median_m, 0.75)
    assert s.scenes == 4 and s.scenes_with_target == 3
    assert math.isclose(s.time_per_scene_ms, 8.0)  # median of 5, 7, 10, 9 ms


def _pose(yaw_deg, x, y, z):
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return [[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]]


def test_translation_error_is_relative_to_the_sensor():
    """A pipeline whose camera pose drifted 3 m places the target as far off as its camera: the
    detection is right relative to the sensor (TP, ~0 m); the drift is the navigation error, reported apart."""
    T_true = _pose(30.0, 0.0, -40.0, 30.0)
    T_est = _pose(30.0, 3.0, -40.0, 30.0)
    probe = SceneRecord(1, 1, TRUTH, [], 10.0, T_world_cam_true=T_true, T_world_cam_est=T_est)
    # where a perfect matcher working in the drifted frame puts the target: est_cam . true_cam^-1 . truth
    p_true = [10.0, 5.0, 0.0]
    inverse = SceneRecord(1, 1, TRUTH, [], 10.0, T_world_cam_true=T_est, T_world_cam_est=T_true)
    placed = inverse.sensor_relative(p_true)
    assert math.dist(placed, p_true) > 2.0
    drifted = SceneRecord(
        1, 1, TRUTH, [hyp(*placed[:2])], 10.0, T_world_cam_true=T_true, T_world_cam_est=T_est
    )
    s = score_record(drifted, "t72")
    assert s.outcome == "tp" and s.translation_error_m < 1e-9
    # without the poses the same detection is judged in the world frame: > 2 m off, an FP
    assert score_record(record(TRUTH, [hyp(*placed[:2])]), "t72").outcome == "fp"
    assert summarise([drifted], "t72").nav_error_median_m == 3.0
    assert math.isnan(summarise([record(TRUTH, [])], "t72").nav_error_median_m)
    assert probe.nav_error_m == 3.0
    # a drifted heading too: the detection is still carried back exactly
    T_turned = _pose(35.0, 3.0, -40.0, 30.0)
    back = SceneRecord(1, 1, TRUTH, [], 10.0, T_world_cam_true=T_turned, T_world_cam_est=T_true)
    placed = back.sensor_relative(p_true)
    turned = SceneRecord(
        1, 1, TRUTH, [hyp(*placed[:2])], 10.0, T_world_cam_true=T_true, T_world_cam_est=T_turned
    )
    assert score_record(turned, "t72").translation_error_m < 1e-9
