"""The launcher's process lifecycle on real processes: exit 0 is done, a failure is restarted, and a launcher
stopped by SIGTERM, SIGINT or SIGHUP takes every process it started down with it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from bus.launcher import Supervisor, load_layout, user_variables
from bus.recording import write_messages

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import free_port  # noqa: E402

REPO = Path(__file__).resolve().parents[2]

# `atr service router --help` exits 0 at once; `--bogus` exits 2 (argparse) at once.
_LAYOUT = """
name: lifecycle
variables: {uav: uav1}
processes:
  - {name: finished, service: router, role: source, args: [--help]}
  - {name: failing, service: router, args: [--bogus]}
"""


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _children(pid: int) -> set[int]:
    """Direct children of `pid` (Linux /proc)."""
    children: set[int] = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        children |= {int(c) for c in text}
    return children


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


def _wait_for_children(proc: subprocess.Popen[bytes], count: int, timeout_s: float) -> set[int]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[1].decode()
        children = _children(proc.pid)
        if len(children) >= count:
            return children
        time.sleep(0.1)
    raise AssertionError(f"the launcher started {len(_children(proc.pid))} of {count} processes")


def test_exit_0_is_done_and_a_failure_is_restarted(tmp_path: Path) -> None:
    path = tmp_path / "lifecycle.yml"
    path.write_text(_LAYOUT)
    supervisor = Supervisor(load_layout(path), max_backoff_s=0.5)
    supervisor.start()
    try:
        deadline = time.monotonic() + 8.0
        while time.monotonic() < deadline and supervisor.running["failing"].restarts < 2:
            supervisor.poll()
            time.sleep(0.05)
        for _ in range(20):  # a good while after the source finished
            supervisor.poll()
            time.sleep(0.05)
    finally:
        supervisor.stop(grace_s=2.0)
    finished, failing = supervisor.running["finished"], supervisor.running["failing"]
    assert finished.popen.returncode == 0
    assert finished.done and finished.restarts == 0 and finished.failures == []
    assert failing.restarts >= 2 and set(failing.failures) == {2}
    assert supervisor.failures() == {"failing": failing.failures}


def test_the_launcher_gives_its_processes_one_state_folder_and_removes_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "lifecycle.yml"
    path.write_text(_LAYOUT)
    monkeypatch.delenv("ATR_STATE_DIR", raising=False)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    supervisor = Supervisor(load_layout(path))
    specs = supervisor.specs
    folders = {supervisor._env(spec)["ATR_STATE_DIR"] for spec in specs}
    assert len(folders) == 1 and len(specs) == 2
    folder = Path(folders.pop())
    assert folder.is_dir() and folder.parent == tmp_path
    (folder / "sfm-uav1.state").write_bytes(b"a journal left by a killed service")
    supervisor.start()
    supervisor.stop(grace_s=2.0)
    assert not folder.exists()
    # a folder the caller chose is the caller's: given to the processes, never removed
    chosen = tmp_path / "chosen"
    chosen.mkdir()
    monkeypatch.setenv("ATR_STATE_DIR", str(chosen))
    supervisor = Supervisor(load_layout(path))
    assert supervisor._env(specs[0])["ATR_STATE_DIR"] == str(chosen)
    supervisor.start()
    supervisor.stop(grace_s=2.0)
    assert chosen.is_dir()


def test_user_path_variables_are_resolved_against_the_callers_folder(tmp_path: Path) -> None:
    variables = user_variables({"out": "runs/r.mcap", "deploy": "d", "uav": "uav2"}, cwd=tmp_path)
    assert variables == {
        "out": str(tmp_path / "runs/r.mcap"),
        "deploy": str(tmp_path / "d"),
        "uav": "uav2",
    }
    absolute = str(tmp_path / "x.mcap")
    assert user_variables({"out": absolute})["out"] == absolute


def _input_recording(path: Path) -> Path:
    write_messages(path, [])
    return path


@pytest.mark.e2e
@pytest.mark.parametrize(
    ("command", "signum"),
    [("run", signal.SIGTERM), ("up", signal.SIGHUP), ("up", signal.SIGTERM)],
)
def test_a_stopped_launcher_leaves_no_process_behind(
    tmp_path: Path, command: str, signum: int
) -> None:
    hub = f"tcp/127.0.0.1:{free_port()}"
    if command == "run":
        args = ["run", str(_input_recording(tmp_path / "in.mcap")), "--out", "out.mcap"]
    else:
        args = ["up", "--no-source", "--var", f"hub={hub}", "--var", "out=out.mcap"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "cli.main", *args],
        cwd=tmp_path,
        env=_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    children: set[int] = set()
    try:
        children = _wait_for_children(proc, 6, timeout_s=20.0)
        time.sleep(1.0)  # the services are mid-start: the hardest time to be stopped
        proc.send_signal(signum)
        _, stderr = proc.communicate(timeout=30)
        assert "Traceback" not in stderr.decode(), stderr.decode()
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and any(_alive(pid) for pid in children):
            time.sleep(0.1)
        assert not [pid for pid in children if _alive(pid)], "services outlived their launcher"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for pid in children:  # what a failed run left behind
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
