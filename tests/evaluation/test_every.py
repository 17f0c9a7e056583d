"""`atr eval --every K` samples a run's scenes without changing them: each sampled scene gets the truth, cloud
and detections the full run gives it (the IMU is integrated over the skipped frames; only their rendering is
skipped)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from atr.errors import ConfigError
from cli.main import build_parser

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _small_flight import SMALL_FLIGHT  # noqa: E402

ARGS = [*SMALL_FLIGHT, "--frames", "7"]


def scenes(results, every: int):
    from cli.evaluate import execute, plan

    p = plan(build_parser().parse_args([*ARGS, "--every", str(every), "--results", str(results)]))
    out = execute(p)
    assert len(out) == 1
    return next(iter(out.values()))


def test_every_third_scene_equals_the_full_runs_scenes(tmp_path):
    full = scenes(tmp_path / "full", 1)
    sampled = scenes(tmp_path / "sampled", 3)
    assert [s.frame for s in full] == [1, 2, 3, 4, 5, 6]
    assert [s.frame for s in sampled] == [3, 6]
    by_frame = {s.frame: s for s in full}
    assert any(s.detections for s in sampled), "the comparison must cover detections"
    for s in sampled:
        ref = by_frame[s.frame]
        assert s.truth == ref.truth
        assert s.cloud_points == ref.cloud_points > 0
        assert s.detections == ref.detections


def test_every_is_refused_with_the_service_graph(tmp_path):
    from cli.evaluate import plan

    args = build_parser().parse_args(
        [*ARGS, "--every", "2", "--via-services", "--results", str(tmp_path)]
    )
    with pytest.raises(ConfigError, match="--every 2"):
        plan(args)


def test_a_navigation_fix_every_frame_bounds_the_drift(tmp_path):
    """sim.nav_fix_every_frame: each pair is integrated from a correct state over one frame interval, so the
    camera pose the cloud is placed with stays near the truth while dead reckoning from take-off drifts."""
    from cli.evaluate import execute, plan

    def last_scene(extra: list[str], folder: str):
        args = [*ARGS, "--every", "6", "--results", str(tmp_path / folder), *extra]
        out = execute(plan(build_parser().parse_args(args)))
        return next(iter(out.values()))[-1]

    inertial = last_scene([], "inertial")
    aided = last_scene(["--set", "sim.nav_fix_every_frame=true"], "aided")
    assert inertial.frame == aided.frame == 6
    assert aided.nav_error_m < 0.5 * inertial.nav_error_m
    assert aided.truth == inertial.truth
