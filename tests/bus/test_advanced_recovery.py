"""Recovery through zenoh-ext's advanced publisher/subscriber, on real sessions over a real router.

A router process joins two client sessions on loopback, as in the split layout: one Node publishes IMU
batches, another takes them as input, a recorder records the bus. The router is killed and started
again while messages are published: an outage the publisher's cache covers loses nothing, one it does
not cover loses exactly what fell out of the cache, and both the subscriber and the recorder say how
many and from whom.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from mcap.reader import make_reader

from bus import codec, keys
from bus.node import Message, Node
from bus.recorder import Recorder
from bus.reliable import LinkBudget, loss_count
from bus.session import default_config, open_session

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "schemas"))
from conftest import REPO, free_port, stop_process, wait_for_port  # noqa: E402
from test_codec import example  # noqa: E402

pytestmark = pytest.mark.e2e

UAV = "uav1"
# 2 s at 5 messages/s: each publisher keeps its last 10 messages; a heartbeat every 0.3 s
BUDGET = LinkBudget(outage_s=2.0, rate_hz=5.0, heartbeat_s=0.3)
CACHED = BUDGET.cache_samples(BUDGET.rate_hz, 1)


class Router:
    """`atr service router` in router mode on a fixed loopback port, killed and started at will."""

    def __init__(self) -> None:
        self.port = free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "cli.main", "service", "router", "--mode", "router"]
            + ["--listen", self.endpoint],
            cwd=REPO,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        wait_for_port(self.port)

    def kill(self) -> None:
        assert self.proc is not None
        self.proc.kill()
        self.proc.wait(10)


def _imu(index: int) -> dict:
    message = {k: v for k, v in example("ImuBatch").items() if k != "seq"}  # the Node numbers it
    message["stamp_ns"] = 1_000_000 * (index + 1)
    return message


def _take(node: Node, until: Callable[[list[Message]], bool], timeout_s: float) -> list[Message]:
    got: list[Message] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and not until(got):
        got.extend(node.events(timeout_s=0.1))
    return got


def test_outages_within_the_cache_lose_nothing_and_beyond_it_are_counted(tmp_path: Path) -> None:
    router = Router()
    router.start()
    client = default_config("client", connect=[router.endpoint])
    recording = tmp_path / "bus.mcap"
    problems: list[tuple[str, Exception]] = []
    recorder_session = open_session(client)
    try:
        with (
            Node("sensor_source", UAV, zenoh_config=client, budget=BUDGET) as source,
            Node("sfm", UAV, [keys.imu(UAV)], zenoh_config=client, budget=BUDGET) as sfm,
        ):
            recorder = Recorder(
                recorder_session,
                recording,
                on_problem=lambda key, exc: problems.append((key, exc)),
            )
            # the route exists once a first message gets through
            sent = 0
            got: list[Message] = []
            deadline = time.monotonic() + 20
            while not got and time.monotonic() < deadline:
                source.publish(keys.imu(UAV), _imu(sent))
                sent += 1
                got = _take(sfm, lambda g: bool(g), 0.3)
            assert got, "no message reached the subscriber"
            first = got[0].seq

            # 1. An outage the cache covers: every message arrives, in order, none reported lost.
            router.kill()
            for _ in range(CACHED - 2):
                source.publish(keys.imu(UAV), _imu(sent))
                sent += 1
            router.start()
            got += _take(sfm, lambda g: bool(g) and g[-1].seq == sent - 1, 20)
            seqs = [m.seq for m in got if m.key == keys.imu(UAV)]
            assert seqs == list(range(first, sent)), seqs
            assert sfm.counters.lost == 0
            assert not [key for key, _ in problems if key == keys.imu(UAV)]

            # 2. An outage longer than the cache: what fell out of it is lost, counted exactly.
            router.kill()
            outage_first = sent
            for _ in range(CACHED + 7):
                source.publish(keys.imu(UAV), _imu(sent))
                sent += 1
            outage_end = sent
            router.start()
            after = _take(sfm, lambda g: bool(g) and g[-1].seq == outage_end - 1, 20)
            time.sleep(0.5)  # the recorder's writer thread reports its own loss
            recorder.close()

            # 3. A subscriber that joins later gets what is published from then on, nothing older
            # (neither from the cache nor after a heartbeat), whatever the cache holds.
            with Node("tracker", UAV, [keys.imu(UAV)], zenoh_config=client) as late:
                time.sleep(3 * BUDGET.heartbeat_s)
                source.publish(keys.imu(UAV), _imu(sent))
                sent += 1
                joined = _take(late, lambda g: bool(g), 10)
                time.sleep(3 * BUDGET.heartbeat_s)
                joined += _take(late, lambda g: False, 0.3)

        lost_seqs = set(range(outage_first, outage_end - CACHED))
        assert [m.seq for m in after] == list(range(outage_end - CACHED, outage_end))
        assert sfm.counters.lost == len(lost_seqs) == 7
        assert sfm.counters.gaps == 1
        # the recorder lost the same messages, and said so, with the count
        imu_problems = [str(exc) for key, exc in problems if key == keys.imu(UAV)]
        assert [loss_count(text) for text in imu_problems] == [len(lost_seqs)], problems
        assert f"from {source.source_id} " in imu_problems[0]
        with recording.open("rb") as stream:
            records = [
                (c.topic, codec.unpack(m.data))
                for _, c, m in make_reader(stream).iter_messages(log_time_order=False)
            ]
        recorded = [d["seq"] for t, d in records if t == keys.imu(UAV)]
        assert sorted(recorded) == recorded, "a publisher's messages recorded out of order"
        assert set(recorded) == set(range(recorded[0], outage_end)) - lost_seqs
        # the subscriber's report is on its errors key, in the recording, naming the publisher
        reports = [d for t, d in records if t == keys.service_key(UAV, "sfm", "errors")]
        assert [loss_count(r["reason"]) for r in reports] == [len(lost_seqs)]
        assert reports[0]["input_source"] == source.source_id
        assert reports[0]["key"] == keys.imu(UAV)
        assert [m.seq for m in joined] == [sent - 1]
    finally:
        recorder_session.close()
        if router.proc is not None:
            stop_process(router.proc)


def test_the_link_budget_reads_its_linger_and_refuses_a_negative_one(monkeypatch) -> None:
    from atr.errors import ConfigError

    monkeypatch.setenv("ATR_LINK_LINGER_S", "0.25")
    assert LinkBudget.from_env().linger_s == 0.25
    monkeypatch.setenv("ATR_LINK_LINGER_S", "0")  # no linger: a closing node leaves at once
    assert LinkBudget.from_env().linger_s == 0.0
    monkeypatch.setenv("ATR_LINK_LINGER_S", "-1")
    with pytest.raises(ConfigError, match="linger_s -1.0 must be a number >= 0"):
        LinkBudget.from_env()
