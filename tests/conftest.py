"""Fixtures shared by every test folder: free TCP ports, a Zenoh hub process, peer configs.

Topology used by tests that talk over a real bus, as in compose/local: one hub process (a Zenoh
session in peer mode) listens on a free loopback port; every other session is a peer that connects
to the hub and listens on tcp/127.0.0.1:0 so that gossip can link peers to each other. Multicast
scouting is always off.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]

_HUB_CODE = """
import sys
from bus.session import default_config, open_session
from bus.stopping import StopRequest, stop_on_signals
mode = sys.argv[2] if len(sys.argv) > 2 else "peer"
session = open_session(default_config(mode, connect=[], listen=[sys.argv[1]]))
stop = StopRequest()
stop_on_signals(stop.set)
print("ready", flush=True)
stop.wait()
session.close()
"""


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def wait_for_port(port: int, timeout_s: float = 10.0) -> None:
    """Block until something accepts TCP connections on 127.0.0.1:`port`."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.02)
    raise TimeoutError(f"nothing listens on 127.0.0.1:{port} after {timeout_s} s")


def peer_config(hub_endpoint: str) -> dict[str, Any]:
    """A peer-mode Zenoh config dict that connects to `hub_endpoint`."""
    from bus.session import default_config

    return default_config("peer", connect=[hub_endpoint], listen=["tcp/127.0.0.1:0"])


def bus_env(hub_endpoint: str) -> dict[str, str]:
    """Environment for a child process whose default Zenoh session joins the hub as a peer."""
    env = dict(os.environ)
    env["ATR_ZENOH_CONNECT"] = hub_endpoint
    env["ATR_ZENOH_LISTEN"] = "tcp/127.0.0.1:0"
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("ATR_ZENOH_CONFIG", None)
    return env


def start_hub(port: int | None = None) -> tuple[subprocess.Popen[bytes], str]:
    """Start a hub process; returns it and its endpoint. The caller terminates it."""
    port = port or free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    env = bus_env(endpoint)
    proc = subprocess.Popen(
        [sys.executable, "-c", _HUB_CODE, endpoint], env=env, cwd=REPO, stdout=subprocess.PIPE
    )
    try:
        wait_for_port(port)
    except TimeoutError:
        proc.kill()
        raise
    return proc, endpoint


def stop_process(proc: subprocess.Popen[Any], timeout_s: float = 10.0) -> int:
    """SIGTERM `proc`, then SIGKILL if it has not ended after `timeout_s`; returns its exit code."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)


@pytest.fixture
def hub() -> Iterator[str]:
    """A running hub; yields its endpoint, e.g. "tcp/127.0.0.1:40123"."""
    proc, endpoint = start_hub()
    try:
        yield endpoint
    finally:
        stop_process(proc)


@pytest.fixture
def zenoh_config_file(hub: str, tmp_path: Path) -> Path:
    """A JSON5 Zenoh config file (peer joining `hub`), for commands that take --zenoh."""
    path = tmp_path / "zenoh.json5"
    path.write_text(json.dumps(peer_config(hub), indent=2))
    return path
