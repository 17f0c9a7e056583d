"""What made a recording: the software, its configuration, the machine and the input, as the
recorder writes it into every segment (MCAP metadata `provenance`, the configuration as an
attachment `config.json`). `atr audit` reads it back (docs/recording.md, "Provenance").

Everything here is cheap to gather except the effective configuration (loading the typed config
imports the algorithms), so the recorder gathers it on a thread of its own after it has started
recording: nothing on the bus waits for it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import platform
import socket
import time
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from atr.provenance import file_sha256, source_commit, source_sha256

METADATA_NAME = "provenance"
END_METADATA_NAME = "recording_end"
CONFIG_ATTACHMENT = "config.json"
# The distributions whose versions shape results (import names differ; versions come from metadata,
# so nothing heavy is imported to read them).
_LIBRARIES = {
    "numpy": "numpy",
    "scipy": "scipy",
    "opencv": "opencv-contrib-python-headless",
    "open3d": "open3d-cpu",
    "zenoh": "eclipse-zenoh",
    "mcap": "mcap",
    "numba": "numba",
}


@dataclasses.dataclass(frozen=True)
class RunContext:
    """What the launcher knows about a run that the recorder cannot see on the bus.

    Attributes:
        uav: vehicle id.
        layout: the deployment layout's name (`local`, `split`), empty when recording by hand.
        overrides: the `--set group.field=value` the pipeline services were started with.
        config_file: the `--config` YAML they were started with, if any.
        input_recording: the recording a replay (`atr run`) publishes, if any.

    """

    uav: str = "uav1"
    layout: str = ""
    overrides: tuple[str, ...] = ()
    config_file: str | None = None
    input_recording: str | None = None


def _version(dist: str) -> str:
    try:
        return version(dist)
    except PackageNotFoundError:
        return "not installed"


def effective_config(context: RunContext) -> dict[str, Any]:
    """The configuration the pipeline services run with (defaults, then the file, then the
    overrides), as plain JSON-able data.
    """
    from atr.config import load_config

    config = load_config(context.config_file, list(context.overrides))
    return json.loads(json.dumps(dataclasses.asdict(config), default=str))


def gather(context: RunContext, out: Path, segment: int) -> tuple[dict[str, str], bytes]:
    """The provenance record (MCAP metadata: strings only) and the configuration's JSON bytes.

    A configuration that cannot be loaded is recorded as such (`config_error`), never raised: the
    recording goes on whatever its provenance says.
    """
    record: dict[str, str] = {
        "package": "passive-atr",
        "package_version": _version("passive-atr"),
        "source_commit": source_commit(),
        "source_sha256": source_sha256(),
        "python": platform.python_version(),
        **{name: _version(dist) for name, dist in _LIBRARIES.items()},
        "host": socket.gethostname(),
        "platform": platform.platform(),
        "uav": context.uav,
        "layout": context.layout,
        "overrides": json.dumps(list(context.overrides)),
        "config_file": context.config_file or "",
        "recording": out.name,
        "segment": str(segment),
        "start_time_ns": str(time.time_ns()),
    }
    if context.input_recording:
        record["input_recording"] = Path(context.input_recording).name
        try:
            record["input_sha256"] = file_sha256(context.input_recording)
        except OSError as exc:
            record["input_sha256"] = f"unreadable: {exc}"
    config_bytes = b""
    try:
        config_bytes = json.dumps(effective_config(context), sort_keys=True, indent=1).encode()
        record["config_sha256"] = hashlib.sha256(config_bytes).hexdigest()
    except Exception as exc:  # noqa: BLE001 - a broken config is evidence, not a reason to stop
        record["config_error"] = f"{type(exc).__name__}: {exc}"
    return record, config_bytes
