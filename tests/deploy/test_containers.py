"""The container compose files run the same processes as the `split` layout, host by host, with the same configs."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from bus.launcher import load_layout

CONTAINERS = Path(__file__).resolve().parents[2] / "compose" / "containers"


@pytest.mark.parametrize("host", ["ground", "air"])
def test_container_services_match_the_layout(host: str) -> None:
    layout = load_layout("split", {"deploy": "${ATR_DEPLOY}"})
    compose = yaml.safe_load((CONTAINERS / f"{host}.compose.yml").read_text())
    services = compose["services"]
    expected = {p.name: p for p in layout.processes if p.host == host}
    assert set(services) == set(expected)
    for name, spec in expected.items():
        command = services[name]["command"]
        assert command[:3] == ["atr", "service", spec.service], command
        if spec.role == "hub":  # the routers read the same Zenoh file as in the layout
            assert command[3:] == list(spec.args)
        else:
            assert services[name]["environment"]["ATR_ZENOH_CONFIG"] == spec.zenoh
