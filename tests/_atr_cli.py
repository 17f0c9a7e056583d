"""The `atr` command as a user runs it, for the tests that check a whole command: a fresh process, its
output captured."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from _small_camera import SMALL_CAMERA

REPO = Path(__file__).resolve().parents[1]


def atr(*args: str, cwd: Path = REPO, timeout_s: float = 600.0) -> subprocess.CompletedProcess[str]:
    """Run `atr ARGS` in `cwd` (the repository stays importable from any folder); stdout and stderr
    captured as text, the exit code not checked."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, "-m", "cli.main", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )


def simulate_small_flight(out: Path, frames: int) -> Path:
    """`atr simulate` of scenario 1 run 3 with the small camera (tests/_small_camera.py) into `out`."""
    made = atr(
        "simulate", "--scenario", "1", "--run", "3", "--frames", str(frames), *SMALL_CAMERA,
        "--out", str(out),
    )  # fmt: skip
    assert made.returncode == 0, made.stdout + made.stderr
    return out
