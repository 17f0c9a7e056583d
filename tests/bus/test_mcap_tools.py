"""The MCAP writer and `atr mcap` tools on files made here, read back with the `mcap` library."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer as McapLibWriter

from atr.errors import RecordingError
from bus import mcap_tools, schemas
from cli.main import main as atr_main


def _write(
    path: Path, n: int = 40, chunk_size: int = 2000
) -> list[tuple[str, int, int, int, bytes]]:
    """A file with two schema'd channels and one without schema; returns what was written."""
    written = []
    with mcap_tools.ChunkedWriter(path, chunk_size_bytes=chunk_size) as w:
        sid = w.add_schema("Image", "jsonschema", schemas.schema_bytes("Image"))
        a = w.add_channel("atr/uav1/camera/image", "msgpack", sid)
        b = w.add_channel("atr/uav1/imu", "msgpack", w.add_schema("ImuBatch", "jsonschema", b"{}"))
        c = w.add_channel("foreign/key", "msgpack", 0)
        for i in range(n):
            channel, topic = [
                (a, "atr/uav1/camera/image"),
                (b, "atr/uav1/imu"),
                (c, "foreign/key"),
            ][i % 3]
            data = bytes([i % 256]) * (50 + 7 * i)
            w.add_message(channel, 1_000 + 10 * i, 500 + i, i, data)
            written.append((topic, 1_000 + 10 * i, 500 + i, i, data))
    return written


def test_written_file_reads_back_with_the_mcap_library(tmp_path: Path) -> None:
    path = tmp_path / "a.mcap"
    written = _write(path)
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        got = [
            (c.topic, m.log_time, m.publish_time, m.sequence, m.data)
            for _, c, m in reader.iter_messages()
        ]
        summary = reader.get_summary()
    assert got == written
    assert summary is not None and summary.statistics.message_count == len(written)
    assert summary.statistics.chunk_count > 3  # small chunks: several were written
    image = next(s for s in summary.schemas.values() if s.name == "Image")
    assert image.encoding == "jsonschema" and image.data == schemas.schema_bytes("Image")
    foreign = next(c for c in summary.channels.values() if c.topic == "foreign/key")
    assert foreign.schema_id == 0 and foreign.message_encoding == "msgpack"
    assert mcap_tools.check(path) == []


def test_check_passes_a_file_of_the_reference_writer(tmp_path: Path) -> None:
    path = tmp_path / "ref.mcap"
    with open(path, "wb") as f:
        w = McapLibWriter(f, chunk_size=300)
        w.start()
        sid = w.register_schema("Image", "jsonschema", b"{}")
        cid = w.register_channel("t", "msgpack", sid)
        for i in range(30):
            w.add_message(cid, log_time=i, data=b"x" * i, publish_time=i, sequence=i)
        w.finish()
    assert mcap_tools.check(path) == []
    info = mcap_tools.info(path)
    assert info.messages == 30 and info.channels[0].schema_name == "Image" and info.closed


def _chunk_offsets(path: Path) -> list[tuple[int, int]]:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return [(ci.chunk_start_offset, ci.chunk_length) for ci in summary.chunk_indexes]


def test_check_names_a_flipped_byte_inside_a_chunk(tmp_path: Path) -> None:
    path = tmp_path / "flip.mcap"
    _write(path)
    offset, length = _chunk_offsets(path)[2]
    data = bytearray(path.read_bytes())
    data[offset + length - 20] ^= 0x5A  # inside the compressed records of the third chunk
    path.write_bytes(bytes(data))
    problems = mcap_tools.check(path)
    assert problems, "a corrupted chunk must be reported"
    assert any(
        f"chunk #3 at offset {offset}" in p and ("CRC" in p or "corrupted" in p) for p in problems
    ), problems


def test_check_names_a_truncated_file_and_recover_keeps_its_complete_chunks(tmp_path: Path) -> None:
    path = tmp_path / "cut.mcap"
    written = _write(path)
    chunks = _chunk_offsets(path)
    offset, length = chunks[-2]
    cut = tmp_path / "cut-short.mcap"
    cut.write_bytes(path.read_bytes()[: offset + length // 2])  # inside the second-to-last chunk
    problems = mcap_tools.check(cut)
    assert any("truncated" in p and f"offset {offset}" in p for p in problems), problems

    out = tmp_path / "recovered.mcap"
    result = mcap_tools.recover(cut, out)
    assert result.problem is not None and "truncated" in result.problem
    assert mcap_tools.check(out) == []
    with open(out, "rb") as f:
        got = [
            (c.topic, m.log_time, m.publish_time, m.sequence, m.data)
            for _, c, m in make_reader(f).iter_messages()
        ]
    assert got == written[: len(got)]
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    first_lost_time = summary.chunk_indexes[-2].message_start_time
    # every message of the chunks before the cut, in order, nothing invented
    assert got == [w for w in written if w[1] < first_lost_time]


def test_check_reports_statistics_that_disagree_with_the_data(tmp_path: Path) -> None:
    path = tmp_path / "stats.mcap"
    w = mcap_tools.ChunkedWriter(path)
    cid = w.add_channel("t", "msgpack", 0)
    w.add_message(cid, 5, 5, 0, b"abc")
    w.statistics.message_count = 7  # a writer bug: the summary claims more than the data holds
    w.close()
    problems = mcap_tools.check(path)
    assert any("message_count = 7" in p for p in problems), problems


def test_garbage_is_refused_with_a_typed_error(tmp_path: Path) -> None:
    path = tmp_path / "garbage.mcap"
    path.write_bytes(b"not an mcap file at all")
    assert mcap_tools.check(path)
    with pytest.raises(RecordingError):
        mcap_tools.recover(path, tmp_path / "out.mcap")
    with pytest.raises(RecordingError):
        mcap_tools.info(tmp_path / "missing.mcap")


def test_cli_check_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    good, bad = tmp_path / "good.mcap", tmp_path / "bad.mcap"
    _write(good)
    bad.write_bytes(good.read_bytes()[:-100])
    assert atr_main(["mcap", "check", str(good)]) == 0
    assert capsys.readouterr().out.strip() == "OK"
    assert atr_main(["mcap", "check", str(bad)]) == 1
    out = capsys.readouterr().out
    assert str(bad) in out and "OK" not in out
    assert atr_main(["mcap", "info", str(good)]) == 0
    out = capsys.readouterr().out
    assert "atr/uav1/camera/image" in out and "Image" in out and "messages:  40" in out


def _corrupt_chunk(path: Path, which: int) -> int:
    """Flips a byte inside the compressed records of chunk `which`; returns the chunk's offset."""
    offset, length = _chunk_offsets(path)[which]
    data = bytearray(path.read_bytes())
    data[offset + length - 20] ^= 0x5A
    path.write_bytes(bytes(data))
    return offset


def test_the_writer_never_truncates_an_existing_file(tmp_path: Path) -> None:
    path = tmp_path / "kept.mcap"
    _write(path)
    before = path.read_bytes()
    with pytest.raises(RecordingError, match="already exists"):
        mcap_tools.ChunkedWriter(path)
    assert path.read_bytes() == before


def test_segments_continue_a_recording_and_read_as_one(tmp_path: Path) -> None:
    first = tmp_path / "flight.mcap"
    written = _write(first, n=12)
    last_offset, _ = _chunk_offsets(first)[-1]
    with open(first, "rb") as f:
        last_start = make_reader(f).get_summary().chunk_indexes[-1].message_start_time
    first.write_bytes(first.read_bytes()[: last_offset + 5])  # a crash inside its last chunk
    kept = [w for w in written if w[1] < last_start]
    writer, path, index = mcap_tools.create_segment(first)
    assert (path, index) == (tmp_path / "flight.1.mcap", 1)
    cid = writer.add_channel("atr/uav1/imu", "msgpack", 0)
    later = [("atr/uav1/imu", 9_000 + i, i, i, bytes([i])) for i in range(5)]
    for topic, log_time, stamp, seq, data in later:
        writer.add_message(cid, log_time, stamp, seq, data)
    writer.close()
    second = mcap_tools.create_segment(first)
    second[0].close()
    assert second[1:] == (tmp_path / "flight.2.mcap", 2)

    assert mcap_tools.segments(first) == [first, path, second[1]]
    with open(path, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["atr.segment"] == {
        "recording": "flight.mcap",
        "segment": "1",
        "continues": "flight.mcap",
        "previous_closed": "false",
    }
    got = [
        (t, m.log_time, m.publish_time, m.sequence, m.data)
        for t, m in mcap_tools.iter_messages(first)
    ]
    assert kept and got == kept + later
    info = mcap_tools.info(first)
    assert info.messages == len(got) and len(info.segments) == 3 and not info.closed
    assert any("flight.mcap" in p and "truncated" in p for p in info.problems)
    out = tmp_path / "joined.mcap"
    result = mcap_tools.recover(first, out)
    assert result.segments == 3 and result.messages == len(got)
    assert mcap_tools.check(out) == []
    assert [(t, m.log_time, m.data) for t, m in mcap_tools.iter_messages(out)] == [
        (t, lt, d) for t, lt, _, _, d in got
    ]
    problems = mcap_tools.check(first)
    assert any(p.startswith("flight.mcap: truncated") for p in problems), problems
    assert not any(p.startswith("flight.1.mcap") for p in problems), problems


def test_recover_keeps_every_intact_chunk_after_a_corrupted_one(tmp_path: Path) -> None:
    path = tmp_path / "bad-first.mcap"
    written = _write(path, n=12, chunk_size=300)
    chunks = _chunk_offsets(path)
    assert len(chunks) >= 4
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    lost_end = summary.chunk_indexes[0].message_end_time
    _corrupt_chunk(path, 0)  # the chunk that defines the channels

    out = tmp_path / "out.mcap"
    result = mcap_tools.recover(path, out)
    assert mcap_tools.check(out) == []
    with open(out, "rb") as f:
        got = [
            (c.topic, m.log_time, m.publish_time, m.sequence, m.data)
            for _, c, m in make_reader(f).iter_messages()
        ]
    assert got == [w for w in written if w[1] > lost_end]
    assert result.messages == len(got) > 0
    assert any(f"offset {chunks[0][0]}" in p for p in result.problems), result.problems


def test_recover_goes_on_after_a_chunk_whose_framing_is_broken(tmp_path: Path) -> None:
    path = tmp_path / "bad-length.mcap"
    written = _write(path, n=12, chunk_size=300)
    (offset, _), (next_offset, _) = _chunk_offsets(path)[1:3]
    data = bytearray(path.read_bytes())
    data[offset + 1 : offset + 9] = (2**40).to_bytes(8, "little")  # record length: nonsense
    path.write_bytes(bytes(data))
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    after = summary.chunk_indexes[2].message_start_time
    out = tmp_path / "out.mcap"
    mcap_tools.recover(path, out)
    with open(out, "rb") as f:
        times = [m.log_time for _, _, m in make_reader(f).iter_messages()]
    assert [w[1] for w in written if w[1] >= after] == [t for t in times if t >= after]
    assert times[0] == written[0][1]


def test_info_warns_and_exits_1_on_a_corrupted_chunk(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.mcap"
    _write(path, n=12, chunk_size=300)
    offset = _corrupt_chunk(path, 0)
    assert atr_main(["mcap", "info", str(path)]) == 1
    captured = capsys.readouterr()
    assert f"offset {offset}" in captured.err and "warning" in captured.err
    assert "messages:  0" not in captured.out  # the intact chunks are counted


def test_reading_a_corrupted_chunk_raises_a_recording_error_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "bad.mcap"
    _write(path, n=12, chunk_size=300)
    offset = _corrupt_chunk(path, 2)
    with pytest.raises(RecordingError, match=rf"bad\.mcap: chunk #3 at offset {offset}: "):
        list(mcap_tools.iter_messages(path))


def test_the_data_section_crc_catches_an_edit_no_other_crc_covers(tmp_path: Path) -> None:
    """A Metadata record has no CRC of its own: an edit of its value (same length) is seen only by
    the data section's CRC, which the writer records in DataEnd and `check` recomputes."""
    path = tmp_path / "a.mcap"
    with mcap_tools.ChunkedWriter(path, metadata={"provenance": {"config_sha256": "aaaa"}}) as w:
        channel = w.add_channel("atr/uav1/imu", "msgpack", 0)
        w.add_message(channel, 1, 1, 0, b"x" * 100)
    assert mcap_tools.check(path) == []
    data = path.read_bytes()
    assert data.count(b"aaaa") == 1
    path.write_bytes(data.replace(b"aaaa", b"bbbb"))
    problems = mcap_tools.check(path)
    assert any("data section CRC mismatch" in p for p in problems), problems
