"""The recorder under a flood of distinct keys (MCAP channel ids are 16-bit) and a message that
cannot be written: it refuses what it must, counts and reports it, and records everything else."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import zenoh

from atr.errors import AtrError
from bus import mcap_tools
from bus.recorder import Recorder
from bus.session import open_session

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import peer_config  # noqa: E402

pytestmark = pytest.mark.e2e


def _wait(
    condition: Callable[[], bool], progress: Callable[[], int], stall_s: float = 30.0
) -> None:
    """Wait for `condition` while `progress` keeps moving: a stalled recorder fails the test, a slow
    machine does not."""
    last, deadline = progress(), time.monotonic() + stall_s
    while not condition():
        now = progress()
        if now != last:
            last, deadline = now, time.monotonic() + stall_s
        assert time.monotonic() < deadline, f"the recorder stalled at {now} messages"
        time.sleep(0.05)


@contextmanager
def _recording(
    hub: str, out: Path
) -> Iterator[tuple[Recorder, zenoh.Session, list[tuple[str, AtrError]]]]:
    """A Recorder writing `out` on its own session, a peer session to put with, and the problems the
    recorder reports; the sessions close on exit."""
    problems: list[tuple[str, AtrError]] = []
    recorder_session = open_session(peer_config(hub))
    peer = open_session(peer_config(hub))
    try:
        recorder = Recorder(
            recorder_session, out, on_problem=lambda key, exc: problems.append((key, exc))
        )
        time.sleep(0.5)  # the subscription reaches the peer
        yield recorder, peer, problems
    finally:
        peer.close()
        recorder_session.close()


def test_66000_distinct_keys_do_not_stop_the_recording(hub: str, tmp_path: Path) -> None:
    out = tmp_path / "flood.mcap"
    with _recording(hub, out) as (recorder, peer, problems):
        flood = 66_000
        block = zenoh.CongestionControl.BLOCK  # a loaded machine drops nothing of the flood
        for i in range(flood):
            peer.put(f"atr/flood/{i}", b"x", congestion_control=block)
        for i in range(5):
            peer.put("atr/uav1/imu", bytes([i]), congestion_control=block)
        taken = lambda: recorder.stats.messages + recorder.stats.refused  # noqa: E731
        _wait(lambda: taken() == flood + 5, taken)
        stats = recorder.close()  # the old recorder failed here: channel id beyond 65535

    cap = recorder.config.max_foreign_keys
    assert (stats.refused, stats.write_errors) == (flood - cap, 0)
    assert mcap_tools.check(out) == []
    got = list(mcap_tools.iter_messages(out))
    assert [m.data for t, m in got if t == "atr/uav1/imu"] == [bytes([i]) for i in range(5)]
    assert sum(t.startswith("atr/flood/") for t, _ in got) == cap
    # reported, but not once per refused message
    refusals = [exc for _, exc in problems if "not recorded" in str(exc)]
    assert 1 <= len(refusals) < 100 and f"holds {cap} keys outside the contract" in str(refusals[0])


def test_a_message_that_cannot_be_written_does_not_stop_the_others(
    hub: str, tmp_path: Path
) -> None:
    out = tmp_path / "one-bad.mcap"
    with _recording(hub, out) as (recorder, peer, problems):
        peer.put("atr/uav1/imu", b"before")
        _wait(lambda: recorder.stats.messages == 1, lambda: recorder.stats.messages)
        # what the writer thread would get from a broken callback: no payload at all
        recorder._queue.put((time.time_ns(), "atr/uav1/imu", None, None))
        peer.put("atr/uav1/imu", b"after")
        _wait(lambda: recorder.stats.messages == 2, lambda: recorder.stats.messages)
        stats = recorder.close()

    assert stats.write_errors == 1 and recorder.failure is None
    assert any("not recorded" in str(exc) for _, exc in problems), problems
    assert mcap_tools.check(out) == []
    assert [m.data for _, m in mcap_tools.iter_messages(out)] == [b"before", b"after"]
