"""Pooling for the report: F1 of summed counts (not the mean of F1s), pooled TP errors, compactness (eq. 6)."""

from __future__ import annotations

import math

from atr.evaluation.aggregate import arm_label, compactness, pool, select


def row(run, tp, fp, fn, errors, pipeline="gftt-sfm", descriptor="shot", scenes=10, ms=100.0):
    return {
        "scenario": 1,
        "run": run,
        "pipeline": pipeline,
        "descriptor": descriptor,
        "tp": tp,
        "fp": fp,
        "fn": fn,
        "tn": 0,
        "scenes": scenes,
        "t_errors_m": errors,
        "time_per_scene_ms": ms,
        "noise": "none",
    }


def test_pool_sums_counts_before_f1():
    rows = [row(1, 9, 0, 1, [0.1] * 9), row(2, 0, 0, 10, [])]
    pooled = pool(rows, arm_label)["gftt-sfm/shot"]
    assert (pooled["tp"], pooled["fp"], pooled["fn"]) == (9, 0, 11)
    assert math.isclose(pooled["f1"], 18 / 29)  # not the mean of the two runs' F1 (0.947 and 0)
    assert pooled["t_error_median_m"] == 0.1 and pooled["runs"] == 2


def test_pool_time_weighted_by_scenes_and_groups_by_key():
    rows = [
        row(1, 1, 0, 0, [0.2], scenes=1, ms=100.0),
        row(2, 1, 0, 0, [0.4], scenes=3, ms=200.0),
        row(1, 0, 1, 0, [], pipeline="lidar"),
    ]
    pooled = pool(rows, arm_label)
    assert set(pooled) == {"gftt-sfm/shot", "lidar/shot"}
    assert math.isclose(pooled["gftt-sfm/shot"]["time_per_scene_ms"], 175.0)
    assert pooled["lidar/shot"]["f1"] == 0.0


def test_compactness_and_select():
    assert math.isclose(compactness(0.66, "fpfh"), 0.02)  # FPFH has 33 bins (Table III)
    rows = [row(1, 1, 0, 0, []), row(2, 1, 0, 0, [], pipeline="lidar")]
    assert select(rows, pipeline="lidar") == [rows[1]]
    assert select(rows, run=lambda r: r > 1) == [rows[1]]
