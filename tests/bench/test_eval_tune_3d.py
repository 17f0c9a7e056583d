"""The threshold sweep refuses the worlds whose figures are reported (docs/evaluation/protocol.md)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from atr.evaluation.aggregate import REPORTED_SEEDS

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "eval_tune_3d.py"


@pytest.mark.parametrize("seed", REPORTED_SEEDS)
def test_a_reported_seed_is_refused_before_anything_runs(seed: int) -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--seed", str(seed)], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert f"seed {seed} is a reported world" in done.stderr
    assert "Traceback" not in done.stderr
