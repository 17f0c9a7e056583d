"""Faulty sensor input through the real service graph (`atr run`, lock-step): every frame gets exactly one
answer — Detections, or an ErrorReport naming its stamp — and nothing waits for the answer timeout.

A missing IMU batch (its frame must be reported, not waited for), a flight whose first frame is not 0, and a
duplicated IMU batch (one answer, not two)."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from bus import codec, keys, mcap_tools
from bus.recording import write_messages

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))
from _atr_cli import atr, simulate_small_flight  # noqa: E402

pytestmark = [pytest.mark.e2e, pytest.mark.slow]
UAV = "uav1"


@pytest.fixture(scope="module")
def flight(tmp_path_factory) -> list[tuple[str, dict]]:
    """The (key, message) inputs of a 6-frame simulated flight, in order."""
    path = simulate_small_flight(tmp_path_factory.mktemp("flight") / "flight.mcap", frames=6)
    return [(topic, codec.unpack(m.data)) for topic, m in mcap_tools.iter_messages(path)]


def _answers(out: Path) -> Counter[int]:
    """How many answers each frame stamp got: Detections, or ErrorReports naming it."""
    answers: Counter[int] = Counter()
    for topic, message in mcap_tools.iter_messages(out):
        if topic == keys.detections(UAV):
            answers[codec.unpack(message.data)["stamp_ns"]] += 1
        elif topic.endswith("/errors") and "/replayer/" not in topic:
            stamp = codec.unpack(message.data).get("input_stamp_ns")
            if stamp is not None:
                answers[stamp] += 1
    return answers


def _replay(
    messages: list[tuple[str, dict]], folder: Path
) -> tuple[subprocess.CompletedProcess, Path]:
    source, out = folder / "in.mcap", folder / "out.mcap"
    write_messages(source, messages)
    # a short answer timeout: a frame left unanswered would show as a timeout, not a slow test
    return atr("run", str(source), "--out", str(out), "--answer-timeout", "60"), out


def _stamps(messages: list[tuple[str, dict]]) -> list[int]:
    return [m["stamp_ns"] for k, m in messages if k == keys.image(UAV)]


def test_a_missing_imu_batch_is_reported_for_its_frame(flight, tmp_path: Path) -> None:
    dropped = next(m["stamp_ns"] for k, m in flight if k == keys.imu(UAV) and m["frame_seq"] == 3)
    inputs = [(k, m) for k, m in flight if not (k == keys.imu(UAV) and m["stamp_ns"] == dropped)]
    result, out = _replay(inputs, tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "(0 unanswered)" in result.stdout, result.stdout
    answers = _answers(out)
    assert all(answers[s] >= 1 for s in _stamps(inputs)), answers
    reasons = [
        codec.unpack(m.data)["reason"]
        for t, m in mcap_tools.iter_messages(out)
        if t.endswith("/errors") and codec.unpack(m.data).get("input_stamp_ns") == dropped
    ]
    assert any("IMU batch of frame 3" in r for r in reasons), reasons


def test_a_flight_from_frame_1_and_a_duplicated_batch_get_one_answer_each(flight, tmp_path) -> None:
    first = [m for k, m in flight if k == keys.imu(UAV) and m["frame_seq"] == 0][0]
    inputs = []
    for k, m in flight:
        if m.get("frame_seq") == 0:
            continue  # the flight starts at frame 1: its first batch carries the initial state
        if k == keys.imu(UAV) and m["frame_seq"] == 1:
            m = m | {"init": first["init"]}
            inputs.append((k, m))  # and frame 1's batch comes twice
        inputs.append((k, m))
    result, out = _replay(inputs, tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "(0 unanswered)" in result.stdout, result.stdout
    answers = _answers(out)
    stamps = _stamps(inputs)
    assert [answers[s] for s in stamps] == [1] * len(stamps), answers
