"""Start a deployment layout from compose/, keep it alive, and stop it.

A layout (compose/<name>.yml) lists processes — each one `atr service NAME` with arguments — the Zenoh config
they share, the variables substituted into both (`${uav}`, `${hub}`, `${out}`, ...), and the edges that wire
outputs to inputs (checked against the service manifests by the tests). The supervisor restarts a process
that dies, with exponential back-off, and stops everything on request (SIGTERM, then SIGKILL after a grace).
"""

from __future__ import annotations

import logging
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import yaml
import zenoh

from atr.errors import BusError, ConfigError
from bus.session import open_session

log = logging.getLogger("atr")

REPO = Path(__file__).resolve().parents[1]
COMPOSE_DIR = REPO / "compose"


@dataclass(frozen=True)
class ProcessSpec:
    """One process of a layout."""

    name: str
    service: str
    args: tuple[str, ...] = ()
    role: str = (
        "pipeline"  # "hub", "pipeline", "recorder" or "source" (the source is skipped by `atr run`)
    )
    host: str = "local"  # which host of a split layout runs it
    zenoh: str | None = None  # this process's own Zenoh config file (default: the layout's)


@dataclass(frozen=True)
class Layout:
    """A deployment layout: processes, their Zenoh config, and the variables both use."""

    name: str
    processes: tuple[ProcessSpec, ...]
    zenoh: str | None
    variables: dict[str, str]
    edges: tuple[str, ...] = ()
    path: Path | None = None

    def services(self) -> list[str]:
        """Services with a status heartbeat (all but the hub)."""
        return [p.name for p in self.processes if p.role != "hub"]


def layout_path(name_or_path: str | Path) -> Path:
    """Resolve `local` to compose/local.yml; a path is taken as it is."""
    path = Path(name_or_path)
    if path.suffix in (".yml", ".yaml") and path.exists():
        return path
    candidate = COMPOSE_DIR / f"{name_or_path}.yml"
    if not candidate.exists():
        known = sorted(p.stem for p in COMPOSE_DIR.glob("*.yml"))
        raise ConfigError(f"layout {name_or_path!r} not found; expected a file or one of {known}")
    return candidate


def _substitute(text: str, variables: dict[str, str]) -> str:
    def value(match: re.Match[str]) -> str:
        name = match.group(1)
        if name not in variables:
            raise ConfigError(
                f"layout variable ${{{name}}} is not defined; defined: {sorted(variables)}"
            )
        return str(variables[name])

    return re.sub(r"\$\{(\w+)\}", value, text)


def load_layout(name_or_path: str | Path, variables: dict[str, str] | None = None) -> Layout:
    """Read a layout, with `variables` overriding its defaults.

    Raises:
        ConfigError: unreadable file, unknown variable, or a process without a service.

    """
    path = layout_path(name_or_path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"layout {path}: {exc}") from exc
    values = {k: str(v) for k, v in (data.get("variables") or {}).items()} | (variables or {})
    processes = []
    for entry in data.get("processes") or []:
        if "name" not in entry:
            raise ConfigError(f"layout {path}: process without a name: {entry}")
        zenoh_file = entry.get("zenoh")
        processes.append(
            ProcessSpec(
                name=entry["name"],
                service=entry.get("service", entry["name"]),
                args=tuple(_substitute(str(a), values) for a in entry.get("args") or []),
                role=entry.get("role", "pipeline"),
                host=entry.get("host", "local"),
                zenoh=_substitute(zenoh_file, values) if zenoh_file else None,
            )
        )
    zenoh_file = data.get("zenoh")
    return Layout(
        name=data.get("name", path.stem),
        processes=tuple(processes),
        zenoh=_substitute(zenoh_file, values) if zenoh_file else None,
        variables=values,
        edges=tuple(data.get("edges") or ()),
        path=path,
    )


@dataclass
class _Running:
    spec: ProcessSpec
    popen: subprocess.Popen[bytes]
    started: float
    restarts: int = 0
    next_start: float | None = None
    failures: list[int] = field(default_factory=list)


class Supervisor:
    """Runs a layout's processes; restarts a crashed one with back-off; stops all on request."""

    def __init__(
        self,
        layout: Layout,
        *,
        overrides: list[str] = (),
        hosts: tuple[str, ...] | None = None,
        skip_roles: tuple[str, ...] = (),
        log_dir: Path | None = None,
        max_backoff_s: float = 30.0,
    ) -> None:
        self.layout = layout
        self.overrides = list(overrides)
        self.specs = [
            p
            for p in layout.processes
            if p.role not in skip_roles and (hosts is None or p.host in hosts)
        ]
        self.log_dir = log_dir
        self.max_backoff_s = max_backoff_s
        self.running: dict[str, _Running] = {}
        self._logs: list[IO[bytes]] = []
        self._lock = threading.Lock()
        self._stopping = False
        self._once: list[subprocess.Popen[bytes]] = []

    def _command(self, spec: ProcessSpec) -> list[str]:
        command = [sys.executable, "-m", "cli.main", "service", spec.service, *spec.args]
        if spec.role != "hub":
            command += ["--uav", self.layout.variables.get("uav", "uav1")]
            if spec.role == "pipeline" or spec.role == "source":
                for override in self.overrides:
                    command += ["--set", override]
        return command

    def _env(self, spec: ProcessSpec) -> dict[str, str]:
        env = dict(os.environ)
        env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
        # Several services share few cores: one BLAS thread each, numba on OpenMP (Debian's TBB is too old).
        env.setdefault("OPENBLAS_NUM_THREADS", "1")
        env.setdefault("NUMBA_THREADING_LAYER", "omp")
        config = spec.zenoh or self.layout.zenoh
        if config:
            env["ATR_ZENOH_CONFIG"] = (
                str(REPO / config) if not Path(config).is_absolute() else config
            )
        hub = self.layout.variables.get("hub")
        if hub and spec.role != "hub":
            env.setdefault("ATR_ZENOH_CONNECT", hub)
        return env

    def _spawn(self, spec: ProcessSpec) -> subprocess.Popen[bytes]:
        out: IO[bytes] | None = None
        if self.log_dir is not None:
            self.log_dir.mkdir(parents=True, exist_ok=True)
            out = open(self.log_dir / f"{spec.name}.log", "ab")  # noqa: SIM115 - closed in stop()
            self._logs.append(out)
        log.info("starting %s: %s", spec.name, " ".join(self._command(spec)[3:]))
        return subprocess.Popen(
            self._command(spec),
            env=self._env(spec),
            cwd=REPO,
            stdout=out,
            stderr=out,
            start_new_session=True,
        )

    def spawn_once(self, spec: ProcessSpec) -> subprocess.Popen[bytes]:
        """Start a process that runs to completion (a flight's source): not supervised, not restarted."""
        popen = self._spawn(spec)
        self._once.append(popen)
        return popen

    def start(self) -> None:
        """Start every process, the hub first."""
        for spec in sorted(self.specs, key=lambda p: p.role != "hub"):
            self.running[spec.name] = _Running(spec, self._spawn(spec), time.monotonic())
            if spec.role == "hub":
                time.sleep(0.5)  # let it bind before the others dial in

    def poll(self) -> None:
        """Restart processes that died, after a back-off that doubles per restart."""
        now = time.monotonic()
        with self._lock:
            if self._stopping:
                return
            for name, proc in self.running.items():
                code = proc.popen.poll()
                if code is None:
                    continue
                if proc.next_start is None:
                    proc.failures.append(code)
                    backoff = min(self.max_backoff_s, 0.5 * 2**proc.restarts)
                    if now - proc.started > 60:
                        backoff = 0.5  # it ran a good while: a fresh failure, not a crash loop
                    proc.next_start = now + backoff
                    log.warning("%s exited with %s; restarting in %.1f s", name, code, backoff)
                elif now >= proc.next_start:
                    proc.popen = self._spawn(proc.spec)
                    proc.started, proc.next_start = now, None
                    proc.restarts += 1

    def failures(self) -> dict[str, list[int]]:
        """Exit codes of every process that died while it should have run."""
        return {name: p.failures for name, p in self.running.items() if p.failures}

    def stop(self, grace_s: float = 10.0) -> dict[str, int | None]:
        """SIGTERM every process (the recorder and hub last), wait, SIGKILL what remains.

        Returns:
            The exit code of each process.

        """
        with self._lock:
            self._stopping = True
        for popen in self._once:
            if popen.poll() is None:
                popen.terminate()
                popen.wait(grace_s)
        order = sorted(
            self.running.values(), key=lambda p: {"hub": 2, "recorder": 1}.get(p.spec.role, 0)
        )
        codes: dict[str, int | None] = {}
        for group in (0, 1, 2):
            members = [p for p in order if {"hub": 2, "recorder": 1}.get(p.spec.role, 0) == group]
            for proc in members:
                if proc.popen.poll() is None:
                    proc.popen.send_signal(signal.SIGTERM)
            deadline = time.monotonic() + grace_s
            for proc in members:
                try:
                    proc.popen.wait(max(0.1, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    log.warning("%s ignored SIGTERM; killing it", proc.spec.name)
                    proc.popen.kill()
                    proc.popen.wait()
                codes[proc.spec.name] = proc.popen.returncode
        for handle in self._logs:
            handle.close()
        return codes


def wait_until_ready(
    session: zenoh.Session,
    uav: str,
    services: list[str],
    timeout_s: float,
    supervisor: Supervisor | None = None,
) -> None:
    """Block until every service has published a `running` status.

    Raises:
        BusError: some services were not ready in time (named in the message).

    """
    ready: set[str] = set()
    lock = threading.Lock()

    def on_status(sample: zenoh.Sample) -> None:
        from bus import codec  # noqa: PLC0415 - keeps this module light for `atr up --help`

        try:
            status = codec.unpack(sample.payload.to_bytes())
        except Exception:
            return
        if status.get("state") == "running":
            with lock:
                ready.add(status.get("service"))

    subscriber = session.declare_subscriber(f"atr/{uav}/*/status", on_status)
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            with lock:
                if set(services) <= ready:
                    return
            if supervisor is not None:
                supervisor.poll()
            time.sleep(0.1)
        missing = sorted(set(services) - ready)
        raise BusError(
            f"services not ready (no `running` status) after {timeout_s:.0f} s: {missing}"
        )
    finally:
        subscriber.undeclare()


def observer_session(layout: Layout) -> zenoh.Session:
    """A session of this process (the launcher itself) joined to the layout's hub."""
    from bus.session import default_config  # noqa: PLC0415

    hub = layout.variables.get("hub")
    return open_session(default_config("peer", [hub] if hub else None, ["tcp/127.0.0.1:0"]))


def describe(layout: Layout) -> dict[str, Any]:
    """A short description for logs."""
    return {"name": layout.name, "processes": [p.name for p in layout.processes]}
