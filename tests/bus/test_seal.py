"""Sealing and verifying recordings: every kind of tampering an attacker can do with valid CRCs is
detected and located; keys are pinned by the verifier."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import pytest
from mcap.writer import CompressionType
from mcap.writer import Writer as McapLibWriter

from atr.errors import ConfigError, RecordingError
from bus import seal as sealing

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _atr_cli import atr  # noqa: E402

# (topic, log_time, publish_time, sequence, payload)
Row = tuple[str, int, int, int, bytes]


def _rows(n: int = 30) -> list[Row]:
    topics = ["atr/uav1/camera/image", "atr/uav1/imu", "atr/uav1/detections"]
    return [
        (topics[i % 3], 1_000 + 10 * i, 500 + i, i // 3, bytes([i]) * (20 + i)) for i in range(n)
    ]


def _write(path: Path, rows: list[Row], metadata: dict[str, str] | None = None) -> None:
    """What an attacker does: rewrite the whole file with the reference writer, CRCs all valid."""
    with path.open("wb") as f:
        w = McapLibWriter(f, chunk_size=400, compression=CompressionType.ZSTD)
        w.start(profile="", library="passive-atr recorder")
        schema = w.register_schema("Any", "jsonschema", b"{}")
        channels: dict[str, int] = {}
        for topic, log_time, publish_time, seq, data in rows:
            if topic not in channels:
                channels[topic] = w.register_channel(topic, "msgpack", schema)
            w.add_message(channels[topic], log_time, data, publish_time, seq)
        w.add_metadata("provenance", metadata or {"version": "1.0", "uav": "uav1"})
        w.finish()


@pytest.fixture(scope="module")
def keys(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return sealing.generate_keys(tmp_path_factory.mktemp("keys"))


def _sealed(tmp_path: Path, keys: tuple[Path, Path]) -> Path:
    path = tmp_path / "flight.mcap"
    _write(path, _rows())
    sealing.seal(path, sealing.load_private_key(keys[0]))
    return path


def _verify(path: Path, keys: tuple[Path, Path]) -> sealing.Verdict:
    return sealing.verify(path, sealing.load_public_key(keys[1]))


def test_an_untouched_recording_verifies(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    verdict = _verify(_sealed(tmp_path, keys), keys)
    assert verdict.intact and verdict.signature_ok and verdict.sealed_messages == 30
    assert verdict.lines() == []


def test_a_flipped_payload_byte_is_named(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    path = _sealed(tmp_path, keys)
    rows = _rows()
    topic, log_time, publish_time, seq, data = rows[7]
    rows[7] = (topic, log_time, publish_time, seq, data[:3] + bytes([data[3] ^ 1]) + data[4:])
    _write(path, rows)
    verdict = _verify(path, keys)
    assert not verdict.intact and verdict.signature_ok
    assert [(c.topic, c.log_time, c.sequence) for c in verdict.changed] == [(topic, log_time, seq)]
    assert not verdict.added and not verdict.removed and not verdict.moved


def test_a_removed_message_is_named(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    path = _sealed(tmp_path, keys)
    rows = _rows()
    gone = rows.pop(12)
    _write(path, rows)
    verdict = _verify(path, keys)
    assert [(r.topic, r.log_time, r.sequence) for r in verdict.removed] == [gone[:2] + gone[3:4]]
    assert not verdict.changed and not verdict.added and not verdict.intact


def test_an_inserted_message_is_named(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    path = _sealed(tmp_path, keys)
    rows = _rows()
    extra: Row = ("atr/uav1/detections", 1_095, 509, 3, b"a forged detection")
    rows.insert(10, extra)
    _write(path, rows)
    verdict = _verify(path, keys)
    assert [(a.topic, a.log_time, a.sequence) for a in verdict.added] == [(extra[0], 1_095, 3)]
    assert not verdict.changed and not verdict.removed and not verdict.intact


def test_a_reordered_pair_is_named(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    path = _sealed(tmp_path, keys)
    rows = _rows()
    rows[20], rows[21] = rows[21], rows[20]
    _write(path, rows)
    verdict = _verify(path, keys)
    assert len(verdict.moved) == 1
    assert verdict.moved[0].log_time in (rows[20][1], rows[21][1])
    assert not verdict.changed and not verdict.added and not verdict.removed


def test_a_changed_metadata_record_is_named(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    path = _sealed(tmp_path, keys)
    _write(path, _rows(), metadata={"version": "9.9", "uav": "uav1"})
    verdict = _verify(path, keys)
    assert [c.topic for c in verdict.changed] == ["@metadata provenance"]
    assert not verdict.intact


def test_a_reforged_manifest_is_refused(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    """An attacker who edits the file and re-seals it with a key of their own fails: the verifier
    pins its key; one who edits the manifest's records fails the signed root."""
    path = _sealed(tmp_path, keys)
    rows = _rows()
    rows[0] = (*rows[0][:4], b"forged")
    _write(path, rows)
    attacker = sealing.generate_keys(tmp_path / "attacker")
    sealing.seal(path, sealing.load_private_key(attacker[0]))
    verdict = _verify(path, keys)
    assert not verdict.signature_ok and not verdict.intact
    assert any("not the trusted key" in p for p in verdict.problems)

    (tmp_path / "b").mkdir()
    path2 = _sealed(tmp_path / "b", keys)
    manifest = sealing.seal_path(path2)
    text = manifest.read_text()
    original = sealing.read_leaves(path2).leaves
    digest = next(leaf.digest for leaf in original if not leaf.topic.startswith("@"))
    manifest.write_text(text.replace(digest, "0" * 64, 1))
    verdict = _verify(path2, keys)
    assert any("signed root" in p for p in verdict.problems) and not verdict.intact


def test_a_cut_recording_verifies_what_is_there(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    path = _sealed(tmp_path, keys)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    verdict = _verify(path, keys)
    assert not verdict.intact and verdict.signature_ok
    assert any("cut or broken" in p for p in verdict.problems)
    assert verdict.removed and not verdict.changed and not verdict.added
    # what survived the cut is the sealed prefix, unchanged
    assert len(verdict.removed) < verdict.sealed_messages


def test_keys_are_refused_clearly(tmp_path: Path, keys: tuple[Path, Path]) -> None:
    with pytest.raises(ConfigError, match="refusing to overwrite"):
        sealing.generate_keys(keys[0].parent)
    with pytest.raises(ConfigError, match="no usable public key"):
        sealing.load_public_key(keys[0])
    (tmp_path / "junk.pub").write_text("hello")
    with pytest.raises(ConfigError, match="not a PEM key file"):
        sealing.load_public_key(tmp_path / "junk.pub")
    with pytest.raises(RecordingError, match="no seal"):
        _write(tmp_path / "x.mcap", _rows(3))
        sealing.verify(tmp_path / "x.mcap", sealing.load_public_key(keys[1]))


def test_cli_exit_codes(tmp_path: Path) -> None:
    path = tmp_path / "f.mcap"
    _write(path, _rows())
    assert atr("keygen", "--out", str(tmp_path / "k")).returncode == 0
    sealed = atr("seal", str(path), "--key", str(tmp_path / "k" / "recorder.key"))
    assert sealed.returncode == 0, sealed.stderr
    receipt = tmp_path / "receipt.json"
    ok = atr(
        "verify", str(path), "--pub", str(tmp_path / "k" / "recorder.pub"), "--json", str(receipt)
    )
    assert ok.returncode == 0 and "intact" in ok.stdout
    recorded = json.loads(receipt.read_text())
    assert recorded["intact"] and recorded["problems"] == []
    assert recorded["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    rows = _rows()
    rows[4] = (*rows[4][:4], b"changed")
    _write(path, rows)
    bad = atr("verify", str(path), "--pub", str(tmp_path / "k" / "recorder.pub"))
    assert bad.returncode == 1 and "changed: atr/uav1/imu at log time 1040 ns" in bad.stdout
    missing = atr("verify", str(tmp_path / "nope.mcap"), "--pub", str(tmp_path / "k/recorder.pub"))
    assert missing.returncode == 2 and "Traceback" not in missing.stderr
    for result in (ok, bad, missing, sealed):
        assert "Traceback" not in result.stderr
