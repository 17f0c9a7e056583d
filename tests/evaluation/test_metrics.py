"""The paper's F1 with the 2 m translation-error constraint (§III-C)."""

import numpy as np
import pytest

from atr.evaluation.metrics import Counts, count, score_scene

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
