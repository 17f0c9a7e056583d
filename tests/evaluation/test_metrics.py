"""The paper's F1 with the 2 m translation-error constraint (§III-C)."""

import numpy as np
import pytest

from atr.errors import InputError
from atr.evaluation.metrics import Counts, count, f1_interval, score_scene, vehicle_under

TARGET = [np.array([10.0, 5.0, 0.0])]


@pytest.mark.parametrize(
    ("truth", "hypotheses", "outcome"),
    [
        (TARGET, [np.array([10.5, 5.0, 0.2])], "tp"),
        (TARGET, [np.array([13.0, 5.0, 0.0])], "fp"),  # present but > 2 m off: FP, not FN (§III-C)
        (TARGET, [], "fn"),
        ([], [np.array([0.0, 0.0, 0.0])], "fp"),
        ([], [], "tn"),
    ],
)
def test_scene_outcomes(truth, hypotheses, outcome):
    assert score_scene(truth, hypotheses).outcome == outcome


def test_only_the_best_hypothesis_is_judged():
    # Best first: a correct second guess does not rescue a wrong first one.
    assert score_scene(TARGET, [np.array([20.0, 5, 0]), np.array([10.0, 5, 0])]).outcome == "fp"


def test_boundary_is_strict():
    assert score_scene(TARGET, [TARGET[0] + [2.0, 0, 0]]).outcome == "fp"
    assert score_scene(TARGET, [TARGET[0] + [1.999, 0, 0]]).outcome == "tp"


def test_f1_matches_equation_5():
    scores = (
        [score_scene(TARGET, [TARGET[0]])] * 8
        + [score_scene(TARGET, [])] * 2
        + [score_scene([], [np.zeros(3)])]
    )
    counts = count(scores)
    assert counts == Counts(tp=8, fp=1, fn=2, tn=0)
    assert counts.f1 == pytest.approx(2 * 8 / (2 * 8 + 1 + 2))
    assert np.isnan(Counts().f1)


def _flights(rng: np.random.Generator, scenes: int, p_tp: float, p_fp: float) -> list[str]:
    """Scenes that all have the target: TP with p_tp, FP (off target) with p_fp, else FN."""
    return [
        str(o) for o in rng.choice(["tp", "fp", "fn"], size=scenes, p=[p_tp, p_fp, 1 - p_tp - p_fp])
    ]


def _f1(outcomes: list[str]) -> float:
    return Counts(*(outcomes.count(o) for o in ("tp", "fp", "fn", "tn"))).f1


def test_f1_interval_covers_the_true_f1_about_as_often_as_it_says():
    # F1 of many scenes drawn with these chances: 2p / (2p + p_fp + p_fn).
    p_tp, p_fp = 0.8, 0.05
    true_f1 = 2 * p_tp / (2 * p_tp + p_fp + (1 - p_tp - p_fp))
    rng = np.random.default_rng(7)
    covered = [
        low <= true_f1 <= high
        for low, high in (
            f1_interval(_flights(rng, 150, p_tp, p_fp), resamples=1000) for _ in range(200)
        )
    ]
    assert 0.89 <= np.mean(covered) <= 0.99


def test_f1_interval_narrows_with_the_square_root_of_the_scenes():
    scenes = _flights(np.random.default_rng(3), 100, 0.8, 0.05)
    low, high = f1_interval(scenes)
    low4, high4 = f1_interval(scenes * 4)
    assert low <= _f1(scenes) <= high
    assert 1.6 < (high - low) / (high4 - low4) < 2.5


def test_paired_interval_of_a_difference():
    a = _flights(np.random.default_rng(5), 150, 0.8, 0.05)
    assert f1_interval(a, a) == (0.0, 0.0)
    # b misses 10 of a's true positives: F1 drops on those scenes only, so the interval excludes 0
    tp = [i for i, o in enumerate(a) if o == "tp"][:10]
    b = ["fn" if i in tp else o for i, o in enumerate(a)]
    low, high = f1_interval(a, b)
    assert 0 < low <= _f1(a) - _f1(b) <= high
    # unpaired, the same difference hides in the two arms' own spreads
    a_low, a_high = f1_interval(a)
    b_low, b_high = f1_interval(b)
    assert a_low < b_high


def test_f1_interval_is_reproducible_and_checks_its_input():
    a = _flights(np.random.default_rng(9), 60, 0.7, 0.1)
    assert f1_interval(a, seed=4) == f1_interval(a, seed=4)
    assert f1_interval(["tp"] * 8) == (1.0, 1.0)
    assert all(np.isnan(f1_interval([])))
    with pytest.raises(InputError, match="60 against 59"):
        f1_interval(a, a[:-1])


def test_vehicle_under_names_the_nearest_vehicle_whose_radius_holds_the_position():
    names = ["ifv", "truck6x6", "car"]
    positions = np.array([[20.0, 0.0, 0.0], [23.0, 0.0, 0.0], [0.0, 30.0, 0.0]])
    radii = np.array([3.7, 3.9, 2.3])
    assert vehicle_under(np.array([21.0, 0.5, 5.0]), names, positions, radii) == "ifv"
    assert vehicle_under(np.array([22.8, 0.0, 0.0]), names, positions, radii) == "truck6x6"
    assert vehicle_under(np.array([0.0, 32.0, 0.0]), names, positions, radii) == "car"
    assert vehicle_under(np.array([0.0, 33.0, 0.0]), names, positions, radii) == ""
    assert vehicle_under(np.array([0.0, 0.0, 0.0]), [], np.zeros((0, 3)), np.zeros(0)) == ""
