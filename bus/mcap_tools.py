"""MCAP files of this project: a chunked writer, and the tools behind `atr mcap` (info, check,
recover).

The writer (`ChunkedWriter`) produces standard MCAP (readable by the `mcap` library and Foxglove):
Header, then zstd-compressed Chunks each followed by its MessageIndex records, DataEnd, a summary
section (schemas, channels, Statistics, ChunkIndexes, SummaryOffsets) and the Footer. Schemas and
channels are written inside the chunk that holds their first message, so a file cut short by a crash
still defines everything it contains up to its last complete chunk. It is our own (not
`mcap.writer.Writer`, which always uses zstd level 3 in the calling thread): the zstd level is
chosen (1 costs about half of level 3's CPU, bench/codec.py), chunks are compressed and written on
a thread of their own, and message records are framed without an intermediate BytesIO (one copy
less of a 3.7 MB image). Records are serialised with `mcap.records` where speed does not matter.

`check(path)` walks the file record by record with `mcap.stream_reader.StreamReader` and names every
problem it finds; `recover(src, dst)` copies every message up to the first broken record into a
clean file; `info(path)` summarises a file (from its summary section, or by a scan when a crash left
none).
"""

from __future__ import annotations

import functools
import heapq
import io
import os
import queue
import struct
import threading
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import zstandard
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.exceptions import InvalidMagic, McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import StreamReader, get_chunk_data_stream

from atr.errors import RecordingError
from bus._closing import ClosesOnExit

MAGIC = bytes([137, 77, 67, 65, 80, 48, 13, 10])
PROFILE = ""
LIBRARY = "passive-atr recorder"
# opcode, record length, channel, sequence, log_time, publish_time
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")
# opcode, record length, start, end, uncompressed size, crc, len("zstd"), "zstd", records length
_CHUNK_HEAD = struct.Struct("<BQQQQII4sQ")
_U32 = 0xFFFFFFFF
_U64 = 0xFFFFFFFFFFFFFFFF
MAX_ID = 0xFFFF  # schema and channel ids are 16-bit in MCAP


def _clamp(value: int, upper: int) -> int:
    return min(max(int(value), 0), upper)


class ChunkedWriter(ClosesOnExit):
    """Writes an MCAP file in zstd chunks; schemas and channels ride in the chunk of their first
    message.

    Args:
        out: path or binary stream to write to (a path is opened and closed by the writer).
        chunk_size_bytes: a chunk is closed once its uncompressed records exceed this size.
        zstd_level: zstd compression level of chunks (1 = fastest).
        zstd_threads: zstd worker threads (0 = compress in the calling thread).
        background: compress and write chunks on a thread of the writer's own, so that filling the
            next chunk overlaps with compressing the last (zstd and crc32 release the GIL).
        metadata: MCAP Metadata records (name -> string map) written right after the Header.

    Raises:
        RecordingError: the output cannot be opened, or a file already exists at `out` (it is
            created exclusively: a writer never truncates or overwrites a file).

    """

    def __init__(
        self,
        out: str | Path | IO[bytes],
        *,
        chunk_size_bytes: int = 8 * 1024 * 1024,
        zstd_level: int = 1,
        zstd_threads: int = 0,
        background: bool = False,
        metadata: dict[str, dict[str, str]] | None = None,
    ) -> None:
        if chunk_size_bytes <= 0:
            raise RecordingError(f"chunk size {chunk_size_bytes} bytes must be > 0")
        self._owns = not hasattr(out, "write")
        try:
            # 'xb': exclusive creation, so no code path can truncate an existing recording.
            self._f: IO[bytes] = open(out, "xb") if self._owns else out  # type: ignore[arg-type]
        except FileExistsError as exc:
            raise RecordingError(
                f"{out} already exists; a recording is never overwritten (choose another path)"
            ) from exc
        except OSError as exc:
            raise RecordingError(f"cannot open {out} for writing: {exc}") from exc
        self._chunk_size = chunk_size_bytes
        self._zstd = zstandard.ZstdCompressor(level=zstd_level, threads=zstd_threads)
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._chunk_indexes: list[ChunkIndex] = []
        self.statistics = Statistics(
            attachment_count=0,
            channel_count=0,
            channel_message_counts={},
            chunk_count=0,
            message_count=0,
            message_end_time=0,
            message_start_time=0,
            metadata_count=0,
            schema_count=0,
        )
        self._buf = bytearray()
        self._index: dict[int, list[tuple[int, int]]] = {}
        self._chunk_start = 0
        self._chunk_end = 0
        self._chunk_messages = 0
        self._pos = 0
        self._data_crc = 0  # CRC-32 of every byte before DataEnd (MCAP's data section CRC)
        self._closed = False
        self._failure: BaseException | None = None
        self._write_records(lambda b: b.write(MAGIC), Header(PROFILE, LIBRARY).write)
        self._metadata_indexes: list[MetadataIndex] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        for name, values in (metadata or {}).items():
            self._write_metadata(name, values)
        self._jobs: queue.Queue[Any] | None = queue.Queue(maxsize=2) if background else None
        self._thread = None
        if self._jobs is not None:
            self._thread = threading.Thread(
                target=self._compress_loop, name="mcap-chunks", daemon=True
            )
            self._thread.start()

    # Public interface --------------------------------------------------------------------------

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Define a schema; returns its id (1, 2, ...).

        Raises:
            RecordingError: the file already holds 65,535 schemas (MCAP ids are 16-bit).

        """
        if len(self._schemas) >= MAX_ID:
            raise RecordingError(f"schema {name!r}: the file already holds {MAX_ID} schemas")
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas[schema.id] = schema
        self.statistics.schema_count += 1
        self._buf += _record_bytes(schema)
        return schema.id

    def add_channel(
        self,
        topic: str,
        message_encoding: str,
        schema_id: int,
        metadata: dict[str, str] | None = None,
    ) -> int:
        """Define a channel (schema_id 0 = no schema); returns its id (1, 2, ...).

        Raises:
            RecordingError: the schema is not defined, or the file already holds 65,535 channels
                (MCAP ids are 16-bit); nothing is written then.

        """
        if len(self._channels) >= MAX_ID:
            raise RecordingError(
                f"channel {topic!r}: the file already holds {MAX_ID} channels, "
                "the most MCAP's 16-bit channel ids allow"
            )
        if schema_id != 0 and schema_id not in self._schemas:
            raise RecordingError(f"channel {topic!r} refers to undefined schema id {schema_id}")
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=dict(metadata or {}),
        )
        self._channels[channel.id] = channel
        self.statistics.channel_count += 1
        self._buf += _record_bytes(channel)
        return channel.id

    def add_message(
        self, channel_id: int, log_time: int, publish_time: int, sequence: int, data: bytes
    ) -> None:
        """Append a message to the current chunk (times in ns; sequence kept modulo 2**32).

        Raises:
            RecordingError: the channel is not defined (nothing is written then), or an earlier
                background write failed.

        """
        if channel_id not in self._channels:
            raise RecordingError(f"message on channel id {channel_id}, which is not defined")
        if not isinstance(data, bytes | bytearray | memoryview):
            raise RecordingError(f"message data is {type(data).__name__}, expected bytes")
        log_time = _clamp(log_time, _U64)
        # framed before any state changes, so a bad argument leaves the chunk as it was
        head = _MESSAGE_HEAD.pack(
            Opcode.MESSAGE,
            22 + len(data),
            channel_id,
            int(sequence) & _U32,
            log_time,
            _clamp(publish_time, _U64),
        )
        stats = self.statistics
        if self._chunk_messages == 0:
            self._chunk_start = self._chunk_end = log_time
        else:
            self._chunk_start = min(self._chunk_start, log_time)
            self._chunk_end = max(self._chunk_end, log_time)
        if stats.message_count == 0:
            stats.message_start_time = stats.message_end_time = log_time
        else:
            stats.message_start_time = min(stats.message_start_time, log_time)
            stats.message_end_time = max(stats.message_end_time, log_time)
        stats.message_count += 1
        stats.channel_message_counts[channel_id] = (
            stats.channel_message_counts.get(channel_id, 0) + 1
        )
        self._index.setdefault(channel_id, []).append((log_time, len(self._buf)))
        self._buf += head
        self._buf += data
        self._chunk_messages += 1
        if len(self._buf) > self._chunk_size:
            self.flush()

    @property
    def failure(self) -> BaseException | None:
        """The error that stopped the background writes (None while the file is writable)."""
        return self._failure

    @property
    def pending_messages(self) -> int:
        """Messages in the chunk not yet written to the file."""
        return self._chunk_messages

    def flush(self) -> None:
        """Close the chunk in progress (if it holds a message): compress it and write it to the
        stream.

        With `background=True` the compression and write happen on the writer's own thread (at most
        two chunks wait for it); `close()` waits for them.

        Raises:
            RecordingError: an earlier background write failed.

        """
        self._raise_failure()
        if self._chunk_messages == 0:
            return
        job = (self._buf, self._index, self._chunk_start, self._chunk_end)
        self._buf = bytearray()
        self._index = {}
        self._chunk_messages = 0
        self.statistics.chunk_count += 1
        self._run(functools.partial(self._write_chunk, *job))

    def add_metadata(self, name: str, values: dict[str, str]) -> None:
        """Write a Metadata record (a name and a string map) after the chunk in progress."""
        self.flush()
        self._run(functools.partial(self._write_metadata, name, dict(values)))

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time: int) -> None:
        """Write an Attachment record (e.g. the effective configuration) after the chunk in
        progress; `log_time` in ns.
        """
        self.flush()
        self._run(functools.partial(self._write_attachment, name, media_type, data, log_time))

    def _run(self, job: Any) -> None:
        # Records reach the file in the order they were added: in background mode every write is
        # a job on the one writer thread.
        if self._jobs is None:
            job()
        else:
            self._jobs.put(job)

    def _compress_loop(self) -> None:
        assert self._jobs is not None
        while True:
            job = self._jobs.get()
            if job is None:
                return
            if self._failure is None:
                try:
                    job()
                except (OSError, zstandard.ZstdError) as exc:
                    self._failure = exc

    def _raise_failure(self) -> None:
        if self._failure is not None:
            failure = self._failure
            raise RecordingError(f"writing the recording failed: {failure}") from failure

    def _write_chunk(
        self, raw: bytearray, index: dict[int, list[tuple[int, int]]], start: int, end: int
    ) -> None:
        compressed = self._zstd.compress(raw)
        chunk_offset = self._pos
        # Chunk record framed by hand: the compressed payload is written straight, not copied again.
        head = _CHUNK_HEAD.pack(
            Opcode.CHUNK,
            8 + 8 + 8 + 4 + 4 + 4 + 8 + len(compressed),
            start,
            end,
            len(raw),
            zlib.crc32(raw),
            4,
            b"zstd",
            len(compressed),
        )
        self._emit(head, compressed)
        builder = RecordBuilder()
        offsets = {}
        for channel_id, records in index.items():
            offsets[channel_id] = self._pos + builder.count
            MessageIndex(channel_id=channel_id, records=records).write(builder)
        index_bytes = builder.end()
        self._emit(index_bytes)
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_offset,
                chunk_length=len(head) + len(compressed),
                message_index_offsets=offsets,
                message_index_length=len(index_bytes),
                compression="zstd",
                compressed_size=len(compressed),
                uncompressed_size=len(raw),
            )
        )
        self._f.flush()

    def close(self, metadata: dict[str, dict[str, str]] | None = None) -> None:
        """Write the last chunk, then `metadata` (name -> string map; e.g. a clean-close marker),
        DataEnd with the data section's CRC, the summary section, the footer and the closing magic.
        """
        if self._closed:
            return
        self._closed = True
        self.flush()
        if self._jobs is not None:
            self._jobs.put(None)
            assert self._thread is not None
            self._thread.join()
        self._raise_failure()
        # Definitions not yet followed by a message stay in the summary only.
        self._buf = bytearray()
        for name, values in (metadata or {}).items():
            self._write_metadata(name, values)
        self._write_records(DataEnd(self._data_crc).write)
        summary_start = self._pos
        builder = RecordBuilder()
        groups: list[SummaryOffset] = []

        def group(opcode: Opcode, records: list[Any]) -> None:
            start = builder.count
            for record in records:
                record.write(builder)
            if records:
                groups.append(SummaryOffset(opcode, summary_start + start, builder.count - start))

        group(Opcode.SCHEMA, list(self._schemas.values()))
        group(Opcode.CHANNEL, list(self._channels.values()))
        group(Opcode.STATISTICS, [self.statistics])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.ATTACHMENT_INDEX, self._attachment_indexes)
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offsets_start = summary_start + builder.count
        for offset in groups:
            offset.write(builder)
        summary = builder.end()
        footer_head = struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offsets_start)
        crc = zlib.crc32(footer_head, zlib.crc32(summary))
        self._f.write(summary)
        self._f.write(footer_head + struct.pack("<I", crc))
        self._f.write(MAGIC)
        self._f.flush()
        if self._owns:
            self._f.close()

    # Internals ---------------------------------------------------------------------------------

    def _write_records(self, *writers: Any) -> None:
        builder = RecordBuilder()
        for write in writers:
            write(builder)
        self._emit(builder.end())

    def _emit(self, *parts: bytes | bytearray) -> None:
        for part in parts:
            self._f.write(part)
            self._pos += len(part)
            self._data_crc = zlib.crc32(part, self._data_crc)

    def _write_attachment(self, name: str, media_type: str, data: bytes, log_time: int) -> None:
        record = _record_bytes(Attachment(log_time, log_time, name, media_type, data))
        self._attachment_indexes.append(
            AttachmentIndex(self._pos, len(record), log_time, log_time, len(data), name, media_type)
        )
        self._emit(record)
        self.statistics.attachment_count += 1

    def _write_metadata(self, name: str, values: dict[str, str]) -> None:
        record = _record_bytes(Metadata(name=name, metadata=dict(values)))
        self._metadata_indexes.append(MetadataIndex(self._pos, len(record), name))
        self._emit(record)
        self.statistics.metadata_count += 1


def _record_bytes(record: Any) -> bytes:
    builder = RecordBuilder()
    record.write(builder)
    return builder.end()


# Reading ---------------------------------------------------------------------------------------


class _TruncatedError(McapError):
    def __init__(self, offset: int, wanted: int, got: int) -> None:
        super().__init__(
            f"file ends at offset {offset + got}: a record needs {wanted - got} more bytes"
        )
        self.offset = offset


class _StrictStream:
    """A read-only view of a file that raises on a short read (the mcap reader does not) and knows
    its offset.
    """

    def __init__(self, f: IO[bytes]) -> None:
        self._f = f
        self.offset = 0

    def read(self, n: int = -1) -> bytes:
        data = self._f.read(n)
        if n is not None and n >= 0 and len(data) < n:
            raise _TruncatedError(self.offset, n, len(data))
        self.offset += len(data)
        return data


class _UnreadableRecordError(Exception):
    """A record the mcap reader cannot read: where it starts, and why (`cause`)."""

    def __init__(self, offset: int, cause: Exception) -> None:
        super().__init__(f"record at offset {offset}: {cause}")
        self.offset = offset
        self.cause = cause


def _records(f: IO[bytes], size: int, offset: int = 0) -> Iterator[tuple[int, Any, int]]:
    """(start offset, record, end offset) of each record of `f` from `offset` on (0: the file's start,
    its magic checked; else the start of a record); chunks are not opened.

    Raises:
        _UnreadableRecordError: a record cannot be read (a short read's cause is a `_TruncatedError`).

    """
    f.seek(offset)
    strict = _StrictStream(f)
    strict.offset = offset
    records = StreamReader(
        strict,
        skip_magic=offset > 0,
        emit_chunks=True,
        record_size_limit=size,  # type: ignore[arg-type]
    ).records
    start = offset or len(MAGIC)
    while True:
        try:
            record = next(records)
        except StopIteration:
            return
        except (McapError, struct.error, UnicodeDecodeError, ValueError) as exc:
            raise _UnreadableRecordError(start, exc) from exc
        yield start, record, strict.offset
        start = strict.offset


@dataclass
class _Walk:
    """What one pass over a file found."""

    problems: list[str] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    message_counts: dict[int, int] = field(default_factory=dict)
    chunks: dict[int, Chunk] = field(default_factory=dict)  # offset -> chunk (data dropped)
    chunk_indexes: list[ChunkIndex] = field(default_factory=list)
    summary_schemas: dict[int, Schema] = field(default_factory=dict)
    summary_channels: dict[int, Channel] = field(default_factory=dict)
    statistics: Statistics | None = None
    footer: Footer | None = None
    summary_offsets: list[SummaryOffset] = field(default_factory=list)
    start_time: int | None = None
    end_time: int | None = None
    messages: int = 0
    data_end: bool = False
    complete_up_to: int = 0  # offset after the last record read whole


@dataclass
class _Summary:
    """The definitions and chunk offsets a file's summary section states."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunk_offsets: list[int] = field(default_factory=list)


def _read_summary(path: str | Path) -> _Summary | None:
    """The summary section of `path`, or None when it has none that can be read."""
    try:
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
    except Exception:  # the mcap reader raises many types on a damaged file
        return None
    if summary is None:
        return None
    return _Summary(
        schemas=dict(summary.schemas),
        channels=dict(summary.channels),
        chunk_offsets=sorted(ci.chunk_start_offset for ci in summary.chunk_indexes),
    )


def _chunk_records(chunk: Chunk, where: str, problems: list[str]) -> list[Any] | None:
    try:
        stream, length = get_chunk_data_stream(chunk, validate_crc=False)
    except (zstandard.ZstdError, McapError, RuntimeError, ValueError) as exc:
        problems.append(f"{where}: compressed data is corrupted ({chunk.compression}: {exc})")
        return None
    data = stream.read(length) if length else b""
    if len(data) != chunk.uncompressed_size:
        problems.append(
            f"{where}: uncompressed size {len(data)} bytes differs from the recorded "
            f"{chunk.uncompressed_size}"
        )
    if chunk.uncompressed_crc != 0 and zlib.crc32(data) != chunk.uncompressed_crc:
        problems.append(
            f"{where}: CRC mismatch, data corrupted (computed 0x{zlib.crc32(data):08x}, "
            f"recorded 0x{chunk.uncompressed_crc:08x})"
        )
        return None
    inner = ReadDataStream(io.BytesIO(data))
    records: list[Any] = []
    try:
        while inner.count < len(data):
            start = inner.count
            opcode, rec_len = inner.read1(), inner.read8()
            body = ReadDataStream(io.BytesIO(inner.read(rec_len)))
            if opcode == Opcode.MESSAGE:
                records.append((start, Message.read(body, rec_len)))
            elif opcode == Opcode.SCHEMA:
                records.append((start, Schema.read(body)))
            elif opcode == Opcode.CHANNEL:
                records.append((start, Channel.read(body)))
    except (McapError, struct.error, UnicodeDecodeError) as exc:
        problems.append(f"{where}: record inside the chunk cannot be read ({exc})")
        return None
    return records


def _walk(
    path: str | Path,
    *,
    on_message: Any = None,
    stop_at_first_problem: bool = False,
    summary: _Summary | None = None,
) -> _Walk:
    """One pass over the records of `path`; `on_message(schema, channel, message)` is called in file
    order.

    With `summary` (what the file's own summary section says), a message whose channel was defined
    in a chunk that cannot be read still finds its channel there, and after a record that cannot be
    read the walk goes on at the next chunk the summary's chunk indexes locate.
    """
    w = _Walk()
    size = os.path.getsize(path)
    fallback = summary or _Summary()
    with open(path, "rb") as f:
        records = _records(f, size)
        in_summary = False
        last_chunk_offset: int | None = None
        chunk_message_offsets: dict[int, list[tuple[int, int]]] = {}
        n_chunk = 0
        while True:
            try:
                start, record, end = next(records)
            except StopIteration:
                break
            except _UnreadableRecordError as unreadable:
                exc, at_offset = unreadable.cause, unreadable.offset
                resume = next((o for o in fallback.chunk_offsets if o > at_offset), None)
                if resume is None or stop_at_first_problem or in_summary:
                    _read_problem(w, exc, at_offset)
                    break
                w.problems.append(
                    f"unreadable record at offset {at_offset} ({exc}); going on at the chunk at "
                    f"offset {resume} (from the summary's chunk index)"
                )
                records = _records(f, size, resume)
                continue
            at = f"{type(record).__name__} at offset {start}"
            if isinstance(record, (Schema, Channel, Message, Chunk)) and in_summary:
                if isinstance(record, Schema):
                    w.summary_schemas[record.id] = record
                elif isinstance(record, Channel):
                    w.summary_channels[record.id] = record
                else:
                    w.problems.append(f"{at}: data record inside the summary section")
            elif isinstance(record, Schema):
                w.schemas[record.id] = record
            elif isinstance(record, Channel):
                _define_channel(w, record, at)
            elif isinstance(record, Message):
                _take_message(w, record, at, on_message, fallback)
            elif isinstance(record, Chunk):
                n_chunk += 1
                where = f"chunk #{n_chunk} at offset {start}"
                before = len(w.problems)
                inner = _chunk_records(record, where, w.problems)
                if inner is None:
                    if stop_at_first_problem:
                        break
                    continue
                last_log = None
                times = []
                chunk_message_offsets = {}
                for inner_offset, item in inner:
                    if isinstance(item, Schema):
                        w.schemas[item.id] = item
                    elif isinstance(item, Channel):
                        _define_channel(w, item, f"{where}: channel {item.id}")
                    else:
                        _take_message(w, item, f"{where}: message", on_message, fallback)
                        chunk_message_offsets.setdefault(item.channel_id, []).append(
                            (item.log_time, inner_offset)
                        )
                        times.append(item.log_time)
                        if last_log is not None and item.log_time < last_log:
                            w.problems.append(
                                f"{where}: log time goes back ({item.log_time} after {last_log})"
                            )
                        last_log = item.log_time
                if times and (min(times), max(times)) != (
                    record.message_start_time,
                    record.message_end_time,
                ):
                    w.problems.append(
                        f"{where}: message time range [{record.message_start_time}, "
                        f"{record.message_end_time}] differs from its messages "
                        f"[{min(times)}, {max(times)}]"
                    )
                if stop_at_first_problem and len(w.problems) > before:
                    break
                w.chunks[start] = Chunk(
                    compression=record.compression,
                    data=b"",
                    message_start_time=record.message_start_time,
                    message_end_time=record.message_end_time,
                    uncompressed_crc=record.uncompressed_crc,
                    uncompressed_size=record.uncompressed_size,
                )
                last_chunk_offset = start
            elif isinstance(record, MessageIndex):
                _check_message_index(w, record, at, last_chunk_offset, chunk_message_offsets)
            elif isinstance(record, DataEnd):
                w.data_end = True
                in_summary = True
                if record.data_section_crc:
                    _check_data_crc(w, f, start, record.data_section_crc)
                    f.seek(end)
            elif isinstance(record, ChunkIndex):
                w.chunk_indexes.append(record)
            elif isinstance(record, Statistics):
                w.statistics = record
            elif isinstance(record, SummaryOffset):
                w.summary_offsets.append(record)
            elif isinstance(record, Footer):
                w.footer = record
            if stop_at_first_problem and w.problems:
                break
            w.complete_up_to = end
    return w


def _read_problem(w: _Walk, exc: BaseException, start: int) -> None:
    if isinstance(exc, _TruncatedError):
        w.problems.append(f"truncated: record at offset {start}: {exc}")
    elif isinstance(exc, InvalidMagic):
        where = "the start" if w.complete_up_to == 0 else "the end"
        w.problems.append(f"bad magic at {where} of the file: {exc}")
    elif isinstance(exc, McapError):
        w.problems.append(f"unreadable record at offset {start}: {exc}")
    else:
        w.problems.append(f"malformed record at offset {start}: {exc}")


def _define_channel(w: _Walk, channel: Channel, at: str) -> None:
    if channel.schema_id != 0 and channel.schema_id not in w.schemas:
        w.problems.append(
            f"{at}: channel {channel.topic!r} refers to schema id {channel.schema_id}, "
            "not defined before it"
        )
    w.channels[channel.id] = channel


def _take_message(
    w: _Walk, message: Message, at: str, on_message: Any, fallback: _Summary | None = None
) -> None:
    channel = w.channels.get(message.channel_id)
    if channel is None and fallback is not None:
        channel = fallback.channels.get(message.channel_id)
        if channel is not None:  # defined in a chunk that cannot be read: the summary's copy
            w.channels[channel.id] = channel
            if channel.schema_id in fallback.schemas:
                w.schemas.setdefault(channel.schema_id, fallback.schemas[channel.schema_id])
    if channel is None:
        w.problems.append(
            f"{at}: message on channel id {message.channel_id}, not defined before it"
        )
        return
    w.messages += 1
    w.message_counts[message.channel_id] = w.message_counts.get(message.channel_id, 0) + 1
    w.start_time = message.log_time if w.start_time is None else min(w.start_time, message.log_time)
    w.end_time = message.log_time if w.end_time is None else max(w.end_time, message.log_time)
    if on_message is not None:
        schema = w.schemas.get(channel.schema_id)
        if schema is None and fallback is not None:
            schema = fallback.schemas.get(channel.schema_id)
        on_message(schema, channel, message)


def _check_message_index(
    w: _Walk,
    index: MessageIndex,
    at: str,
    chunk_offset: int | None,
    offsets: dict[int, list[tuple[int, int]]],
) -> None:
    if chunk_offset is None:
        w.problems.append(f"{at}: message index before any chunk")
        return
    expected = offsets.get(index.channel_id, [])
    if index.records != expected:
        w.problems.append(
            f"{at}: index of channel {index.channel_id} lists {len(index.records)} message(s) "
            f"that do not match the {len(expected)} in the chunk at offset {chunk_offset}"
        )
    times = [t for t, _ in index.records]
    if times != sorted(times):
        w.problems.append(f"{at}: log times of channel {index.channel_id} are not in order")


def _check_data_crc(w: _Walk, f: IO[bytes], data_end: int, recorded: int) -> None:
    """The data section's CRC (every byte before DataEnd) against the one DataEnd records."""
    f.seek(0)
    crc, left = 0, data_end
    while left > 0:
        block = f.read(min(left, 1 << 24))
        if not block:
            break
        crc = zlib.crc32(block, crc)
        left -= len(block)
    if crc != recorded:
        w.problems.append(
            f"data section CRC mismatch (computed 0x{crc:08x}, recorded 0x{recorded:08x}): "
            "the data section was changed after it was written"
        )


def _check_summary(w: _Walk, path: str | Path) -> None:
    if not w.data_end:
        w.problems.append("no DataEnd record: the file was not closed (use `atr mcap recover`)")
    if w.footer is None:
        w.problems.append("no Footer: the file was not closed (use `atr mcap recover`)")
        return
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        if w.footer.summary_start:
            f.seek(w.footer.summary_start)
            summary = f.read(size - 8 - 29 - w.footer.summary_start)
            head = struct.pack(
                "<BQQQ", Opcode.FOOTER, 20, w.footer.summary_start, w.footer.summary_offset_start
            )
            crc = zlib.crc32(head, zlib.crc32(summary))
            if w.footer.summary_crc not in (0, crc):
                w.problems.append(
                    f"summary CRC mismatch (computed 0x{crc:08x}, "
                    f"recorded 0x{w.footer.summary_crc:08x})"
                )
        for offset in w.summary_offsets:
            if offset.group_length == 0:  # may point anywhere (the reference writer does so)
                continue
            f.seek(offset.group_start)
            opcode = f.read(1)
            if not opcode or opcode[0] != offset.group_opcode:
                w.problems.append(
                    f"summary offset for opcode 0x{offset.group_opcode:02x} points at offset "
                    f"{offset.group_start}, which holds another record"
                )
    for sid, schema in w.summary_schemas.items():
        if w.schemas.get(sid) != schema:
            w.problems.append(
                f"summary schema {sid} ({schema.name}) differs from the data section's"
            )
    for cid, channel in w.summary_channels.items():
        if w.channels.get(cid) != channel:
            w.problems.append(
                f"summary channel {cid} ({channel.topic}) differs from the data section's"
            )
    if w.chunk_indexes:
        indexed = {ci.chunk_start_offset: ci for ci in w.chunk_indexes}
        for offset in sorted(set(w.chunks) - set(indexed)):
            w.problems.append(f"chunk at offset {offset} has no chunk index in the summary")
        for offset, ci in sorted(indexed.items()):
            chunk = w.chunks.get(offset)
            if chunk is None:
                w.problems.append(
                    f"chunk index points at offset {offset}, where no readable chunk starts"
                )
            elif (ci.message_start_time, ci.message_end_time, ci.uncompressed_size) != (
                chunk.message_start_time,
                chunk.message_end_time,
                chunk.uncompressed_size,
            ):
                w.problems.append(
                    f"chunk index for offset {offset} disagrees with the chunk (times or size)"
                )
    s = w.statistics
    if s is None:
        return
    expected = {
        "message_count": w.messages,
        "schema_count": len(w.schemas),
        "channel_count": len(w.channels),
        "chunk_count": len(w.chunks),
    }
    for name, value in expected.items():
        if getattr(s, name) != value:
            w.problems.append(f"statistics {name} = {getattr(s, name)}, the data holds {value}")
    if w.messages and (s.message_start_time, s.message_end_time) != (w.start_time, w.end_time):
        w.problems.append(
            f"statistics time span [{s.message_start_time}, {s.message_end_time}] differs from "
            f"the messages' [{w.start_time}, {w.end_time}]"
        )
    if dict(s.channel_message_counts) != w.message_counts:
        for cid in sorted(set(s.channel_message_counts) | set(w.message_counts)):
            stated, found = s.channel_message_counts.get(cid, 0), w.message_counts.get(cid, 0)
            if stated != found:
                topic = w.channels[cid].topic if cid in w.channels else f"id {cid}"
                w.problems.append(
                    f"statistics count {stated} for channel {topic}, the data holds {found}"
                )


# Segments --------------------------------------------------------------------------------------

SEGMENT_METADATA = "atr.segment"


def segment_path(path: str | Path, index: int) -> Path:
    """File of segment `index` of the recording `path`: `path` itself for 0, else the index before
    the suffix (`flight.mcap` -> `flight.1.mcap`, `flight.2.mcap`, ...).
    """
    path = Path(path)
    return path if index == 0 else path.with_name(f"{path.stem}.{index}{path.suffix}")


def segments(path: str | Path) -> list[Path]:
    """The files of the recording whose first segment is `path`: `path`, then `flight.1.mcap`,
    `flight.2.mcap`, ... for as long as they exist (a restarted recorder writes the next one).

    Raises:
        RecordingError: `path` does not exist.

    """
    _require(path)
    found = [Path(path)]
    while segment_path(path, len(found)).is_file():
        found.append(segment_path(path, len(found)))
    return found


def is_closed(path: str | Path) -> bool:
    """True when `path` ends with MCAP's closing magic (its writer closed it)."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            if f.tell() < 2 * len(MAGIC):
                return False
            f.seek(-len(MAGIC), os.SEEK_END)
            return f.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def create_segment(path: str | Path, **writer_args: Any) -> tuple[ChunkedWriter, Path, int]:
    """A writer on the next free segment of the recording `path`: `path` itself when it does not
    exist, else the segment after the last one. A continuing segment carries a Metadata record
    `atr.segment` saying which file it continues and whether that one was closed or cut.

    Args:
        path: the recording (its first segment).
        **writer_args: passed to `ChunkedWriter`.

    Returns:
        The writer, the file it writes and its segment index (0 for the first).

    Raises:
        RecordingError: the file cannot be created.

    """
    path = Path(path)
    for _ in range(1000):  # another writer may take a name between our look and our create
        index = len(segments(path)) if path.is_file() else 0
        out = segment_path(path, index)
        metadata = None
        if index > 0:
            previous = segment_path(path, index - 1)
            metadata = {
                SEGMENT_METADATA: {
                    "recording": path.name,
                    "segment": str(index),
                    "continues": previous.name,
                    "previous_closed": str(is_closed(previous)).lower(),
                }
            }
        try:
            return ChunkedWriter(out, metadata=metadata, **writer_args), out, index
        except RecordingError:
            if not out.exists():
                raise
    raise RecordingError(f"no free segment name for {path}")


# Tools -----------------------------------------------------------------------------------------


def check(path: str | Path) -> list[str]:
    """Validate a recording; returns the problems found (empty when it is sound).

    Every segment (`segments(path)`) is checked; with several, each problem starts with its file's
    name. Checked: magic at both ends; every channel's schema and every message's channel defined
    before use; chunk decompression, uncompressed sizes and CRCs, chunk time ranges; message
    indexes against their chunk; log times non-decreasing within chunks and indexes; DataEnd and
    Footer present; summary CRC; summary schemas and channels equal to the data section's; chunk
    indexes and statistics consistent with the data.

    Raises:
        RecordingError: the file cannot be opened.

    """
    files = segments(path)
    problems = []
    for file in files:
        found = _check_file(file)
        problems += [f"{file.name}: {p}" for p in found] if len(files) > 1 else found
    return problems


def _check_file(path: Path) -> list[str]:
    w = _walk(path)
    if not w.problems or w.footer is not None:
        _check_summary(w, path)
    elif w.footer is None and not any(p.startswith("truncated") for p in w.problems):
        w.problems.append("no Footer: the file was not closed (use `atr mcap recover`)")
    return w.problems


@dataclass(frozen=True)
class RecoverResult:
    """What `recover` kept: messages and channels copied, the bytes of the source that could be
    read, the segments read, and the problems met (the first also as `problem`).
    """

    messages: int
    channels: int
    readable_bytes: int
    source_bytes: int
    problem: str | None
    problems: list[str] = field(default_factory=list)
    segments: int = 1


def recover(src: str | Path, dst: str | Path) -> RecoverResult:
    """Copy every message of every readable chunk of the recording `src` (all its segments) into
    one clean, indexed file `dst`.

    A chunk that cannot be read is skipped and named; the chunks after it are still copied. When
    the chunk defining a channel is the broken one, the definitions come from the summary section;
    after a record whose framing is broken, reading goes on at the next chunk the summary's chunk
    indexes locate (a file cut short by a crash has no summary: it is read up to its last complete
    chunk). Message bytes, times and sequence numbers are kept; schema and channel ids may be
    renumbered, and channels of the same topic in several segments become one.

    Raises:
        RecordingError: `src` cannot be opened or is not MCAP at all, or `dst` is one of its
            segments or exists already.

    """
    files = segments(src)
    if any(f.resolve() == Path(dst).resolve() for f in files):
        raise RecordingError(f"recover would overwrite its input {dst}; choose another output path")
    schema_ids: dict[tuple[str, str, bytes], int] = {}
    channel_ids: dict[tuple[Any, ...], int] = {}
    problems: list[str] = []
    readable = 0
    with ChunkedWriter(dst) as writer:
        for file in files:
            ids: dict[int, int] = {}

            def copy(
                schema: Schema | None, channel: Channel, message: Message, ids: dict = ids
            ) -> None:
                if channel.id not in ids:
                    sid = 0
                    if schema is not None:
                        skey = (schema.name, schema.encoding, schema.data)
                        if skey not in schema_ids:
                            schema_ids[skey] = writer.add_schema(*skey)
                        sid = schema_ids[skey]
                    ckey = (
                        channel.topic,
                        channel.message_encoding,
                        sid,
                        tuple(sorted(channel.metadata.items())),
                    )
                    if ckey not in channel_ids:
                        channel_ids[ckey] = writer.add_channel(
                            channel.topic, channel.message_encoding, sid, channel.metadata
                        )
                    ids[channel.id] = channel_ids[ckey]
                writer.add_message(
                    ids[channel.id],
                    message.log_time,
                    message.publish_time,
                    message.sequence,
                    message.data,
                )

            w = _walk(file, on_message=copy, summary=_read_summary(file))
            if file == files[0] and w.complete_up_to == 0 and w.problems:
                Path(dst).unlink(missing_ok=True)
                raise RecordingError(f"{src} is not an MCAP file: {w.problems[0]}")
            if w.footer is None and not w.problems:
                w.problems.append("not closed (no Footer)")
            named = len(files) > 1
            problems += [f"{file.name}: {p}" if named else p for p in w.problems]
            readable += w.complete_up_to
        n = writer.statistics.message_count
    return RecoverResult(
        messages=n,
        channels=len(channel_ids),
        readable_bytes=readable,
        source_bytes=sum(os.path.getsize(f) for f in files),
        problem=problems[0] if problems else None,
        problems=problems,
        segments=len(files),
    )


@dataclass(frozen=True)
class ChannelInfo:
    """One channel (topic) of a recording; `id` is its id in the first segment holding it."""

    id: int
    topic: str
    schema_name: str
    message_encoding: str
    messages: int


@dataclass(frozen=True)
class RecordingInfo:
    """Summary of a recording (all its segments): channels, message count, time span (log time,
    ns), size, and the problems met reading it (a segment not closed, a chunk that cannot be read).
    """

    path: str
    size_bytes: int
    channels: list[ChannelInfo]
    messages: int
    chunks: int
    start_ns: int | None
    end_ns: int | None
    closed: bool
    segments: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        """End minus start of the messages' log times, seconds."""
        if self.start_ns is None or self.end_ns is None:
            return 0.0
        return (self.end_ns - self.start_ns) / 1e9


def info(path: str | Path) -> RecordingInfo:
    """Summarise the recording `path` (all its segments) by reading every record; files that were
    not closed and chunks that cannot be read are counted up to what is readable, and named in
    `problems`.

    Raises:
        RecordingError: the file cannot be opened or is not MCAP.

    """
    files = segments(path)
    by_topic: dict[tuple[str, str, str], ChannelInfo] = {}
    problems: list[str] = []
    messages = chunks = size = 0
    start: int | None = None
    end: int | None = None
    for file in files:
        w = _walk(file, summary=_read_summary(file))
        if w.complete_up_to == 0 and w.problems:
            raise RecordingError(f"{file} is not a readable MCAP file: {w.problems[0]}")
        found = list(w.problems)
        if w.footer is None and not any(p.startswith("truncated") for p in found):
            found.append("not closed (no Footer)")
        problems += [f"{file.name}: {p}" for p in found]
        for c in w.channels.values():
            schema = w.schemas[c.schema_id].name if c.schema_id in w.schemas else ""
            key = (c.topic, schema, c.message_encoding)
            known = by_topic.get(key)
            count = w.message_counts.get(c.id, 0) + (known.messages if known else 0)
            by_topic[key] = ChannelInfo(
                id=known.id if known else c.id,
                topic=c.topic,
                schema_name=schema,
                message_encoding=c.message_encoding,
                messages=count,
            )
        messages += w.messages
        chunks += len(w.chunks)
        size += os.path.getsize(file)
        if w.start_time is not None:
            start = w.start_time if start is None else min(start, w.start_time)
            end = w.end_time if end is None else max(end, w.end_time)  # type: ignore[type-var]
    return RecordingInfo(
        path=str(path),
        size_bytes=size,
        channels=sorted(by_topic.values(), key=lambda c: (c.topic, c.id)),
        messages=messages,
        chunks=chunks,
        start_ns=start,
        end_ns=end,
        closed=all(is_closed(f) for f in files),
        segments=[str(f) for f in files],
        problems=problems,
    )


def topics(path: str | Path) -> list[str]:
    """The channel topics of the recording `path` (all its segments), sorted; from the summary of
    a closed segment, by reading the records of one that was cut short.

    Raises:
        RecordingError: a file cannot be opened or is not MCAP.

    """
    found: set[str] = set()
    for file in segments(path):
        summary = _read_summary(file)
        if summary is None:
            w = _walk(file)
            if w.complete_up_to == 0 and w.problems:
                raise RecordingError(f"{file} is not a readable MCAP file: {w.problems[0]}")
            found |= {c.topic for c in w.channels.values()}
        else:
            found |= {c.topic for c in summary.channels.values()}
    return sorted(found)


def iter_messages(
    path: str | Path, topics: list[str] | tuple[str, ...] | None = None
) -> Iterator[tuple[str, Message]]:
    """(topic, Message) pairs of the recording `path` (all its segments, one after the other) in
    log-time order, read chunk by chunk (what replay reads). A segment cut short by a crash is read
    up to its last complete chunk.

    Args:
        path: the recording (its first segment).
        topics: only messages on these topics (None: all).

    Raises:
        RecordingError: a file cannot be opened, or a record or chunk of it cannot be read (the
            error names the file, the chunk's offset and what is wrong; `atr mcap recover` copies
            the chunks that can).

    """
    wanted = None if topics is None else set(topics)
    for file in segments(path):
        yield from _stream(file, wanted)


def _stream(path: Path, wanted: set[str] | None) -> Iterator[tuple[str, Message]]:
    """Messages of one file in log-time order: a chunk's messages are sorted, and those of the
    chunks read so far wait in a heap until the next chunk starts later.
    """
    size = os.path.getsize(path)
    heap: list[tuple[int, int, str, Message]] = []
    channels: dict[int, Channel] = {}
    n = 0  # arrival number: equal log times keep file order

    def take(message: Message) -> None:
        nonlocal n
        channel = channels.get(message.channel_id)
        if channel is None:
            raise RecordingError(
                f"{path}: message on channel id {message.channel_id}, which is not defined"
            )
        if wanted is None or channel.topic in wanted:
            heapq.heappush(heap, (message.log_time, n, channel.topic, message))
            n += 1

    with open(path, "rb") as f:
        n_chunk = 0
        try:
            for start, record, _ in _records(f, size):
                if isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    take(record)
                elif isinstance(record, Chunk):
                    n_chunk += 1
                    while heap and heap[0][0] <= record.message_start_time:
                        _, _, topic, message = heapq.heappop(heap)
                        yield topic, message
                    problems: list[str] = []
                    where = f"chunk #{n_chunk} at offset {start}"
                    inner = _chunk_records(record, where, problems)
                    if inner is None:
                        raise RecordingError(
                            f"{path}: {problems[0]}; `atr mcap recover` copies the chunks that can "
                            "be read"
                        )
                    for _, item in inner:
                        if isinstance(item, Channel):
                            channels[item.id] = item
                        elif isinstance(item, Message):
                            take(item)
                elif isinstance(record, DataEnd):
                    break
        except _UnreadableRecordError as unreadable:
            # a segment cut short by a crash is read up to its last complete chunk
            if not isinstance(unreadable.cause, _TruncatedError):
                raise RecordingError(
                    f"{path}: record at offset {unreadable.offset} cannot be read: "
                    f"{unreadable.cause}"
                ) from unreadable.cause
    while heap:
        _, _, topic, message = heapq.heappop(heap)
        yield topic, message


def _require(path: str | Path) -> None:
    if not Path(path).is_file():
        raise RecordingError(f"recording {path} does not exist")
