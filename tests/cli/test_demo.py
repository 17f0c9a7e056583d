"""`atr demo` picks the scenario's 30 deg run when --run is not given."""

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
