"""`atr eval` in-process and through the real service graph (`atr simulate` + `atr run`) give the same scenes:
the same SfM cloud sizes, bit-identical detections (target, position, score) and the same estimated camera pose,
frame by frame. The camera has a distorted lens, so both paths must carry and apply its coefficients alike.

Everything on the service side is real: processes on a Zenoh bus on loopback, lock-step replay, MCAP recording.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from atr.sim.config import SimConfig
from cli.main import build_parser

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _small_flight import SMALL_FLIGHT  # noqa: E402

# barrel distortion, ~15 px at the corners of the small camera
LENS = ["--set", "sim.dist_coeffs=[-0.25,0.05,0.0,0.0,0.0]"]
ARGS = [*SMALL_FLIGHT, *LENS, "--frames", "3"]


def evaluate(results, via_services: bool):
    from cli.evaluate import execute, plan

    args = build_parser().parse_args([*ARGS, "--results", str(results)])
    p = plan(args)
    out = execute(p, via_services=via_services)
    assert len(out) == 1
    return next(iter(out.values()))


def test_in_process_and_service_graph_give_identical_detections(tmp_path):
    local = evaluate(tmp_path / "local", via_services=False)
    bus = evaluate(tmp_path / "bus", via_services=True)
    assert [r.frame for r in local] == [r.frame for r in bus] == [1, 2]
    assert all(r.error is None for r in local + bus)
    assert sum(len(r.detections) for r in local) > 0
    for a, b in zip(local, bus, strict=True):
        assert a.stamp_ns == b.stamp_ns
        # the Truth message lists the targets in the scene (visible fraction >= the presence threshold)
        present = SimConfig().present_min_visible_fraction
        assert [t for t in a.truth if t["visible_fraction"] >= present] == b.truth
        assert a.cloud_points == b.cloud_points > 0
        assert a.detections == b.detections, f"frame {a.frame}"
        # both judge the detections relative to the sensor, with the same estimated camera pose
        assert a.T_world_cam_est == b.T_world_cam_est != a.T_world_cam_true, f"frame {a.frame}"
