"""`atr demo` picks the scenario's 30 deg run when --run is not given, and flies the default (dense) arm
unless --preset says otherwise."""

from __future__ import annotations

import pytest

from atr.sim.scenarios import scenario
from cli.demo import DEMO_OBLIQUITY_DEG, demo_run


@pytest.mark.parametrize("number", [1, 2, 3])
def test_demo_run_flies_the_medium_obliquity_run_of_every_scenario(number: int) -> None:
    run = demo_run(number)
    # scenario() raises for a run the scenario does not have (scenario 3 has only run 1)
    assert scenario(number, run).obliquity_deg == DEMO_OBLIQUITY_DEG


def test_demo_run_of_scenario_1_is_the_readme_demo() -> None:
    assert demo_run(1) == 3


def test_demo_flies_the_dense_arm_unless_the_paper_preset_is_asked_for() -> None:
    """The demo's services get `--preset` as given, before the overrides that fly another target."""
    from atr.config import load_config
    from cli.demo import vehicle_options
    from cli.main import build_parser

    parser = build_parser("demo")
    _, overrides = vehicle_options(parser.parse_args(["demo"]))
    assert load_config(None, overrides).sfm.matcher == "sgm"
    argv = ["demo", "--preset", "paper", "--target", "m109", "--set", "sfm.klt_window_px=15"]
    _, overrides = vehicle_options(parser.parse_args(argv))
    assert overrides[:2] == ["preset=paper", "sfm.klt_window_px=15"]
    config = load_config(None, overrides)
    assert config.sfm.matcher == "gftt" and config.sfm.klt_window_px == 15
    assert "m109" in config.pipeline.targets
