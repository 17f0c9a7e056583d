"""The recorder: every message on `atr/**` and `sim/**`, as received, into one MCAP file
(docs/recording.md).

- topic = key expression; message encoding `msgpack`; schema encoding `jsonschema` with the
  registry's schema (`bus.schemas.schema_bytes`); keys outside the contract get a channel without
  schema (schema id 0);
- log_time = receive time (ns, taken on Zenoh's callback thread under a lock, so it never goes
  back); publish_time = the message's stamp_ns; sequence = its seq. Both come from the attachment,
  else from the payload itself (`codec.unpack`), else 0;
- bytes are written as received: nothing is re-encoded, nothing rejected (a bad message is
  evidence);
- one Zenoh subscriber (on `**`, filtered, when several key expressions are asked for), so messages
  are written in the order the link delivered them: Zenoh runs callbacks of different subscribers
  concurrently;
- it is a zenoh-ext AdvancedSubscriber (bus/reliable.py): what a link outage or a router restart hid
  is fetched from the publishers' caches and recorded late (log_time = when it arrived), in each
  publisher's order; what the caches no longer held is reported with its exact count and publisher
  (`lost` counts the messages, `gaps` the reports);
- Zenoh's callback only timestamps and enqueues (unbounded queue: no loss); a writer thread does the
  rest;
- a chunk is closed when it exceeds `chunk_size_bytes`, `flush_interval_s` after its first message,
  or as soon as the bus has been quiet for `idle_flush_s` (between lock-step frames, between bursts):
  what is written survives a `kill -9` of the recorder (the OS holds it), so a kill loses only what
  arrived since the bus was last quiet, at most `flush_interval_s` under a steady load; SIGINT/SIGTERM close the file with its
  summary and indexes;
- an existing file is never truncated or overwritten: a recorder started again with the same `out`
  (e.g. restarted after a crash) writes the next segment (`flight.1.mcap`, ...), which names the
  segment it continues and whether that one was cut (`bus.mcap_tools.create_segment`); the
  restart is also reported on the recorder's errors key;
- keys are bounded: MCAP channel ids are 16-bit, so at most `max_keys` channels, of which at most
  `max_foreign_keys` for keys outside the contract; messages on further keys are refused, counted
  (`refused`) and reported at most once per second. A message that cannot be written is reported
  and counted (`write_errors`); only a failure of the file itself stops the recording.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from atr.errors import AtrError, BusError, ConfigError, RecordingError
from bus import codec, keys, reliable, schemas
from bus._closing import ClosesOnExit
from bus.mcap_tools import MAX_ID, create_segment, is_closed, segment_path
from bus.node import Node
from bus.provenance import (
    CONFIG_ATTACHMENT,
    END_METADATA_NAME,
    METADATA_NAME,
    RunContext,
    gather,
)
from bus.reliable import Loss
from bus.seal import load_private_key, seal

log = logging.getLogger("atr.recorder")

DEFAULT_KEY_EXPRS = ("atr/**", "sim/**")


@dataclass(frozen=True)
class RecorderConfig:
    """Settings of the recorder.

    Attributes:
        key_exprs: key expressions subscribed to.
        chunk_size_bytes: a chunk is written once its uncompressed records exceed this many bytes.
        idle_flush_s: a chunk is written once no message has arrived for this long (the bus is quiet),
            seconds.
        flush_interval_s: a chunk is written at the latest this long after its first message (bounds
            the loss on a crash), seconds.
        zstd_level: zstd level of chunks (1: fastest positive level; see docs/performance/bus.md).
        zstd_threads: zstd worker threads (0 = compress in the writer thread).
        max_keys: most distinct keys (MCAP channels) recorded; MCAP's ids allow 65,535.
        max_foreign_keys: most distinct keys outside the contract's key expressions recorded (so
            that a peer publishing many such keys cannot take the room of the contract's).

    """

    key_exprs: tuple[str, ...] = DEFAULT_KEY_EXPRS
    chunk_size_bytes: int = 8 * 1024 * 1024
    flush_interval_s: float = 1.0
    idle_flush_s: float = 0.05
    zstd_level: int = 1
    zstd_threads: int = 0
    max_keys: int = MAX_ID
    max_foreign_keys: int = 1024

    def __post_init__(self) -> None:
        if not self.key_exprs:
            raise ConfigError("recorder key expressions must not be empty")
        if self.chunk_size_bytes <= 0:
            raise ConfigError(f"chunk size {self.chunk_size_bytes} bytes must be > 0")
        if not self.flush_interval_s > 0:
            raise ConfigError(f"flush interval {self.flush_interval_s} s must be > 0")
        if not self.idle_flush_s > 0:
            raise ConfigError(f"idle flush {self.idle_flush_s} s must be > 0")
        if not -7 <= self.zstd_level <= 22:
            raise ConfigError(f"zstd level {self.zstd_level} must be in [-7, 22]")
        if not 1 <= self.max_keys <= MAX_ID:
            raise ConfigError(f"max keys {self.max_keys} must be in [1, {MAX_ID}]")
        if not 0 <= self.max_foreign_keys <= self.max_keys:
            raise ConfigError(
                f"max foreign keys {self.max_foreign_keys} must be in [0, {self.max_keys}]"
            )


@dataclass
class RecorderStats:
    """What the recorder has written so far."""

    messages: int = 0
    bytes: int = 0
    channels: int = 0
    without_schema: int = 0
    unstamped: int = 0
    gaps: int = 0
    lost: int = 0
    queue_max: int = 0
    refused: int = 0
    write_errors: int = 0
    segment: int = 0
    by_topic: dict[str, int] = field(default_factory=dict)


_STOP = object()
PROVENANCE_WAIT_S = 15.0  # close() waits this long at most for the provenance record


@dataclass(frozen=True)
class _Provenance:
    """A queue item: the provenance record and the configuration, ready to write."""

    record: dict[str, str]
    config_json: bytes


class Recorder(ClosesOnExit):
    """Subscribes to the bus and writes what arrives into an MCAP file.

    Args:
        session: an open Zenoh session (not closed by the recorder).
        out: path of the recording (parent folders are created); when it exists, the next segment
            is written (`flight.1.mcap`, ...; `self.path` is the file written).
        config: chunking and subscription settings.
        on_problem: called from the writer thread with (key, exception) for problems worth reporting
            on the bus (sequence gaps, refused keys, a message that could not be written, a failure
            of the file, after which recording stops and `failure` is set).

    Raises:
        RecordingError: the file cannot be created.

    """

    def __init__(
        self,
        session: zenoh.Session,
        out: str | Path,
        config: RecorderConfig | None = None,
        on_problem: Any = None,
        context: RunContext | None = None,
    ) -> None:
        self.config = config or RecorderConfig()
        self.recording = Path(out)
        try:
            self.recording.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RecordingError(f"cannot create the folder of {out}: {exc}") from exc
        self.stats = RecorderStats()
        self.failure: BaseException | None = None
        self._writer, self.path, self.segment = create_segment(
            self.recording,
            chunk_size_bytes=self.config.chunk_size_bytes,
            zstd_level=self.config.zstd_level,
            zstd_threads=self.config.zstd_threads,
            background=True,
        )
        self.stats.segment = self.segment
        self.continues: Path | None = None
        self.previous_closed = True
        if self.segment > 0:
            self.continues = segment_path(self.recording, self.segment - 1)
            self.previous_closed = is_closed(self.continues)
        self._foreign_keys = 0
        self._last_report_ns: dict[str, int] = {}
        self._on_problem = on_problem
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._clock = threading.Lock()
        self._schema_ids: dict[str, int] = {}
        self._channel_ids: dict[str, int] = {}
        self._last_seq: dict[tuple[str, str], int] = {}
        self._thread = threading.Thread(target=self._write_loop, name="mcap-writer", daemon=True)
        self._thread.start()
        # One subscriber only: Zenoh runs different subscribers' callbacks concurrently, so two of
        # them (atr/**, sim/**) would interleave the link's order; with several key expressions we
        # take `**` and keep the samples that match one of them.
        exprs = self.config.key_exprs
        self._filters = [zenoh.KeyExpr(k) for k in exprs] if len(exprs) > 1 else []
        sub_key = exprs[0] if len(exprs) == 1 else "**"
        self._subscribers = [reliable.Subscriber(session, sub_key, self._on_sample, self._on_loss)]
        self._closed = False
        # Provenance is gathered after the subscription exists (loading the configuration takes a
        # second or two): the recording starts at once, the record follows within a few seconds
        # (`wait_for_provenance`).
        self._provenance_thread: threading.Thread | None = None
        if context is not None:
            self._provenance_thread = threading.Thread(
                target=self._gather_provenance, args=(context,), name="provenance", daemon=True
            )
            self._provenance_thread.start()

    def wait_for_provenance(self, timeout_s: float = PROVENANCE_WAIT_S) -> None:
        """Return once the provenance record is queued (or after `timeout_s`). The recorder service
        declares itself ready only then: gathering it (loading the configuration, hashing the source
        and the input recording) takes two CPU seconds, which a flight started at once would share
        with its first scenes. Messages that come meanwhile are recorded all the same.
        """
        if self._provenance_thread is not None:
            self._provenance_thread.join(timeout=timeout_s)

    def _gather_provenance(self, context: RunContext) -> None:
        record, config_bytes = gather(context, self.recording, self.segment)
        with self._clock:
            self._queue.put(_Provenance(record, config_bytes))

    # Zenoh callback thread -----------------------------------------------------------------------

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if self._filters and not any(f.intersects(sample.key_expr) for f in self._filters):
            return
        payload = sample.payload.to_bytes()
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        key = str(sample.key_expr)
        sequenced = reliable.is_sequenced(sample)
        with self._clock:  # receive time and queue order agree, so log times never go back
            self._queue.put((time.time_ns(), key, payload, attachment, sequenced))

    def _on_loss(self, loss: Loss) -> None:
        with self._clock:
            self._queue.put(loss)

    # Writer thread --------------------------------------------------------------------------------

    def _write_loop(self) -> None:
        interval_ns = int(self.config.flush_interval_s * 1e9)
        idle_s = min(self.config.idle_flush_s, self.config.flush_interval_s)
        idle_ns = int(idle_s * 1e9)
        first_pending_ns = last_item_ns = 0
        while True:
            try:
                item = self._queue.get(timeout=idle_s)
            except queue.Empty:
                item = None
            now = time.monotonic_ns()
            if item is not None:
                last_item_ns = now
            if item is _STOP:
                return
            if isinstance(item, _Provenance) and self.failure is None:
                self._write_provenance(item)
            elif isinstance(item, Loss):
                self.stats.gaps += 1
                self.stats.lost += item.count
                self._problem(item.key, BusError(item.reason()))
            elif item is not None and self.failure is None:
                try:
                    self._write(*item)
                except Exception as exc:  # noqa: BLE001 - one message must not stop the others:
                    if self._writer.failure is not None or isinstance(exc, OSError):
                        self._fail(item[1], exc)  # the file itself failed: stop, close() raises
                    else:
                        self.stats.write_errors += 1
                        self._limited(
                            "write_errors",
                            item[1],
                            RecordingError(
                                f"message on {item[1]} not recorded ({type(exc).__name__}: "
                                f"{exc}); {self.stats.write_errors} such so far"
                            ),
                        )
                if self._writer.pending_messages == 1:
                    first_pending_ns = now
                depth = self._queue.qsize()
                self.stats.queue_max = max(self.stats.queue_max, depth)
            quiet = now - last_item_ns >= idle_ns and self._queue.empty()
            due = quiet or now - first_pending_ns >= interval_ns
            if self._writer.pending_messages and due and self.failure is None:
                try:
                    self._writer.flush()
                except (OSError, RecordingError) as exc:
                    self._fail("*", exc)

    def _write_provenance(self, item: _Provenance) -> None:
        try:
            self._writer.add_metadata(METADATA_NAME, item.record)
            if item.config_json:
                self._writer.add_attachment(
                    CONFIG_ATTACHMENT, "application/json", item.config_json, time.time_ns()
                )
        except (OSError, RecordingError) as exc:
            self._fail("*", exc)

    def _fail(self, key: str, exc: BaseException) -> None:
        self.failure = exc
        log.error("recording to %s failed: %s", self.path, exc)
        self._problem(key, RecordingError(f"writing {self.path} failed, recording stopped: {exc}"))

    def _problem(self, key: str, exc: AtrError) -> None:
        if self._on_problem is not None:
            try:
                self._on_problem(key, exc)
            except Exception:  # reporting must never stop the recording
                log.exception("problem report failed")

    def _limited(self, kind: str, key: str, exc: AtrError) -> None:
        """Report at most one problem of this kind per second (a flood must not flood the bus)."""
        now = time.monotonic_ns()
        if now - self._last_report_ns.get(kind, -(10**10)) >= 1_000_000_000:
            self._last_report_ns[kind] = now
            log.warning("%s", exc)
            self._problem(key, exc)

    def _write(
        self,
        log_time: int,
        key: str,
        payload: bytes,
        attachment: bytes | None,
        sequenced: bool = False,
    ) -> None:
        channel_id = self._channel_ids.get(key)
        if channel_id is None:
            channel_id = self._add_channel(key)
            if channel_id is None:
                return
        seq, stamp_ns = self._seq_stamp(key, payload, attachment, sequenced)
        self._writer.add_message(channel_id, log_time, stamp_ns, seq, payload)
        s = self.stats
        s.messages += 1
        s.bytes += len(payload)
        s.by_topic[key] = s.by_topic.get(key, 0) + 1

    def _add_channel(self, key: str) -> int | None:
        try:
            type_name = keys.message_type(key)
        except BusError:
            type_name = None
        cap = self.config.max_keys
        if type_name is None and self._foreign_keys >= self.config.max_foreign_keys:
            cap, what = self.config.max_foreign_keys, "keys outside the contract"
        elif len(self._channel_ids) >= cap:
            what = "keys"
        else:
            what = ""
        if what:
            self.stats.refused += 1
            self._limited(
                "refused",
                key,
                BusError(
                    f"key {key!r} not recorded: the recording already holds {cap} {what} "
                    f"(the most it takes); {self.stats.refused} message(s) refused so far"
                ),
            )
            return None
        schema_id = 0
        if type_name is not None:
            schema_id = self._schema_ids.get(type_name, 0)
            if not schema_id:
                schema_id = self._writer.add_schema(
                    type_name, "jsonschema", schemas.schema_bytes(type_name)
                )
                self._schema_ids[type_name] = schema_id
        channel_id = self._writer.add_channel(key, "msgpack", schema_id)
        if type_name is None:
            self.stats.without_schema += 1
            self._foreign_keys += 1
        self._channel_ids[key] = channel_id
        self.stats.channels += 1
        return channel_id

    def _seq_stamp(
        self, key: str, payload: bytes, attachment: bytes | None, sequenced: bool
    ) -> tuple[int, int]:
        decoded = codec.decode_attachment(attachment)
        if decoded is not None:
            seq, stamp_ns, source = decoded
            self._check_gap(key, source, seq, report=not sequenced)
            return seq, stamp_ns
        try:
            message = codec.unpack(payload)
        except AtrError:
            message = None
        if not isinstance(message, dict):
            self.stats.unstamped += 1
            return 0, 0
        return _int_field(message, "seq"), _int_field(message, "stamp_ns")

    def _check_gap(self, key: str, source: str, seq: int, report: bool = True) -> None:
        last = self._last_seq.get((key, source))
        if last is not None and seq <= last:
            return  # a message sent again (lock-step's re-send after a restart): nothing lost
        self._last_seq[(key, source)] = seq
        # a publisher Zenoh numbers reports its losses as a Loss (exact, and sooner)
        if report and last is not None and seq != last + 1:
            self.stats.gaps += 1
            self._problem(
                key, BusError(f"sequence gap on {key} from {source}: seq {seq} after {last}")
            )

    # Lifecycle ---------------------------------------------------------------------------------

    def close(self) -> RecorderStats:
        """Stop subscribing, write everything queued, and close the file (summary, indexes, footer).

        Raises:
            RecordingError: the file could not be written (the first failure).

        """
        if self._closed:
            return self.stats
        self._closed = True
        for sub in self._subscribers:
            sub.undeclare()
        self.wait_for_provenance()  # a short recording still gets its provenance
        with self._clock:
            self._queue.put(_STOP)
        self._thread.join()
        if self.failure is None:
            try:
                self._writer.close(metadata={END_METADATA_NAME: self._end_record()})
            except (OSError, RecordingError) as exc:
                self.failure = exc
        if self.failure is not None:
            raise RecordingError(f"recording {self.path} failed: {self.failure}") from self.failure
        return self.stats

    def _end_record(self) -> dict[str, str]:
        """The clean-close marker: only a recorder that closed its file writes it."""
        s = self.stats
        return {
            "clean_close": "true",
            "stop_time_ns": str(time.time_ns()),
            "messages": str(s.messages),
            "gaps": str(s.gaps),
            "lost": str(s.lost),
            "refused": str(s.refused),
            "write_errors": str(s.write_errors),
        }


def _int_field(message: dict[Any, Any], name: str) -> int:
    value = message.get(name)
    return value if isinstance(value, int) and not isinstance(value, bool) else 0


class RecorderNode(Node):
    """A `Node` whose Status also carries the recorder's figures: counters messages, bytes,
    channels, gaps, lost (messages gone beyond the publishers' caches), queue_max, unstamped, refused
    (messages on keys beyond the cap), write_errors,
    segment (index of the file written); handled_by_key = messages recorded per topic.
    """

    recorder: Recorder | None = None

    def extra_status(self) -> dict[str, Any]:
        """The recorder's counters, and messages recorded per topic as handled_by_key; zeros
        until the recorder is attached (its subscriber may record a heartbeat sent before that).
        """
        s = self.recorder.stats if self.recorder is not None else RecorderStats()
        counters = {
            "messages": s.messages,
            "bytes": s.bytes,
            "channels": s.channels,
            "gaps": s.gaps,
            "lost": s.lost,
            "queue_max": s.queue_max,
            "unstamped": s.unstamped,
            "refused": s.refused,
            "write_errors": s.write_errors,
            "segment": s.segment,
        }
        return {"counters": counters, "handled_by_key": self._by_topic()}

    def _by_topic(self) -> dict[str, int]:
        if self.recorder is None:
            return {}
        for _ in range(3):  # the writer thread may add a topic while we copy
            try:
                return dict(self.recorder.stats.by_topic)
            except RuntimeError:
                continue
        return {}


def run_recorder(
    out: str | Path,
    *,
    uav: str = "uav1",
    zenoh_config: dict[str, Any] | str | None = None,
    config: RecorderConfig | None = None,
    service: str = "recorder",
    ready: threading.Event | None = None,
    context: RunContext | None = None,
    seal_key: str | Path | None = None,
) -> RecorderStats:
    """Record until SIGINT/SIGTERM (or `Node.stop()`), then close the file; what `atr record` and
    the recorder service run. Status and ErrorReports go on `atr/{uav}/{service}/...`; `context`
    (what the launcher knows of the run) goes into the provenance record of the file. With
    `seal_key` (an Ed25519 private key) the file is sealed when it closes (`FILE.seal`, bus/seal.py):
    the chain of custody of an air recording starts on the aircraft.

    Raises:
        RecordingError: the file could not be written.

    """
    signer = (
        load_private_key(seal_key) if seal_key is not None else None
    )  # refused before recording
    with RecorderNode(service, uav, zenoh_config=zenoh_config) as node:
        recorder: Recorder | None = None

        def report(key: str, exc: AtrError) -> None:
            node.report_error(key, exc)
            if recorder is not None and recorder.failure is not None:
                node.stop()  # the file itself failed

        recorder = Recorder(
            node.session, out, config, on_problem=report, context=context or RunContext(uav=uav)
        )
        node.recorder = recorder
        log.info("recording %s to %s", ", ".join(recorder.config.key_exprs), recorder.path)
        recorder.wait_for_provenance()
        node.ready()
        if recorder.continues is not None:
            cut = (
                "closed"
                if recorder.previous_closed
                else "cut (not closed: its last second or so is lost)"
            )
            node.report_error(
                str(recorder.recording),
                RecordingError(
                    f"{recorder.recording} exists: recording continues in segment "
                    f"{recorder.segment} ({recorder.path.name}); the previous segment "
                    f"{recorder.continues.name} was {cut}"
                ),
            )
        if ready is not None:
            ready.set()
        try:
            for _ in node.events():  # no inputs: returns when stopped
                pass
        finally:
            stats = recorder.close()
            if signer is not None:
                manifest = seal(recorder.path, signer)
                log.info("sealed %s: %d messages", recorder.path, manifest["messages"])
        log.info(
            "closed %s: %d messages, %.1f MB, %d channels, %d gaps, max queue %d",
            recorder.path,
            stats.messages,
            stats.bytes / 1e6,
            stats.channels,
            stats.gaps,
            stats.queue_max,
        )
        return stats
