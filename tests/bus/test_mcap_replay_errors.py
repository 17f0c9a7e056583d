"""Replaying a recording with a corrupted chunk: a RecordingError naming the file and the chunk,
never a decompressor's traceback."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from atr.errors import RecordingError
from bus import mcap_tools
from bus.replayer import Replayer
from bus.session import open_session

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import peer_config  # noqa: E402

pytestmark = pytest.mark.e2e


def test_replay_of_a_corrupted_chunk_raises_a_recording_error(hub: str, tmp_path: Path) -> None:
    path = tmp_path / "bad.mcap"
    with mcap_tools.ChunkedWriter(path, chunk_size_bytes=300) as w:
        cid = w.add_channel("atr/uav1/imu", "msgpack", 0)
        for i in range(12):
            w.add_message(cid, 1_000 + i, i, i, bytes([i]) * 100)
    with open(path, "rb") as f:
        index = make_reader(f).get_summary().chunk_indexes[2]
    data = bytearray(path.read_bytes())
    data[index.chunk_start_offset + index.chunk_length - 20] ^= 0x5A
    path.write_bytes(bytes(data))

    session = open_session(peer_config(hub))
    try:
        with Replayer(path, session, match_timeout_s=0.1, settle_s=0.0) as replayer:
            with pytest.raises(RecordingError, match=f"offset {index.chunk_start_offset}"):
                replayer.fast()
            # every message of the chunks before the broken one went out
            assert replayer.stats.published == index.message_start_time - 1_000
    finally:
        session.close()
