"""record -> replay -> record over a real bus: byte-identical inputs; lock-step against a fake
pipeline."""

from __future__ import annotations

import signal
import sys
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.reader import make_reader

from bus import codec, mcap_tools
from bus.replayer import Replayer, is_input_topic

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _procs import Watcher, atr, finish, helper  # noqa: E402
from conftest import peer_config, start_hub, stop_process  # noqa: E402

pytestmark = pytest.mark.e2e


def _messages(path: Path) -> list[tuple[str, object]]:
    with open(path, "rb") as f:
        return [(c.topic, m) for _, c, m in make_reader(f, validate_crcs=True).iter_messages()]


def _record(hub: str, watcher: Watcher, out: Path, *during: list[str]) -> None:
    """Record while each `atr` command in `during` runs to completion."""
    recorder = atr(hub, "record", "--out", str(out))
    watcher.wait_for("recorder")
    try:
        for command in during:
            proc = helper(hub, *command[1:]) if command[0] == "helper" else atr(hub, *command)
            code, err = finish(proc, timeout_s=60)
            assert code == 0, err
    finally:
        recorder.send_signal(signal.SIGTERM)
        code, err = finish(recorder)
    assert code == 0, err
    assert mcap_tools.check(out) == []


@pytest.fixture(scope="module")
def hub() -> Iterator[str]:
    """One hub for this module's tests (they run one after the other and share the original
    recording)."""
    proc, endpoint = start_hub()
    try:
        yield endpoint
    finally:
        stop_process(proc)


@pytest.fixture(scope="module")
def original(hub: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("original") / "original.mcap"
    watcher = Watcher(hub)
    try:
        _record(hub, watcher, out, ["helper", "publish", "--frames", "6", "--seed", "4"])
    finally:
        watcher.close()
    return out


def test_replayed_inputs_are_byte_identical(hub: str, tmp_path: Path, original: Path) -> None:
    again = tmp_path / "again.mcap"
    watcher = Watcher(hub)
    try:
        _record(hub, watcher, again, ["replay", str(original), "--fast"])
    finally:
        watcher.close()

    def inputs(path: Path) -> list[tuple[str, bytes, int, int]]:
        return [
            (t, m.data, m.sequence, m.publish_time) for t, m in _messages(path) if is_input_topic(t)
        ]

    first, second = inputs(original), inputs(again)
    assert len(first) == 6 * 4
    assert second == first  # same keys, same order, same bytes, same seq and stamp
    # non-inputs (camera poses, status) are not replayed
    assert not any(t.endswith("pose/camera") for t, m in _messages(again) if "replayer" not in t)


def test_recorded_rate_keeps_the_spacing(hub: str, original: Path) -> None:
    # In-process use (as `atr run` does): replay at 4x and measure the wall time against the
    # recorded span.
    info = mcap_tools.info(original)
    stamps = [m.log_time for t, m in _messages(original) if is_input_topic(t)]
    recorded_s = (stamps[-1] - stamps[0]) / 1e9
    from bus.session import open_session

    session = open_session(peer_config(hub))
    try:
        with Replayer(original, session, settle_s=0.0, match_timeout_s=0.5) as replayer:
            stats = replayer.recorded(rate=4.0)
    finally:
        session.close()
    assert stats.published == len(stamps) and info.messages > len(stamps)
    assert recorded_s / 4 * 0.9 <= stats.wall_s <= recorded_s / 4 + 0.5


def test_lock_step_releases_a_frame_only_after_the_answer_to_the_last(
    hub: str, tmp_path: Path, original: Path
) -> None:
    answered = tmp_path / "lockstep.mcap"
    watcher = Watcher(hub)
    pipeline = helper(hub, "pipeline", "--seed", "7", "--max-delay", "0.08", "--error-every", "3")
    try:
        watcher.wait_for("fake_pipeline")
        _record(
            hub,
            watcher,
            answered,
            [
                "replay",
                str(original),
                "--lock-step",
                "--wait-for",
                "fake_pipeline",
                "--answer-timeout",
                "10",
            ],
        )
    finally:
        pipeline.send_signal(signal.SIGTERM)
        pipeline_code, pipeline_err = finish(pipeline)
        watcher.close()

    # The pipeline itself sees whether a frame came before its answer to the last one. (The order of
    # messages from different sources in a recording is not evidence: they reach the recorder over
    # different links, and Zenoh orders messages per link only.)
    assert "before the answer" not in pipeline_err, pipeline_err
    assert pipeline_code == 0, pipeline_err
    records = _messages(answered)
    images = [m for t, m in records if t == "atr/uav1/camera/image"]
    assert len(images) == 6
    answers: Counter[int] = Counter()  # answers per image stamp
    for topic, m in records:
        if topic == "atr/uav1/detections":
            answers[codec.unpack(m.data)["stamp_ns"]] += 1
        elif topic == "atr/uav1/fake_pipeline/errors":
            answers[codec.unpack(m.data)["input_stamp_ns"]] += 1
    for k, image in enumerate(images):
        assert answers[codec.unpack(image.data)["stamp_ns"]] == 1, f"frame {k}: one answer expected"
    # every third frame was answered with an ErrorReport instead of Detections
    errors = [t for t, _ in records if t == "atr/uav1/fake_pipeline/errors"]
    assert len(errors) == 2
    assert not any(t == "atr/uav1/replayer/errors" for t, _ in records)  # no timeout


def test_paced_replay_sends_every_frame_without_waiting_then_counts_the_answers(
    hub: str, original: Path
) -> None:
    from bus.session import open_session

    def paced(answer_timeout_s: float):
        session = open_session(peer_config(hub))
        try:
            with Replayer(original, session, settle_s=0.0, match_timeout_s=0.5) as replayer:
                return replayer.paced(rate=4.0, answer_timeout_s=answer_timeout_s)
        finally:
            session.close()

    # Nobody answers: every input still goes out at the pace, and the six frames share one wait of
    # 2 s; lock-step waits out the timeout once per frame, 6 x 2 s at the least.
    stats = paced(answer_timeout_s=2.0)
    assert stats.published == 6 * 4 and (stats.frames, stats.answered, stats.timeouts) == (6, 0, 6)
    assert stats.wall_s < 6 * 2.0
    # A pipeline that answers (with Detections, or an ErrorReport every third frame): all counted.
    watcher = Watcher(hub)
    pipeline = helper(hub, "pipeline", "--seed", "7", "--max-delay", "0.08", "--error-every", "3")
    try:
        watcher.wait_for("fake_pipeline")
        stats = paced(answer_timeout_s=10.0)
    finally:
        pipeline.send_signal(signal.SIGTERM)
        finish(pipeline)
        watcher.close()
    assert (stats.frames, stats.answered, stats.timeouts) == (6, 6, 0)
