"""A recorder killed and started again with the same `--out` (what `atr up` does): the first
segment keeps its messages, the second continues the recording, and the tools read both as one."""

from __future__ import annotations

import signal
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from bus import codec, mcap_tools

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _procs import Watcher, atr, finish, helper  # noqa: E402

pytestmark = pytest.mark.e2e

IMAGE = "atr/uav1/camera/image"
INPUTS = ("sim/uav1/truth", "atr/uav1/imu", IMAGE, "atr/uav1/lidar/cloud")


def _record_and_publish(hub: str, out: Path, seed: int, frames: int):
    watcher = Watcher(hub)
    try:
        recorder = atr(hub, "record", "--out", str(out), "--flush-interval", "0.2")
        watcher.wait_for("recorder")
        code, err = finish(helper(hub, "publish", "--frames", str(frames), "--seed", str(seed)))
        assert code == 0, err
        time.sleep(1.0)  # several flush intervals: every message is in a written chunk
    finally:
        watcher.close()
    return recorder


def test_a_restarted_recorder_continues_in_a_new_segment_and_erases_nothing(
    hub: str, tmp_path: Path
) -> None:
    out = tmp_path / "flight.mcap"
    first = _record_and_publish(hub, out, seed=1, frames=3)
    first.send_signal(signal.SIGKILL)
    finish(first)
    cut_bytes = out.read_bytes()
    assert len(cut_bytes) > 0 and not mcap_tools.is_closed(out)

    second = _record_and_publish(hub, out, seed=2, frames=4)
    second.send_signal(signal.SIGTERM)
    code, err = finish(second)
    assert code == 0, err

    # the cut segment is untouched and recoverable; the new one is a clean file of its own
    assert out.read_bytes() == cut_bytes
    segment = tmp_path / "flight.1.mcap"
    assert mcap_tools.segments(out) == [out, segment]
    assert mcap_tools.check(segment) == []
    with open(segment, "rb") as f:
        reader = make_reader(f)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        reports = [
            codec.unpack(m.data)["reason"]
            for _, c, m in reader.iter_messages()
            if c.topic == "atr/uav1/recorder/errors"
        ]
    assert meta["atr.segment"]["continues"] == "flight.mcap"
    assert meta["atr.segment"]["previous_closed"] == "false"
    assert any("flight.1.mcap" in r and "cut" in r for r in reports), reports

    # read as one recording: every input of both runs, in order
    both = list(mcap_tools.iter_messages(out))
    log_times = [m.log_time for _, m in both]
    assert log_times == sorted(log_times)
    frames = [codec.unpack(m.data)["frame_seq"] for t, m in both if t == IMAGE]
    assert frames == [0, 1, 2, 0, 1, 2, 3]
    for key in INPUTS:
        assert sum(t == key for t, _ in both) == 7, key
    joined = tmp_path / "joined.mcap"
    result = mcap_tools.recover(out, joined)
    assert result.segments == 2 and result.messages == len(both)
    assert mcap_tools.check(joined) == []
