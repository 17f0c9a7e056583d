"""Held-out targets: `atr eval --targets` plans one flight per target with the rest of the family as
confusers, and the per-target table pools counts per target, range and obliquity."""

import pytest

from atr.errors import ConfigError
from atr.evaluation.aggregate import target_table
from atr.evaluation.experiment import WORLD_CONFUSERS, Request, plan
from atr.sim.vehicles import VEHICLES


def test_each_target_flies_with_the_rest_of_the_family_and_every_template():
    p = plan(Request(scenarios=(1,), runs=(3,), pipelines=("sgm-sfm",), targets=("t72", "m109")))
    assert [f.target for f in p.flights] == ["t72", "m109"]
    t72, m109 = p.flights
    assert t72.target_mesh is None  # the default target: its world is the reported evaluation's
    assert m109.target_mesh == "m109"
    for flight in p.flights:
        in_world = {flight.target, *WORLD_CONFUSERS, *flight.clutter_meshes}
        assert in_world == set(VEHICLES)
        assert flight.target not in flight.clutter_meshes
    assert set(p.config.pipeline.targets) == set(VEHICLES)


@pytest.mark.parametrize(
    ("request_", "message"),
    [
        (Request(targets=("t72", "tiger")), "tiger"),
        (Request(targets=("t72",), target_mesh="m1"), "not both"),
        (Request(targets=("t72",), pipelines=("2d-1",)), "2D"),
    ],
)
def test_bad_target_sets_are_refused(request_, message):
    with pytest.raises(ConfigError, match=message):
        plan(request_)


def _row(target, range_m, obliquity, tp, fp, fn, tn=0, on_vehicles=0, errors=(0.1,)):
    return {
        "target": target,
        "range_m": range_m,
        "obliquity_deg": obliquity,
        "tp": tp,
        "fp": fp,
        "fn": fn,
        "tn": tn,
        "scenes": tp + fp + fn + tn,
        "t_errors_m": list(errors),
        "time_per_scene_ms": 1.0,
        "false_positives_on": {"m1": on_vehicles, "elsewhere": fp - on_vehicles},
    }


def test_the_table_pools_per_cell_per_target_and_over_held_out_targets():
    rows = [
        _row("t72", 50.0, 0.0, tp=8, fp=1, fn=1, on_vehicles=1),
        _row("t72", 100.0, 0.0, tp=4, fp=0, fn=6),
        _row("m109", 50.0, 0.0, tp=9, fp=0, fn=1),
        _row("m109", 50.0, 30.0, tp=10, fp=2, fn=0, on_vehicles=2, errors=(0.2, 0.4)),
        _row("btr80", 50.0, 0.0, tp=5, fp=5, fn=0, tn=2, on_vehicles=3),
    ]
    table = target_table(rows, tuned_on=("t72",))
    cell = next(c for c in table["cells"] if c["target"] == "t72" and c["range_m"] == 100.0)
    assert (cell["tp"], cell["fn"], cell["f1"]) == (4, 6, pytest.approx(8 / 14))
    by_target = {t["target"]: t for t in table["targets"]}
    assert not by_target["t72"]["held_out"] and by_target["m109"]["held_out"]
    assert by_target["t72"]["f1"] == pytest.approx(24 / (24 + 1 + 7))
    assert by_target["m109"]["t_error_median_m"] == pytest.approx(0.2)
    held = {h["obliquity_deg"]: h for h in table["held_out"]}
    assert set(held) == {0.0, 30.0, None}  # per obliquity, then all
    assert (held[0.0]["tp"], held[0.0]["fp"], held[0.0]["fn"]) == (14, 5, 1)
    assert held[None]["tp"] == 24 and held[None]["scenes"] == 24 + 7 + 1 + 2
    assert held[None]["fp_on_vehicles"] == 5
    assert held[None]["fp_on_vehicles_share"] == pytest.approx(5 / 34)
