"""Result files: one JSON file per (flight, arm), keyed by every parameter and the code version.

A run's file is reused only when its key matches: same flight, arm, effective configuration and code version
(a hash of the `atr` package sources), so a resumed evaluation never mixes results of different code.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from atr.errors import InputError
from atr.evaluation.runner import Arm, Flight, SceneRecord

RESULT_FORMAT = 2


def code_version(package_root: Path | None = None) -> str:
    """Content hash of the algorithm sources (every .py under the `atr` package), 16 hex digits."""
    root = package_root or Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def jsonable(value: Any) -> Any:
    """Plain JSON data: dataclasses and tuples unpacked, NaN/inf as None."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return jsonable(dataclasses.asdict(value))
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "item") and callable(value.item):  # numpy scalars
        return jsonable(value.item())
    return value


def run_key(flight: Flight, arm: Arm, effective_config: Mapping[str, Any], version: str) -> str:
    """The key of one (flight, arm) result: a hash of everything it depends on, 24 hex digits."""
    payload = json.dumps(
        jsonable(
            {
                "flight": flight,
                "arm": arm,
                "config": effective_config,
                "code": version,
                "format": RESULT_FORMAT,
            }
        ),
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:24]


def save_run(
    path: Path,
    flight: Flight,
    arm: Arm,
    key: str,
    records: list[SceneRecord],
    extra: Mapping[str, Any] | None = None,
) -> None:
    """Write one run's scene records atomically (a crash never leaves a half file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {
        "format": RESULT_FORMAT,
        "key": key,
        "flight": jsonable(flight),
        "arm": jsonable(arm),
        "scenes": [jsonable(r.to_dict()) for r in records],
        "extra": jsonable(dict(extra or {})),
    }
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data))
    tmp.replace(path)


def load_run(path: Path, key: str) -> list[SceneRecord] | None:
    """The scene records of a run file when it exists and its key is `key`; None otherwise.

    Raises:
        InputError: the file exists with the right name but is not a result file.

    """
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"result file {path} is unreadable: {exc}") from exc
    if data.get("key") != key or data.get("format") != RESULT_FORMAT:
        return None
    return [SceneRecord.from_dict(_nan(s)) for s in data["scenes"]]


def _nan(scene: dict[str, Any]) -> dict[str, Any]:
    if scene.get("time_ms") is None:
        scene["time_ms"] = float("nan")
    return scene
