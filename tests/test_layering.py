"""The layers import downwards only: `atr/` (algorithms) knows neither the bus, Zenoh nor MCAP, and no
library, command or benchmark imports a service's `main.py` (services are processes, not libraries;
their own tests may)."""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _imports(path: Path) -> list[str]:
    names: list[str] = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
    return names


def _python_files(*folders: str) -> list[Path]:
    return [p for folder in folders for p in sorted((REPO / folder).rglob("*.py"))]


def test_the_algorithms_import_no_bus_no_zenoh_no_mcap() -> None:
    upward = {
        f"{path.relative_to(REPO)}: {name}"
        for path in _python_files("atr")
        for name in _imports(path)
        if name.split(".")[0] in {"bus", "zenoh", "mcap", "services", "cli"}
    }
    assert not upward


def test_nothing_imports_a_service_main() -> None:
    importers = {
        f"{path.relative_to(REPO)}: {name}"
        for path in _python_files("atr", "bus", "cli", "bench")
        for name in _imports(path)
        if name.startswith("services.") and name.endswith(".main")
    }
    assert not importers
