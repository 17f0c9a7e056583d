"""Zenoh sessions from JSON5 configs: peer mode on loopback by default, multicast scouting always off,
timestamping always on (every publication carries its publisher's time: bus/reliable.py delivers only
what was published after a subscription).

Where a config comes from, first match wins:
1. an explicit `config_path` (a layout's JSON5 file);
2. the `ATR_ZENOH_CONFIG` environment variable (path to a JSON5 file);
3. the default: peer mode, connect to `ATR_ZENOH_CONNECT` (comma-separated endpoints, default
   tcp/127.0.0.1:7447), listen on `ATR_ZENOH_LISTEN` (default: none).
`ATR_ZENOH_CONNECT` / `ATR_ZENOH_LISTEN` also override the endpoints of a file config.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import json5
import zenoh

from atr.errors import BusError, ConfigError

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


def default_config(
    mode: str = "peer", connect: list[str] | None = None, listen: list[str] | None = None
) -> dict[str, Any]:
    """A Zenoh config as a dict: explicit endpoints, no multicast scouting."""
    if mode not in ("peer", "client", "router"):
        raise ConfigError(f"zenoh mode {mode!r} must be peer, client or router")
    return {
        "mode": mode,
        "connect": {"endpoints": list(connect if connect is not None else [DEFAULT_ENDPOINT])},
        "listen": {"endpoints": list(listen or [])},
        "scouting": {"multicast": {"enabled": False}},
        "timestamping": {"enabled": True},
    }


def load_config(config_path: str | Path | None = None) -> dict[str, Any]:
    """The effective Zenoh config as a dict (see the module docstring for precedence).

    Raises:
        ConfigError: the file is missing or not valid JSON5.

    """
    path = config_path or os.environ.get("ATR_ZENOH_CONFIG")
    if path:
        try:
            config = json5.loads(Path(path).read_text())
        except (OSError, ValueError) as exc:
            raise ConfigError(f"zenoh config {path}: {exc}") from exc
        config.setdefault("scouting", {}).setdefault("multicast", {})["enabled"] = False
        config.setdefault("timestamping", {})["enabled"] = True
    else:
        config = default_config()
    for env, section in (("ATR_ZENOH_CONNECT", "connect"), ("ATR_ZENOH_LISTEN", "listen")):
        value = os.environ.get(env)
        if value is not None:
            endpoints = [e for e in value.split(",") if e]
            config.setdefault(section, {})["endpoints"] = endpoints
    return config


def open_session(config: dict[str, Any] | str | Path | None = None) -> zenoh.Session:
    """Open a Zenoh session from a config dict, a JSON5 file path, or the environment.

    Raises:
        BusError: Zenoh refused the config or could not open the session.

    """
    as_dict = config if isinstance(config, dict) else load_config(config)
    if not as_dict.get("timestamping", {}).get("enabled"):
        as_dict = as_dict | {"timestamping": as_dict.get("timestamping", {}) | {"enabled": True}}
    try:
        return zenoh.open(zenoh.Config.from_json5(json.dumps(as_dict)))
    except zenoh.ZError as exc:
        raise BusError(f"cannot open a zenoh session with {as_dict}: {exc}") from exc
