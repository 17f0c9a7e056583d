"""Two hosts on one machine: network namespaces `ground` and `air` joined by a veth pair (iproute2, needs root).

    with TwoHosts() as hosts:
        proc = hosts.start("ground", [python, "-m", "cli.main", "up", "split", ...], env=...)
        hosts.rate_limit(2_000_000)     # htb on both ends of the veth pair
    # every process started through `hosts` is killed, the namespaces (and with them the veth pair) are deleted,
    # even when the body raised.

Addresses: ground 10.77.0.1/24, air 10.77.0.2/24 (private, only inside the namespaces this object made).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

GROUND_IP = "10.77.0.1"
AIR_IP = "10.77.0.2"


def netns_unavailable() -> str | None:
    """Why namespaces cannot be made here (None when they can)."""
    if os.geteuid() != 0:
        return "network namespaces need root (ip netns add)"
    if shutil.which("ip") is None:
        return "iproute2's `ip` command is not installed"
    probe = f"atrprobe{os.getpid()}"
    result = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if result.returncode != 0:
        return f"ip netns add failed: {result.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return None


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)
    if check and result.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {result.stderr.strip()}")
    return result


class TwoHosts:
    """The two namespaces, their veth pair, and the processes started in them."""

    def __init__(self) -> None:
        tag = os.getpid() % 100000
        self.ns = {"ground": f"atr-ground-{tag}", "air": f"atr-air-{tag}"}
        self.dev = {"ground": f"atrg{tag}", "air": f"atra{tag}"}
        self.ip = {"ground": GROUND_IP, "air": AIR_IP}
        self.procs: list[subprocess.Popen[Any]] = []

    def __enter__(self) -> TwoHosts:
        try:
            for host in ("ground", "air"):
                _ip("netns", "add", self.ns[host])
            _ip(
                "link",
                "add",
                self.dev["ground"],
                "netns",
                self.ns["ground"],
                "type",
                "veth",
                "peer",
                "name",
                self.dev["air"],
                "netns",
                self.ns["air"],
            )
            for host in ("ground", "air"):
                _ip(
                    "-n", self.ns[host], "addr", "add", f"{self.ip[host]}/24", "dev", self.dev[host]
                )
                _ip("-n", self.ns[host], "link", "set", self.dev[host], "up")
                _ip("-n", self.ns[host], "link", "set", "lo", "up")
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(
        self,
        host: str,
        command: list[str],
        *,
        env: dict[str, str] | None = None,
        cwd: Path | None = None,
        stdout: Any = None,
        stderr: Any = None,
        text: bool = False,
    ) -> subprocess.Popen[Any]:
        """Start `command` inside `host`'s namespace (its own process group, killed on close)."""
        proc = subprocess.Popen(
            ["ip", "netns", "exec", self.ns[host], *command],
            env=env,
            cwd=cwd,
            stdout=stdout,
            stderr=stderr,
            text=text,
            start_new_session=True,
        )
        self.procs.append(proc)
        return proc

    def run(self, host: str, command: list[str], timeout_s: float = 30.0) -> str:
        """Run `command` in `host`'s namespace to completion; its stdout."""
        result = subprocess.run(
            ["ip", "netns", "exec", self.ns[host], *command],
            capture_output=True,
            text=True,
            timeout=timeout_s,
        )
        if result.returncode != 0:
            raise RuntimeError(f"{command} in {host}: {result.stderr.strip()}")
        return result.stdout

    def rate_limit(self, rate_bps: int | None) -> None:
        """Shape both ends of the veth pair to `rate_bps` with htb (None removes the shaping)."""
        for host in ("ground", "air"):
            ns, dev = self.ns[host], self.dev[host]
            _ip("netns", "exec", ns, "tc", "qdisc", "del", "dev", dev, "root", check=False)
            if rate_bps is None:
                continue
            rate = f"{int(rate_bps)}bit"
            for command in (
                ["qdisc", "add", "dev", dev, "root", "handle", "1:", "htb", "default", "10"],
                [
                    "class",
                    "add",
                    "dev",
                    dev,
                    "parent",
                    "1:",
                    "classid",
                    "1:10",
                    "htb",
                    "rate",
                    rate,
                    "ceil",
                    rate,
                ],
            ):
                result = subprocess.run(
                    ["ip", "netns", "exec", ns, "tc", *command],
                    capture_output=True,
                    text=True,
                    timeout=20,
                )
                if result.returncode != 0:
                    raise RuntimeError(f"tc {' '.join(command)}: {result.stderr.strip()}")

    def link_bytes(self) -> dict[str, int]:
        """Bytes sent by each end of the veth pair (kernel counters, headers included)."""
        out = {}
        for host in ("ground", "air"):
            text = self.run(host, ["cat", f"/sys/class/net/{self.dev[host]}/statistics/tx_bytes"])
            out[host] = int(text.strip())
        return out

    @staticmethod
    def stop(proc: subprocess.Popen[Any], timeout_s: float = 20.0) -> int | None:
        """SIGTERM a process started here, SIGKILL after `timeout_s`; its exit code."""
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                proc.kill()
        try:
            return proc.wait(5.0)
        except subprocess.TimeoutExpired:
            return None

    def kill_namespace_processes(self, host: str) -> None:
        """SIGKILL whatever still runs inside `host`'s namespace (a layout's services, once their launcher
        is gone): only processes this object's namespaces hold, listed by `ip netns pids`."""
        result = _ip("netns", "pids", self.ns[host], check=False)
        for pid in (int(p) for p in result.stdout.split() if p.isdigit()):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def close(self) -> None:
        """Stop every process started here, then delete the namespaces (the veth pair goes with them)."""
        for proc in reversed(self.procs):
            self.stop(proc, timeout_s=5.0)
        self.procs.clear()
        for host in ("air", "ground"):
            if self.ns[host] not in _ip("netns", "list", check=False).stdout:
                continue
            deadline = time.monotonic() + 10.0
            while (
                _ip("netns", "pids", self.ns[host], check=False).stdout.strip()
                and time.monotonic() < deadline
            ):
                self.kill_namespace_processes(host)
                time.sleep(0.2)
            _ip("netns", "del", self.ns[host], check=False)
