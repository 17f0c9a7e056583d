"""A recording's chain of custody: a signed manifest that says, message by message, what the file held
when it was sealed, and a verifier that names every message changed, added, removed or moved since.

MCAP's CRCs protect against accidents, not people: whoever edits a file recomputes them. A seal does
what a CRC cannot. `seal(path, private_key)` reads the file once and makes one *leaf* per record that
carries meaning, in file order:

- every Message: its topic, log time, publish time, sequence and the SHA-256 of its payload;
- every Schema and Channel definition (first definition of each id), every Metadata record and every
  Attachment, and the Header (profile, library): what a reader needs to interpret the messages.

The leaves are hashed into a Merkle tree (RFC 6962: leaf = H(0x00 || leaf), node = H(0x01 || l || r))
whose root, with the leaf count and the file's name, is signed with Ed25519 (`cryptography`, no
home-made crypto). The manifest keeps every leaf, so `verify` can say *which* message differs, not only
*that* one does. It is written beside the recording as `FILE.seal` (JSON).

The verifier pins the public key it trusts (`verify(path, public_key)`); the manifest names the key's
fingerprint only so a mismatch can be reported clearly. A seal proves that the file holds exactly what
the holder of the private key sealed; it does not prove that what was sealed was true, nor that nothing
was lost before sealing (that is what the recording's own sequence numbers and gap events are for).
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import struct
import time
from collections import Counter
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey
from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from atr.errors import ConfigError, RecordingError

FORMAT = "passive-atr seal 1"
SEAL_SUFFIX = ".seal"
_SIGNED_PREFIX = b"passive-atr seal 1\n"
_LEAF_HEAD = struct.Struct("<QQQ")  # log_time, publish_time, sequence
_HASH_AHEAD_BYTES = 64 * 1024


@dataclass(frozen=True)
class Leaf:
    """One sealed record: what it is (`topic`, or `@schema:1`, `@metadata:NAME`...), when, and its
    content hash (hex SHA-256).
    """

    topic: str
    log_time: int
    publish_time: int
    sequence: int
    digest: str

    def key(self) -> tuple[str, int, int]:
        """What names this record in a report: topic, log time, sequence."""
        return (self.topic, self.log_time, self.sequence)

    def hash(self) -> bytes:
        """The Merkle leaf hash of this record."""
        head = _LEAF_HEAD.pack(self.log_time, self.publish_time, self.sequence)
        topic = self.topic.encode()
        body = struct.pack("<I", len(topic)) + topic + head + bytes.fromhex(self.digest)
        return hashlib.sha256(b"\x00" + body).digest()

    def describe(self) -> str:
        """A line a person reads: topic, log time and sequence."""
        if self.topic.startswith("@"):
            return self.topic[1:]
        return f"{self.topic} at log time {self.log_time} ns, sequence {self.sequence}"


@dataclass
class ReadResult:
    """The leaves of a file, and where reading stopped if the file is cut or broken."""

    leaves: list[Leaf]
    problem: str | None = None


@dataclass
class Verdict:
    """What `verify` found. `intact` is true only when the signature holds and every leaf matches."""

    intact: bool
    signature_ok: bool
    changed: list[Leaf] = field(default_factory=list)
    added: list[Leaf] = field(default_factory=list)
    removed: list[Leaf] = field(default_factory=list)
    moved: list[Leaf] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    sealed_messages: int = 0

    def lines(self) -> list[str]:
        """Each problem on a line of its own, in the order a reader needs them."""
        out = list(self.problems)
        out += [f"changed: {leaf.describe()}" for leaf in self.changed]
        out += [f"added: {leaf.describe()}" for leaf in self.added]
        out += [f"removed: {leaf.describe()}" for leaf in self.removed]
        out += [f"moved: {leaf.describe()}" for leaf in self.moved]
        return out


# Keys -------------------------------------------------------------------------------------------


def generate_keys(out_dir: str | Path, name: str = "recorder") -> tuple[Path, Path]:
    """Write a new Ed25519 key pair as `NAME.key` (PKCS#8 PEM, readable by the owner only) and
    `NAME.pub` (SubjectPublicKeyInfo PEM) in `out_dir`; refuses to overwrite either.

    Raises:
        ConfigError: a key file of that name exists already, or the folder cannot be written.

    """
    out = Path(out_dir)
    private_path, public_path = out / f"{name}.key", out / f"{name}.pub"
    for path in (private_path, public_path):
        if path.exists():
            raise ConfigError(f"{path} exists; refusing to overwrite a key (choose another --name)")
    key = Ed25519PrivateKey.generate()
    private_pem = key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )
    public_pem = key.public_key().public_bytes(
        serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
    )
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd = os.open(private_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as f:
            f.write(private_pem)
        public_path.write_bytes(public_pem)
    except OSError as exc:
        raise ConfigError(f"cannot write keys to {out}: {exc}") from exc
    return private_path, public_path


def load_private_key(path: str | Path) -> Ed25519PrivateKey:
    """Read an Ed25519 private key written by `generate_keys`.

    Raises:
        ConfigError: the file is missing or holds no Ed25519 private key.

    """
    try:
        key = serialization.load_pem_private_key(_read_key_file(path), password=None)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{path} holds no usable private key: {exc}") from exc
    if not isinstance(key, Ed25519PrivateKey):
        raise ConfigError(f"{path} holds a {type(key).__name__}, expected an Ed25519 private key")
    return key


def load_public_key(path: str | Path) -> Ed25519PublicKey:
    """Read an Ed25519 public key written by `generate_keys`.

    Raises:
        ConfigError: the file is missing or holds no Ed25519 public key.

    """
    try:
        key = serialization.load_pem_public_key(_read_key_file(path))
    except ValueError as exc:
        raise ConfigError(f"{path} holds no usable public key: {exc}") from exc
    if not isinstance(key, Ed25519PublicKey):
        raise ConfigError(f"{path} holds a {type(key).__name__}, expected an Ed25519 public key")
    return key


def fingerprint(public_key: Ed25519PublicKey) -> str:
    """SHA-256 of the raw public key, hex: how a person compares two keys."""
    raw = public_key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return hashlib.sha256(raw).hexdigest()


def _read_key_file(path: str | Path) -> bytes:
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"key file {p} does not exist or is not a file")
    data = p.read_bytes()
    if b"-----BEGIN" not in data:
        raise ConfigError(f"{p} is not a PEM key file (expected one written by `atr keygen`)")
    return data


# Reading -----------------------------------------------------------------------------------------


def read_leaves(path: str | Path) -> ReadResult:
    """Every sealed record of `path`, in file order. A file cut short (kill -9 of its recorder) or
    broken gives the leaves up to the break and says where it broke.

    Raises:
        RecordingError: the file does not exist or is not an MCAP file at all.

    """
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"recording {p} does not exist or is not a file")
    leaves: list[Leaf | Future[Leaf]] = []
    seen: set[tuple[str, int]] = set()
    # Large payloads are hashed on a second thread while the reader decompresses the next chunk
    # (hashlib and zstd release the GIL): sealing costs about one read, not a read plus a hash.
    with p.open("rb") as f, ThreadPoolExecutor(max_workers=1) as hasher:
        try:
            for record in _records(f):
                if isinstance(record, Message) and len(record.data) >= _HASH_AHEAD_BYTES:
                    leaves.append(hasher.submit(_leaf, record, seen))
                    continue
                leaf = _leaf(record, seen)
                if leaf is not None:
                    leaves.append(leaf)
        except (McapError, EOFError, ValueError, OSError, struct.error) as exc:
            problem = f"{p} is cut or broken after {len(leaves)} records: {exc}"
        except Exception as exc:  # zstd and the record parsers raise their own types
            problem = f"{p} is broken after {len(leaves)} records: {exc}"
        else:
            problem = None
    done = [leaf.result() if isinstance(leaf, Future) else leaf for leaf in leaves]
    if problem is not None and not done:
        raise RecordingError(f"{p} is not a readable MCAP file: {problem}")
    return ReadResult(done, problem)


def _records(f: IO[bytes]) -> Iterator[Any]:
    # Summary records repeat what the data section defines; the data section is what readers trust
    # for content, so the seal stops at DataEnd.
    from mcap.records import DataEnd

    for record in StreamReader(f, skip_magic=False).records:
        if isinstance(record, DataEnd):
            return
        yield record


def _leaf(record: Any, seen: set[tuple[str, int]]) -> Leaf | None:
    if isinstance(record, Message):
        digest = hashlib.sha256(record.data).hexdigest()
        return Leaf(
            f"#{record.channel_id}", record.log_time, record.publish_time, record.sequence, digest
        )
    if isinstance(record, Schema):
        if ("schema", record.id) in seen:
            return None
        seen.add(("schema", record.id))
        return _definition(f"@schema {record.id} {record.name}", [record.encoding], record.data)
    if isinstance(record, Channel):
        if ("channel", record.id) in seen:
            return None
        seen.add(("channel", record.id))
        parts = [record.topic, record.message_encoding, str(record.schema_id)]
        return _definition(
            f"@channel {record.id} {record.topic}", parts, _canonical(record.metadata)
        )
    if isinstance(record, Metadata):
        return _definition(f"@metadata {record.name}", [], _canonical(record.metadata))
    if isinstance(record, Attachment):
        return Leaf(
            f"@attachment {record.name}",
            record.log_time,
            record.create_time,
            0,
            hashlib.sha256(record.media_type.encode() + b"\x00" + record.data).hexdigest(),
        )
    if isinstance(record, Header):
        return _definition("@header", [record.profile, record.library], b"")
    return None


def _definition(label: str, parts: list[str], data: bytes) -> Leaf:
    body = "\x00".join(parts).encode() + b"\x00" + data
    return Leaf(label, 0, 0, 0, hashlib.sha256(body).hexdigest())


def _canonical(value: Any) -> bytes:
    return json.dumps(value, sort_keys=True, separators=(",", ":")).encode()


def _named(leaves: list[Leaf]) -> list[Leaf]:
    """Message leaves name their channel by id while reading; a report names the topic."""
    topics = {
        leaf.topic.split(" ", 2)[1]: leaf.topic.split(" ", 2)[2]
        for leaf in leaves
        if leaf.topic.startswith("@channel ")
    }
    return [
        Leaf(topics.get(leaf.topic[1:], leaf.topic), *_rest(leaf))
        if leaf.topic.startswith("#")
        else leaf
        for leaf in leaves
    ]


def _rest(leaf: Leaf) -> tuple[int, int, int, str]:
    return leaf.log_time, leaf.publish_time, leaf.sequence, leaf.digest


# Merkle tree ------------------------------------------------------------------------------------


def merkle_root(leaves: list[Leaf]) -> bytes:
    """RFC 6962 Merkle tree hash over the leaves (the empty tree hashes the empty string)."""
    level = [leaf.hash() for leaf in leaves]
    if not level:
        return hashlib.sha256(b"").digest()
    while len(level) > 1:
        paired = [
            hashlib.sha256(b"\x01" + level[i] + level[i + 1]).digest()
            for i in range(0, len(level) - 1, 2)
        ]
        if len(level) % 2:
            paired.append(level[-1])  # an odd node is promoted, as in RFC 6962's split
        level = paired
    return level[0]


# Seal and verify ---------------------------------------------------------------------------------


def seal_path(path: str | Path) -> Path:
    """Where the manifest of `path` lives: beside it, `FILE.seal`."""
    p = Path(path)
    return p.with_name(p.name + SEAL_SUFFIX)


def seal(
    path: str | Path, private_key: Ed25519PrivateKey, out: str | Path | None = None
) -> dict[str, Any]:
    """Seal a recording: read it once, sign the Merkle root of its records, write the manifest to
    `out` (default `FILE.seal`) and return it.

    Raises:
        RecordingError: the file cannot be read, or is cut or broken (seal a repaired copy:
            `atr mcap recover`).

    """
    result = read_leaves(path)
    if result.problem is not None:
        raise RecordingError(f"will not seal a broken recording: {result.problem}")
    leaves = _named(result.leaves)
    signed = {
        "format": FORMAT,
        "file": Path(path).name,
        "records": len(leaves),
        "messages": sum(not leaf.topic.startswith("@") for leaf in leaves),
        "root": merkle_root(leaves).hex(),
        "key": fingerprint(private_key.public_key()),
    }
    manifest = dict(signed)
    manifest["signature"] = base64.b64encode(private_key.sign(_signed_bytes(signed))).decode()
    manifest["leaves"] = [
        [leaf.topic, leaf.log_time, leaf.publish_time, leaf.sequence, leaf.digest]
        for leaf in leaves
    ]
    target = Path(out) if out is not None else seal_path(path)
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_text(json.dumps(manifest, separators=(",", ":")))
    os.replace(tmp, target)
    return manifest


def verify(
    path: str | Path, public_key: Ed25519PublicKey, manifest_path: str | Path | None = None
) -> Verdict:
    """Check a recording against its signed manifest with the public key the verifier trusts.

    Returns:
        The verdict: intact, or each message changed, added, removed or moved (by topic, log time
        and sequence), and any problem with the signature or the manifest.

    Raises:
        RecordingError: the recording or the manifest cannot be read at all.

    """
    manifest = _load_manifest(manifest_path or seal_path(path))
    verdict = Verdict(intact=False, signature_ok=False)
    signed = {k: manifest.get(k) for k in ("format", "file", "records", "messages", "root", "key")}
    try:
        signature = base64.b64decode(str(manifest.get("signature", "")), validate=True)
        public_key.verify(signature, _signed_bytes(signed))
        verdict.signature_ok = True
    except (InvalidSignature, ValueError):
        if signed["key"] != fingerprint(public_key):
            verdict.problems.append(
                f"the seal was made with key {signed['key']}, not the trusted key "
                f"{fingerprint(public_key)}"
            )
        else:
            verdict.problems.append("the manifest's signature does not verify: it was altered")
    sealed = _manifest_leaves(manifest)
    if merkle_root(sealed).hex() != signed["root"] or len(sealed) != signed["records"]:
        verdict.problems.append("the manifest's records do not match its signed root: altered")
    if signed["file"] != Path(path).name:
        verdict.problems.append(f"the seal is of {signed['file']!r}, not {Path(path).name!r}")
    verdict.sealed_messages = int(signed["messages"] or 0)
    current = read_leaves(path)
    if current.problem is not None:
        verdict.problems.append(current.problem)
    _compare(sealed, _named(current.leaves), verdict)
    verdict.intact = not verdict.lines()
    return verdict


def write_receipt(
    out: str | Path, path: str | Path, public_key: Ed25519PublicKey, verdict: Verdict
) -> None:
    """Record a verification: what was checked (the file's SHA-256), with which key, when, and the
    verdict with every problem, as JSON (the ground's receipt of an air recording).

    Raises:
        RecordingError: the receipt cannot be written.

    """
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(1 << 24):
            digest.update(block)
    receipt = {
        "file": Path(path).name,
        "sha256": digest.hexdigest(),
        "key": fingerprint(public_key),
        "verified_at_ns": time.time_ns(),
        "intact": verdict.intact,
        "signature_ok": verdict.signature_ok,
        "sealed_messages": verdict.sealed_messages,
        "problems": verdict.lines(),
    }
    try:
        Path(out).write_text(json.dumps(receipt, indent=1))
    except OSError as exc:
        raise RecordingError(f"cannot write the receipt {out}: {exc}") from exc


def _compare(sealed: list[Leaf], current: list[Leaf], verdict: Verdict) -> None:
    """Align by (topic, log time, sequence, occurrence): same name and other content is a change;
    a name on one side only is an addition or a removal; common names out of order are moves.
    """
    before = _occurrences(sealed)
    after = _occurrences(current)
    after_index = {name: leaf for name, leaf in after}
    before_names = {name for name, _ in before}
    for name, leaf in before:
        other = after_index.get(name)
        if other is None:
            verdict.removed.append(leaf)
        elif other.digest != leaf.digest or other.publish_time != leaf.publish_time:
            verdict.changed.append(other)
    verdict.added = [leaf for name, leaf in after if name not in before_names]
    common = set(after_index) & before_names
    order_before = [name for name, _ in before if name in common]
    order_after = [name for name, _ in after if name in common]
    rank = {name: i for i, name in enumerate(order_before)}
    # A record is moved when it breaks the sealed order: the longest run kept in order stays, the
    # rest are named (for a swapped pair, one of the two).
    kept = _longest_increasing([rank[name] for name in order_after])
    verdict.moved = [after_index[name] for i, name in enumerate(order_after) if i not in kept]


def _occurrences(leaves: list[Leaf]) -> list[tuple[tuple[str, int, int, int], Leaf]]:
    count: Counter[tuple[str, int, int]] = Counter()
    out = []
    for leaf in leaves:
        key = leaf.key()
        out.append(((*key, count[key]), leaf))
        count[key] += 1
    return out


def _longest_increasing(values: list[int]) -> set[int]:
    """Indices of one longest strictly increasing subsequence (patience sorting, O(n log n))."""
    import bisect

    tails: list[int] = []
    tail_index: list[int] = []
    parent = [-1] * len(values)
    for i, v in enumerate(values):
        j = bisect.bisect_left(tails, v)
        if j == len(tails):
            tails.append(v)
            tail_index.append(i)
        else:
            tails[j] = v
            tail_index[j] = i
        parent[i] = tail_index[j - 1] if j > 0 else -1
    kept: set[int] = set()
    i = tail_index[-1] if tail_index else -1
    while i != -1:
        kept.add(i)
        i = parent[i]
    return kept


def _signed_bytes(signed: dict[str, Any]) -> bytes:
    return _SIGNED_PREFIX + _canonical(signed)


def _load_manifest(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"no seal at {p}: seal the recording with `atr seal` first")
    try:
        manifest = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RecordingError(f"the seal {p} is not a readable manifest: {exc}") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise RecordingError(f"the seal {p} is not a {FORMAT!r} manifest")
    return manifest


def _manifest_leaves(manifest: dict[str, Any]) -> list[Leaf]:
    try:
        return [
            Leaf(str(t), int(a), int(b), int(c), str(d)) for t, a, b, c, d in manifest["leaves"]
        ]
    except (KeyError, TypeError, ValueError) as exc:
        raise RecordingError(f"the seal's record list is malformed: {exc}") from exc
