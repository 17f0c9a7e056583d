"""Every service is a folder with main.py and a manifest; every layout edge joins a declared output to a declared input."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest
import yaml

from bus import schemas
from bus.launcher import COMPOSE_DIR, load_layout

SERVICES = Path(__file__).resolve().parents[2] / "services"
NAMES = sorted(p.name for p in SERVICES.iterdir() if (p / "main.py").exists())


def manifest(name: str) -> dict:
    return yaml.safe_load((SERVICES / name / "service.yml").read_text())


@pytest.mark.parametrize("name", NAMES)
def test_service_folder_has_main_and_manifest(name):
    module = importlib.import_module(f"services.{name}.main")
    assert callable(module.main) and module.__doc__
    data = manifest(name)
    assert data["name"] == name and data["usage"]
    for entry in data.get("inputs", []) + data.get("outputs", []):
        assert entry["schema"] == "*" or entry["schema"] in schemas.names(), entry


@pytest.mark.parametrize("layout", sorted(p.stem for p in COMPOSE_DIR.glob("*.yml")))
def test_layout_edges_match_manifests(layout):
    loaded = load_layout(layout)
    services = {p.name: p.service for p in loaded.processes}
    assert set(services.values()) <= set(NAMES)
    for edge in loaded.edges:
        producer, rest = edge.split(":", 1)
        key, consumer = (s.strip() for s in rest.split("->"))
        outputs = {o["key"]: o["schema"] for o in manifest(services[producer.strip()])["outputs"]}
        inputs = {i["key"]: i["schema"] for i in manifest(services[consumer])["inputs"]}
        assert key in outputs, f"{edge}: {producer} does not declare {key}"
        assert key in inputs, f"{edge}: {consumer} does not declare {key}"
        assert outputs[key] == inputs[key], f"{edge}: schema {outputs[key]} != {inputs[key]}"


@pytest.mark.parametrize("name", NAMES)
def test_a_manifests_declared_defaults_are_the_configs(name):
    """A setting of the one config tree that a manifest declares with a plain type says its real default."""
    from atr.config import AtrConfig

    config = AtrConfig()
    plain = {"bool": bool, "int": int, "float": float, "str": str}
    for key, setting in (manifest(name).get("settings") or {}).items():
        if key.startswith("--") or setting.get("type") not in plain:
            continue
        group, field = key.split(".", 1)
        assert setting["default"] == getattr(getattr(config, group), field), (name, key)
