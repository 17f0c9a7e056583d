"""The tuning tool's account of why a scene is not a true positive (docs/recognition.md)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from atr.recognition.matcher import Detection

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from tune_recognition import _vehicle_under_best, why_not_true_positive  # noqa: E402

T_TRUE = np.eye(4)


def _at(x_m: float, target: str = "t72") -> Detection:
    T = np.eye(4)
    T[0, 3] = x_m
    return Detection(target, "shot", T, score=100.0, overlap=0.7, inliers=9)


def _hypothesis(x_m: float, target: str = "t72") -> tuple:
    return (target, 0, 0.2, 15, 0.6, x_m, 0.0, 0.0)


def test_true_positives_and_negatives_need_no_reason() -> None:
    assert why_not_true_positive("tp", [_at(0.5)], [], T_TRUE) == ""
    assert why_not_true_positive("tn", [], [], None) == ""


@pytest.mark.parametrize(
    ("outcome", "detections", "verified", "T_true", "expected"),
    [
        ("fp", [_at(30.0)], [], None, "reported without target"),
        ("fp", [_at(5.0)], [], T_TRUE, "T-72 fit 2-10 m off"),
        ("fp", [_at(25.0), _at(0.5)], [], T_TRUE, "a true fit scores under a T-72 fit elsewhere"),
        (
            "fp",
            [_at(25.0), _at(0.5, "ifv")],
            [],
            T_TRUE,
            "another template holds the target's place",
        ),
        ("fn", [_at(0.5, "truck6x6")], [], T_TRUE, "another template holds the target's place"),
        ("fn", [], [_hypothesis(1.0)], T_TRUE, "true hypothesis refused by verification"),
        # a refused hypothesis of another template, or one 3 m off, is not a true one
        (
            "fn",
            [],
            [_hypothesis(1.0, "ifv"), _hypothesis(3.0)],
            T_TRUE,
            "no T-72 hypothesis within 2 m of the target",
        ),
        (
            "fp",
            [_at(25.0)],
            [_hypothesis(25.0)],
            T_TRUE,
            "no T-72 hypothesis within 2 m of the target",
        ),
    ],
)
def test_each_failure_gets_the_first_reason_that_holds(
    outcome: str, detections: list, verified: list, T_true: np.ndarray | None, expected: str
) -> None:
    assert why_not_true_positive(outcome, detections, verified, T_true) == expected


def test_a_false_t72_fit_is_told_by_the_vehicle_it_sits_on() -> None:
    from atr.sim import build_world, scenario

    meta = {"seed": 101, "scenario": 2, "run": 1}
    world = build_world(scenario(2, 1), 101)
    ifv = next(v for v in world.vehicles if v.name == "ifv")
    worlds: dict[tuple, tuple] = {}
    on_ifv = [_at(-50.0, "truck6x6"), _at(ifv.position_m[0]), _at(0.0)]
    on_ifv[1].T_world_target[1, 3] = ifv.position_m[1]
    # the best T-72 fit decides, not a better-scoring confuser fit nor a later T-72 fit
    assert _vehicle_under_best(on_ifv, meta, worlds) == "ifv"
    assert list(worlds) == [(101, 2, 1)]
    far = world.T_world_target[0, 3] + 500.0
    assert _vehicle_under_best([_at(far)], meta, worlds) == "elsewhere"
