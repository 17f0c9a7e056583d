"""`atr run` and `atr up` as a user runs them (the real command in a subprocess): every argument is checked
before any process starts, and a relative path is the user's; `--preset` where `--set` is taken."""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bus import keys
from bus.recording import write_messages

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _atr_cli import atr  # noqa: E402

# The smallest layout `atr run` can complete: a hub and the recorder (no pipeline to wait for).
_RECORDER_ONLY = """
name: recorder-only
variables: {uav: uav1, hub: tcp/127.0.0.1:7447, out: runs/latest.mcap}
zenoh: compose/zenoh/local.json5
processes:
  - {name: router, service: router, role: hub, args: [--mode, peer, --listen, "${hub}"]}
  - {name: recorder, service: recorder, role: recorder, args: [--out, "${out}"]}
"""


@pytest.fixture
def recording(tmp_path: Path) -> Path:
    """A recording with one input message (a frame's truth: no answer to wait for)."""
    truth = {
        "stamp_ns": 1_000,
        "seq": 0,
        "version": 1,
        "frame_seq": 0,
        "T_world_cam": np.eye(4),
        "scenario": 1,
        "run": 1,
        "targets": [],
    }
    path = tmp_path / "in.mcap"
    write_messages(path, [(keys.truth("uav1"), truth)])
    return path


def refused(done: subprocess.CompletedProcess[str], *words: str) -> None:
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    for word in words:
        assert word in done.stderr, done.stderr


def test_a_bad_set_is_refused_before_any_process_starts(tmp_path: Path, recording: Path) -> None:
    start = time.monotonic()
    done = atr("run", str(recording), "--out", "o.mcap", "--set", "sfm.bogus=1", cwd=tmp_path)
    refused(done, "bogus")
    assert time.monotonic() - start < 20.0  # not the 900 s ready timeout of crash-looping services
    assert not (tmp_path / "o.logs").exists()  # no service was started
    done = atr("up", "--set", "sfm.matcher=nope", cwd=tmp_path)
    refused(done, "nope")
    done = atr("up", "--host", "moon", cwd=tmp_path)
    refused(done, "moon")


def test_bad_paths_and_values_are_refused_naming_them(
    tmp_path: Path, recording: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    from cli.main import main

    monkeypatch.chdir(tmp_path)

    def refused_here(args: list[str], *words: str) -> None:
        assert main(args) == 1
        stderr = capsys.readouterr().err
        for word in words:
            assert word in stderr, stderr

    (tmp_path / "folder").mkdir()
    (tmp_path / "text.mcap").write_text("not a recording")
    refused_here(["run", str(recording), "--out", "folder"], "is a directory")
    refused_here(["run", "missing.mcap", "--out", "o.mcap"], "missing.mcap", "no such")
    refused_here(["run", "folder", "--out", "o.mcap"], "folder", "is a directory")
    refused_here(["run", "text.mcap", "--out", "o.mcap"], "text.mcap", "not an MCAP")
    refused_here(
        ["run", str(recording), "--out", "o.mcap", "--answer-timeout", "0"], "--answer-timeout 0"
    )
    assert not (tmp_path / "o.logs").exists()


@pytest.mark.parametrize("command", ["run", "demo", "simulate", "regress", "up", "service"])
def test_preset_is_one_switch_in_its_place_among_the_sets(command: str) -> None:
    """Every command that takes --set takes --preset, passed on as the override `preset=NAME` in the order
    given (atr/config.py applies it there: a later --set refines it), and its help names every preset."""
    from atr.config import PRESETS
    from bus.service import service_arguments
    from cli.main import build_parser

    if command == "service":  # what `atr service NAME ARGS` and the layouts hand to every service
        parser, needed = service_arguments("sfm", None), []
    else:
        subparsers = next(
            a for a in build_parser(command)._actions if isinstance(a, argparse._SubParsersAction)
        )
        parser = subparsers.choices[command]
        needed = {
            "run": ["x.mcap", "--out", "o.mcap"],
            "simulate": ["--out", "o.mcap"],
            "regress": ["corpus", "--baseline", "b"],
        }.get(command, [])
    argv = [*needed, "--set", "a.b=1", "--preset", "paper", "--set", "c=2"]
    assert parser.parse_args(argv).overrides == ["a.b=1", "preset=paper", "c=2"]
    assert parser.parse_args(needed).overrides == []
    usage = parser.format_help()
    assert "--preset" in usage and all(f"'{name}'" in usage for name in PRESETS)


def test_an_unknown_preset_is_refused_naming_the_choices(
    tmp_path: Path, recording: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    from cli.main import main

    monkeypatch.chdir(tmp_path)
    assert main(["run", str(recording), "--out", "o.mcap", "--preset", "fastest"]) == 1
    stderr = capsys.readouterr().err
    assert "fastest" in stderr and "paper" in stderr and "dense" in stderr, stderr
    assert not (tmp_path / "o.logs").exists()  # no service was started


@pytest.mark.e2e
def test_a_relative_out_is_written_under_the_users_folder(tmp_path: Path, recording: Path) -> None:
    layout = tmp_path / "recorder-only.yml"
    layout.write_text(_RECORDER_ONLY)
    done = atr("run", str(recording), "--out", "runs/r.mcap", "--layout", str(layout), cwd=tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    out = tmp_path / "runs" / "r.mcap"
    assert out.is_file() and out.read_bytes().startswith(b"\x89MCAP0\r\n")
    assert str(out) in done.stdout


def test_an_existing_output_is_refused_before_anything_starts(
    recording: Path, tmp_path: Path
) -> None:
    """A recording is never overwritten: `atr run` names the file instead of starting a layout whose
    recorder would continue it as a segment of an unrelated flight."""
    existing = tmp_path / "old.mcap"
    existing.write_bytes(b"an earlier flight")
    result = atr("run", str(recording), "--out", str(existing), cwd=tmp_path)
    assert result.returncode == 1 and "exists; a recording is never overwritten" in result.stderr
    assert "Traceback" not in result.stderr
    assert existing.read_bytes() == b"an earlier flight"
    assert not (tmp_path / "old.1.mcap").exists() and not (tmp_path / "old.logs").exists()
