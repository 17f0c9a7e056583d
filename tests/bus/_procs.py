"""Starting and watching the recorder, replayer and helper processes of the tests/bus tests."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import zenoh

from bus import codec
from bus.session import open_session

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE.parent))
from conftest import bus_env, peer_config  # noqa: E402


def atr(hub: str, *args: str, **kwargs: Any) -> subprocess.Popen[bytes]:
    """Start `atr ARGS` as a process on the hub's bus."""
    return subprocess.Popen(
        [sys.executable, "-m", "cli.main", *args],
        env=bus_env(hub),
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        **kwargs,
    )


def helper(hub: str, *args: str) -> subprocess.Popen[bytes]:
    """Start tests/bus/_bus_helpers.py ARGS as a process on the hub's bus."""
    return subprocess.Popen(
        [sys.executable, str(HERE / "_bus_helpers.py"), *args],
        env=bus_env(hub),
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


class Watcher:
    """A test-side Zenoh session that waits for services' Status messages."""

    def __init__(self, hub: str) -> None:
        self.session: zenoh.Session = open_session(peer_config(hub))
        self._seen: set[str] = set()
        self._cv = threading.Condition()
        self._sub = self.session.declare_subscriber("atr/*/*/status", self._on_status)

    def _on_status(self, sample: zenoh.Sample) -> None:
        # "running" comes after the service installed its signal handlers and is ready for input;
        # a signal sent on "starting" could hit it half-built.
        if codec.unpack(sample.payload.to_bytes()).get("state") != "running":
            return
        with self._cv:
            self._seen.add(str(sample.key_expr).split("/")[2])
            self._cv.notify_all()

    def wait_for(self, service: str, timeout_s: float = 20.0) -> None:
        with self._cv:
            if not self._cv.wait_for(lambda: service in self._seen, timeout_s):
                raise TimeoutError(f"no Status from {service} within {timeout_s} s")

    def close(self) -> None:
        self._sub.undeclare()
        self.session.close()


def finish(proc: subprocess.Popen[bytes], timeout_s: float = 30.0) -> tuple[int, str]:
    """Wait for `proc` to end; returns its exit code and stderr."""
    try:
        _, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return int(proc.returncode), err.decode(errors="replace")
