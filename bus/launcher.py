"""Start a deployment layout from compose/, keep it alive, and stop it.

A layout (compose/<name>.yml) lists processes — each one `atr service NAME` with arguments — the Zenoh config
they share, the variables substituted into both (`${uav}`, `${hub}`, `${out}`, ...), and the edges that wire
outputs to inputs (checked against the service manifests by the tests). The supervisor restarts a process
that fails (a non-zero exit), with exponential back-off; a process that exits 0 is done (a source that finished
its flight) and stays down. It stops everything on request (SIGTERM to each process group, then SIGKILL after a
grace); `interrupt_on_signals` and `on_stop_signals` make SIGTERM, SIGINT and SIGHUP to a launcher stop its
layout instead of orphaning it.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
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
STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)
"""The signals that stop a launcher and, through it, its whole layout (a closed terminal sends SIGHUP)."""


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


PATH_VARIABLES = ("out", "air_out", "deploy")
"""Layout variables that name files or folders: a user's relative value is resolved against the user's working
directory (`user_variables`), since the processes run from the repository."""


def user_variables(variables: dict[str, str], cwd: Path | None = None) -> dict[str, str]:
    """A user's layout variables with the paths among them (`PATH_VARIABLES`) made absolute against `cwd`.

    Raises:
        ConfigError: a path variable is empty.

    """
    base = Path.cwd() if cwd is None else cwd
    out = dict(variables)
    for name in PATH_VARIABLES:
        if name in out:
            if not out[name]:
                raise ConfigError(f"layout variable {name} is empty; expected a path")
            out[name] = str(base / Path(out[name]).expanduser())
    return out


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
    done: bool = False  # exited 0: finished its work, not restarted


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
        input_recording: Path | None = None,
    ) -> None:
        self.layout = layout
        self.overrides = list(overrides)
        self.input_recording = input_recording
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
        # One state folder per launcher, made and removed by it, unless the caller chose one: a restarted
        # service finds its journal there, and a stopped layout leaves nothing in the temp directory.
        self._own_state_dir: Path | None = None
        if not os.environ.get("ATR_STATE_DIR"):
            self._own_state_dir = Path(tempfile.mkdtemp(prefix="atr-state-"))

    def _command(self, spec: ProcessSpec) -> list[str]:
        command = [sys.executable, "-m", "cli.main", "service", spec.service, *spec.args]
        if spec.role != "hub":
            command += ["--uav", self.layout.variables.get("uav", "uav1")]
            if spec.role in ("pipeline", "source", "recorder"):
                for override in self.overrides:  # the recorder keeps them in its provenance record
                    command += ["--set", override]
            if spec.role == "recorder":
                command += ["--layout", self.layout.name]
                if self.input_recording is not None:
                    command += ["--input", str(self.input_recording)]
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
        if self._own_state_dir is not None:
            env["ATR_STATE_DIR"] = str(self._own_state_dir)
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
                if code is None or proc.done:
                    continue
                if code == 0 and proc.next_start is None:
                    proc.done = (
                        True  # e.g. a source that finished its flight: flying again is wrong
                    )
                    log.info("%s finished (exit 0); not restarted", name)
                elif proc.next_start is None:
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
        """SIGTERM every process group (the recorder and hub last), wait, SIGKILL what remains.

        A second Ctrl-C or SIGTERM while it stops is ignored, so it cannot leave processes behind.

        Returns:
            The exit code of each process.

        """
        with self._lock:
            self._stopping = True
        with _signals_ignored():
            return self._stop(grace_s)

    def _stop(self, grace_s: float) -> dict[str, int | None]:
        for popen in self._once:
            _signal_group(popen, signal.SIGTERM)
            try:
                popen.wait(grace_s)
            except subprocess.TimeoutExpired:
                _signal_group(popen, signal.SIGKILL)
                popen.wait()
        order = sorted(
            self.running.values(), key=lambda p: {"hub": 2, "recorder": 1}.get(p.spec.role, 0)
        )
        codes: dict[str, int | None] = {}
        for group in (0, 1, 2):
            members = [p for p in order if {"hub": 2, "recorder": 1}.get(p.spec.role, 0) == group]
            for proc in members:
                _signal_group(proc.popen, signal.SIGTERM)
            deadline = time.monotonic() + grace_s
            for proc in members:
                try:
                    proc.popen.wait(max(0.1, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    log.warning("%s ignored SIGTERM; killing it", proc.spec.name)
                    _signal_group(proc.popen, signal.SIGKILL)
                    proc.popen.wait()
                codes[proc.spec.name] = proc.popen.returncode
        for handle in self._logs:
            handle.close()
        if self._own_state_dir is not None:
            shutil.rmtree(self._own_state_dir, ignore_errors=True)
        return codes


def _signal_group(popen: subprocess.Popen[bytes], signum: int) -> None:
    """Signal a child's whole process group (it leads its own session), so nothing it started survives."""
    if popen.poll() is not None:
        return
    try:
        os.killpg(popen.pid, signum)
    except ProcessLookupError:  # it exited between the poll and the signal
        pass


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextmanager
def _signals_ignored() -> Iterator[None]:
    """Ignore the stop signals inside (main thread only: elsewhere handlers cannot be installed)."""
    if not _in_main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _raise_interrupt(signum: int, _frame: object) -> None:
    raise KeyboardInterrupt(f"stopped by {signal.Signals(signum).name}")


@contextmanager
def interrupt_on_signals() -> Iterator[None]:
    """Inside, SIGTERM and SIGHUP raise KeyboardInterrupt as Ctrl-C (SIGINT) does.

    A launcher that runs a layout inside `try: ... finally: supervisor.stop()` then stops its layout on any
    of them instead of dying and orphaning its services. Main thread only; elsewhere it does nothing.
    """
    if not _in_main_thread():
        yield
        return
    previous = {
        sig: signal.signal(sig, _raise_interrupt) for sig in (signal.SIGTERM, signal.SIGHUP)
    }
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def on_stop_signals(stop: Callable[[], None]) -> None:
    """Call `stop` on SIGTERM, SIGINT and SIGHUP (main thread only).

    It runs inside the signal handler, so it must take no lock (`bus.stopping.StopRequest.set` takes none).
    """
    if not _in_main_thread():
        return
    for sig in STOP_SIGNALS:
        signal.signal(sig, lambda *_: stop())


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
        from bus import codec  # keeps this module light for `atr up --help`

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
    from bus.session import default_config

    hub = layout.variables.get("hub")
    return open_session(default_config("peer", [hub] if hub else None, ["tcp/127.0.0.1:0"]))


def describe(layout: Layout) -> dict[str, Any]:
    """A short description for logs."""
    return {"name": layout.name, "processes": [p.name for p in layout.processes]}
