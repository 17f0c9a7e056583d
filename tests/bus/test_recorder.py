"""The recorder as a real process on a real Zenoh bus: what it writes, bad input, SIGTERM and kill
-9."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import msgpack
import pytest
import zenoh
from mcap.reader import make_reader

from bus import codec, keys, mcap_tools, schemas
from bus.recorder import RecorderNode
from bus.session import open_session

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _procs import Watcher, atr, finish, helper  # noqa: E402
from conftest import peer_config  # noqa: E402  (tests/ is on sys.path via _procs)

pytestmark = pytest.mark.e2e

INPUTS = ("sim/uav1/truth", "atr/uav1/imu", "atr/uav1/camera/image", "atr/uav1/lidar/cloud")


def _messages(path: Path) -> list[tuple[str, object, object]]:
    with open(path, "rb") as f:
        return [(c.topic, s, m) for s, c, m in make_reader(f, validate_crcs=True).iter_messages()]


@contextmanager
def _recorder(hub: str, *command: str) -> Iterator[subprocess.Popen[bytes]]:
    """`atr COMMAND` (a recorder) on the hub's bus, once its Status says it is running."""
    with _recorder_and_bus(hub, *command) as (recorder, _):
        yield recorder


@contextmanager
def _recorder_and_bus(
    hub: str, *command: str
) -> Iterator[tuple[subprocess.Popen[bytes], zenoh.Session]]:
    """As `_recorder`, with the session that saw its Status: one that already knows the recorder."""
    watcher = Watcher(hub)
    try:
        recorder = atr(hub, *command)
        watcher.wait_for("recorder")
        yield recorder, watcher.session
    finally:
        watcher.close()


def _stop(recorder: subprocess.Popen[bytes], sig: int = signal.SIGTERM) -> None:
    """Stop the recorder with `sig`; it must exit 0."""
    recorder.send_signal(sig)
    code, err = finish(recorder)
    assert code == 0, err


def _record_published(hub: str, command: tuple[str, ...], *publish: str) -> None:
    """The recorder `atr COMMAND` records what `_bus_helpers.py publish PUBLISH` sends, then stops on
    SIGTERM and exits 0."""
    with _recorder(hub, *command) as recorder:
        code, err = finish(helper(hub, "publish", *publish))
        assert code == 0, err
        time.sleep(0.3)
        _stop(recorder)


def test_records_every_message_as_sent_and_closes_cleanly_on_sigterm(
    hub: str, tmp_path: Path
) -> None:
    out = tmp_path / "rec.mcap"
    _record_published(hub, ("record", "--out", str(out)), "--frames", "4")

    assert mcap_tools.check(out) == []
    records = _messages(out)
    data = [(t, s, m) for t, s, m in records if t in INPUTS + ("atr/uav1/pose/camera",)]
    assert len(data) == 4 * 5
    for topic, schema, message in data:
        decoded = codec.decode(keys.message_type(topic), message.data)  # the bytes decode as sent
        assert schema.name == keys.message_type(topic)
        assert schema.encoding == "jsonschema" and schema.data == schemas.schema_bytes(schema.name)
        assert message.publish_time == decoded["stamp_ns"] and message.sequence == decoded["seq"]
    frames = [codec.unpack(m.data)["frame_seq"] for t, _, m in data if t == "atr/uav1/camera/image"]
    assert frames == [0, 1, 2, 3]
    log_times = [m.log_time for _, _, m in records]
    assert log_times == sorted(log_times)
    # its own Status carries the counters
    statuses = [codec.unpack(m.data) for t, _, m in records if t == "atr/uav1/recorder/status"]
    assert statuses and all({"messages", "bytes"} <= set(s["counters"]) for s in statuses)
    assert max(s["counters"]["messages"] for s in statuses) > 0


def test_a_heartbeat_sent_before_the_recorder_is_attached_carries_its_counters(hub: str) -> None:
    # The recorder's subscriber exists before `node.recorder` is set; a heartbeat in that gap is
    # recorded too and must already have the recorder's counters (zeros), like every other Status.
    with RecorderNode("recorder", "uav9", zenoh_config=peer_config(hub), heartbeat_s=60) as node:
        assert node.recorder is None
        extra = node.extra_status()
    assert extra["counters"] == dict.fromkeys(
        (
            "messages",
            "bytes",
            "channels",
            "gaps",
            "lost",
            "queue_max",
            "unstamped",
            "refused",
            "write_errors",
            "segment",
        ),
        0,
    )
    assert extra["handled_by_key"] == {}


def test_bad_input_from_a_foreign_session_is_recorded_as_it_came(hub: str, tmp_path: Path) -> None:
    out = tmp_path / "bad.mcap"
    foreign = open_session(peer_config(hub))
    not_msgpack = b"\xc1\xff definitely not msgpack"
    breaks_schema = msgpack.packb({"stamp_ns": 77, "seq": 3, "encoding": "bgr16"})
    unknown_key = msgpack.packb({"hello": 1})
    sent = [
        ("atr/uav1/camera/image", not_msgpack, None),
        ("atr/uav1/imu", breaks_schema, None),
        ("atr/uav1/lidar/cloud", b"", codec.encode_attachment(9, 123, "foreign")),
        ("atr/elsewhere/unknown/thing", unknown_key, b"\x00garbage attachment"),
    ]
    try:
        with _recorder(hub, "record", "--out", str(out)) as recorder:
            time.sleep(0.3)
            for key, payload, attachment in sent:
                foreign.put(key, payload, attachment=attachment)
            time.sleep(0.5)
            _stop(recorder, signal.SIGINT)
    finally:
        foreign.close()

    assert mcap_tools.check(out) == []
    got = {t: (s, m) for t, s, m in _messages(out) if t in {k for k, _, _ in sent}}
    for key, payload, _ in sent:
        assert got[key][1].data == payload, key
    # seq/stamp: from the attachment, else the payload's own fields, else 0
    assert (
        got["atr/uav1/lidar/cloud"][1].sequence,
        got["atr/uav1/lidar/cloud"][1].publish_time,
    ) == (9, 123)
    assert (got["atr/uav1/imu"][1].sequence, got["atr/uav1/imu"][1].publish_time) == (3, 77)
    assert (
        got["atr/uav1/camera/image"][1].sequence,
        got["atr/uav1/camera/image"][1].publish_time,
    ) == (0, 0)
    assert got["atr/elsewhere/unknown/thing"][0] is None  # outside the contract: no schema
    assert got["atr/uav1/imu"][0].name == "ImuBatch"


def test_kill_9_leaves_a_file_that_recovers_up_to_its_last_chunk(hub: str, tmp_path: Path) -> None:
    out = tmp_path / "crash.mcap"
    with _recorder(hub, "record", "--out", str(out), "--flush-interval", "0.2") as recorder:
        code, err = finish(helper(hub, "publish", "--frames", "6", "--image-shape", "240", "320"))
        assert code == 0, err
        time.sleep(1.0)  # several flush intervals: every published message is in a written chunk
        recorder.send_signal(signal.SIGKILL)
        finish(recorder)

    problems = mcap_tools.check(out)
    assert problems and any("Footer" in p or "truncated" in p for p in problems), problems
    fixed = tmp_path / "fixed.mcap"
    code = __import__("cli.main", fromlist=["main"]).main(["mcap", "recover", str(out), str(fixed)])
    assert code == 0
    assert mcap_tools.check(fixed) == []
    topics = [t for t, _, _ in _messages(fixed)]
    for key in INPUTS:
        assert topics.count(key) == 6, key


def _record_two_frames(hub: str, out: Path, *args: str) -> None:
    """The recorder service with `args` records two published frames, then stops on SIGTERM."""
    _record_published(hub, ("service", "recorder", "--out", str(out), *args), "--frames", "2")


def test_every_recording_says_what_made_it_and_closes_with_a_marker(
    hub: str, tmp_path: Path
) -> None:
    """Provenance (software, configuration, input) and the clean-close marker, as `atr audit` and a
    reader of the file see them; the data section's CRC is written and holds."""
    from mcap.reader import make_reader as reader_of

    from bus import audit, provenance

    source = tmp_path / "input.mcap"
    source.write_bytes(b"a recording a replay would publish")
    out = tmp_path / "rec.mcap"
    _record_two_frames(
        hub,
        out,
        "--layout",
        "local",
        "--set",
        "recognition.descriptor=fpfh",
        "--input",
        str(source),
    )

    assert mcap_tools.check(out) == []  # includes the data section's CRC
    with open(out, "rb") as f:
        r = reader_of(f)
        metadata = {m.name: m.metadata for m in r.iter_metadata()}
        attachments = {a.name: a for a in r.iter_attachments()}
    record = metadata[provenance.METADATA_NAME]
    assert record["layout"] == "local" and record["uav"] == "uav1"
    assert record["overrides"] == '["recognition.descriptor=fpfh"]'
    assert record["input_sha256"] == provenance.file_sha256(source)
    assert record["source_sha256"] == provenance.source_sha256()
    config = attachments[provenance.CONFIG_ATTACHMENT].data
    assert b'"descriptor": "fpfh"' in config
    assert record["config_sha256"] == __import__("hashlib").sha256(config).hexdigest()
    assert metadata[provenance.END_METADATA_NAME]["clean_close"] == "true"
    report = audit.audit(out)
    assert report.closed and report.provenance[0]["layout"] == "local"


def test_a_recorder_says_it_is_running_once_its_provenance_is_in_hand(
    hub: str, tmp_path: Path
) -> None:
    """The provenance record precedes every message sent after the recorder said it was running:
    gathering it (two CPU seconds) is done before a flight that waits for the recorder starts, not
    beside the flight's first scenes."""
    from mcap.records import Channel, Message, Metadata
    from mcap.stream_reader import StreamReader

    from bus import provenance

    source = tmp_path / "input.mcap"
    with open(source, "wb") as f:  # a replay's input is hashed into the provenance: a second here
        f.truncate(1 << 30)  # sparse: no disk
    out = tmp_path / "rec.mcap"
    command = (
        "service",
        "recorder",
        "--out",
        str(out),
        "--layout",
        "local",
        "--input",
        str(source),
    )
    with _recorder_and_bus(hub, *command) as (recorder, bus):
        bus.put("atr/uav1/probe", b"sent as soon as the recorder said it was running")
        time.sleep(0.3)
        _stop(recorder)

    order = []  # the file's records in order, chunks opened
    with open(out, "rb") as f:
        for r in StreamReader(f, skip_magic=False).records:
            if isinstance(r, Channel):
                order.append(("channel", r.id, r.topic))
            elif isinstance(r, Message):
                order.append(("message", r.channel_id))
            elif isinstance(r, Metadata) and r.name == provenance.METADATA_NAME:
                order.append(("provenance",))
    probe = next(c[1] for c in order if c[0] == "channel" and c[2] == "atr/uav1/probe")
    assert order.index(("provenance",)) < order.index(("message", probe)), order


def test_a_recorder_with_a_key_seals_its_file_when_it_closes(hub: str, tmp_path: Path) -> None:
    """The air recorder's half of the chain of custody: its file is sealed as it closes, and the
    verifier with the pinned public key finds it intact; a bad key is refused before recording."""
    from bus import seal

    private, public = seal.generate_keys(tmp_path / "keys")
    bad = atr(
        hub, "service", "recorder", "--out", str(tmp_path / "x.mcap"), "--seal-key", str(public)
    )
    code, err = finish(bad)
    assert code == 1 and "no usable private key" in err and "Traceback" not in err
    assert not (tmp_path / "x.mcap").exists()
    out = tmp_path / "air.mcap"
    _record_two_frames(hub, out, "--seal-key", str(private))
    verdict = seal.verify(out, seal.load_public_key(public))
    assert verdict.intact and verdict.sealed_messages > 0
