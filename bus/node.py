"""The service runtime every process uses: a Zenoh session, typed input events, publishing, errors, status.

A service is a loop over `node.events()`:

    with Node("sfm", uav, inputs=[keys.image(uav), keys.relative_pose(uav)]) as node:
        for message in node.events():
            with node.handling(message):
                ...  # compute, then node.publish(key, data)

- Zenoh's callback thread only enqueues raw bytes; decoding, validation and computation run in the service thread,
  one input at a time, in arrival order; the `urgent` inputs (the sfm's guidance) go ahead of the inputs
  queued before them, so a service that has fallen behind uses the newest of them for its next input.
- A message that is not msgpack, breaks its schema, or makes the computation raise becomes an ErrorReport on
  `atr/{uav}/{service}/errors` (and the log), is counted, and the loop goes on with the next input.
- Every key is published through a zenoh-ext AdvancedPublisher and every input received through an
  AdvancedSubscriber (bus/reliable.py): inputs hidden by a link outage or a router restart arrive late,
  in order, from the publisher's cache; those the cache no longer held are reported on the errors key
  with their exact count and publisher (`lost` in the Status counts them, `gaps` the reports).
- A gap in the sequence numbers of a publisher Zenoh does not number (an input that never arrived) is
  counted (`gaps`) and reported on the errors key; an input rejected on arrival is no gap.
- With a `state_dir`, the input in hand is journalled until the service asks for the next one. A process
  restarted after a kill finds the journal: with `replay_lost` it handles that input again first (the pose
  integrator: small batches, state checkpointed), otherwise it reports it as lost (an ErrorReport with the
  input's stamp: the frame is answered and lock-step moves on). `save_state`/`load_state` keep a service's
  own checkpoint there (written atomically); a clean stop removes both.
- `republish(key, stamp_ns)` puts a service's last message on a key again, the same bytes and attachment:
  its answer to an input a lock-step driver sent again after a restart (bus/answers.py).
- SIGTERM / SIGINT end `events()`; the context manager closes the session.
"""

from __future__ import annotations

import collections
import logging
import os
import queue
import socket
import struct
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from atr.errors import AtrError, BusError, SchemaError
from bus import codec, keys, reliable
from bus.reliable import LinkBudget, Loss
from bus.session import open_session
from bus.stopping import StopRequest, stop_on_signals

log = logging.getLogger("atr")


@dataclass
class Message:
    """One decoded input."""

    key: str
    type_name: str
    data: dict[str, Any]
    source: str | None = None

    @property
    def seq(self) -> int:
        """The message's own sequence number."""
        return int(self.data["seq"])

    @property
    def stamp_ns(self) -> int:
        """The message's sensor time, ns."""
        return int(self.data["stamp_ns"])


@dataclass
class _Raw:
    key: str
    payload: bytes
    attachment: bytes | None
    sequenced: bool = False  # numbered by Zenoh: its gaps are reported as a Loss, not by seq


_JOURNAL_HEAD = struct.Struct("<I")  # the in-flight journal: header length, header, payload
_WAKE = object()  # put in the queue when an urgent input arrives: the service loop looks at them


@dataclass
class Counters:
    """What a service has done so far; published in every Status."""

    received: int = 0
    handled: int = 0
    published: int = 0
    errors: int = 0
    gaps: int = 0
    dropped: int = 0
    lost: int = 0
    handled_by_key: dict[str, int] = field(default_factory=dict)


def default_state_dir() -> Path:
    """Where services keep checkpoints unless told: ATR_STATE_DIR (the launcher sets it to a folder it
    makes per layout and removes at its stop), else, for a service started by hand, a folder of the
    system's temp directory named after its parent process.
    """
    configured = os.environ.get("ATR_STATE_DIR")
    if configured:
        return Path(configured)
    return Path(tempfile.gettempdir()) / f"atr-state-{os.getppid()}"


def setup_logging(service: str) -> None:
    """Log to stderr with the service name; level from ATR_LOG_LEVEL (default INFO)."""
    logging.basicConfig(
        level=os.environ.get("ATR_LOG_LEVEL", "INFO"),
        format=f"%(asctime)s {service} %(levelname)s %(message)s",
    )


class Node:
    """A service's connection to the bus. See the module docstring for the loop it supports."""

    def __init__(
        self,
        service: str,
        uav: str = "uav1",
        inputs: list[str] | tuple[str, ...] = (),
        *,
        zenoh_config: dict[str, Any] | str | None = None,
        heartbeat_s: float = 1.0,
        max_queue: int = 10_000,
        session: zenoh.Session | None = None,
        state_dir: str | Path | None = None,
        replay_lost: bool = False,
        budget: LinkBudget | None = None,
        urgent: list[str] | tuple[str, ...] = (),
    ) -> None:
        self.service = service
        self.uav = uav
        self.source_id = f"{service}@{socket.gethostname()}:{os.getpid()}"
        self.counters = Counters()
        # SimpleQueue, not Queue: a signal handler puts into it (see bus/stopping.py).
        self._queue: queue.SimpleQueue[_Raw | Loss | object | None] = queue.SimpleQueue()
        self._max_queue = max_queue
        # the urgent inputs wait here, handed out before the queue; a _WAKE in the queue wakes the loop
        self._urgent_keys = frozenset(urgent)
        self._urgent: collections.deque[_Raw] = collections.deque()
        self._stop = StopRequest()
        self._publish_lock = threading.Lock()
        self._budget = budget or LinkBudget.from_env()
        self._heartbeat_s = heartbeat_s
        self._publishers: dict[str, Any] = {}  # key -> its AdvancedPublisher, declared on first use
        self._seq_by_key: dict[str, int] = {}
        self._last_seq: dict[tuple[str, str], int] = {}
        self._dropped_reported = 0
        self._started = time.monotonic()
        self._owns_session = session is None
        self._last_put: dict[
            str, tuple[int, bytes, bytes]
        ] = {}  # key -> (stamp, payload, attachment)
        self._state_dir = Path(state_dir) if state_dir is not None else None
        self._lost: _Raw | None = None
        if self._state_dir is not None:
            self._state_dir.mkdir(parents=True, exist_ok=True)
            lost = self._read_journal()
            if lost is not None and replay_lost:
                log.warning("handling again the input a killed process had in hand (%s)", lost.key)
                self._queue.put(lost)  # before any live input
            else:
                self._lost = lost
        self.session = session if session is not None else open_session(zenoh_config)
        self._subscribers: list[Any] = [
            reliable.Subscriber(self.session, key, self._on_sample, self._on_loss) for key in inputs
        ]
        self._queryables: list[Any] = []
        self._alive: Any = None  # a liveliness token, from ready() on
        self._state = "starting"
        self._heartbeat = threading.Thread(target=self._beat, name="heartbeat", daemon=True)
        self._heartbeat.start()

    # Lifecycle -------------------------------------------------------------------------------

    def __enter__(self) -> Node:
        stop_on_signals(self.stop)
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if exc_type is None and self._state_dir is not None:
            # a clean stop: the next start is a new flight, not a recovery
            for path in self._state_dir.glob(f"{self.service}-{self.uav}.*"):
                path.unlink(missing_ok=True)
        self.close()

    def stop(self) -> None:
        """Ask `events()` to end after the input in hand. Takes no lock: signal handlers call it."""
        self._stop.set()
        self._queue.put(None)

    def ready(self) -> None:
        """Declare the service ready (status `running`): launchers wait for this before sending inputs.

        An input a killed process of this service had in hand (and does not handle again) is reported
        now, with its stamp: its frame is answered.
        """
        self._state = "running"
        if self._alive is None:
            # gone within milliseconds of this process's death, whatever kills it (bus/answers.py)
            self._alive = self.session.liveliness().declare_token(
                f"atr/{self.uav}/{self.service}/alive"
            )
        self._publish_status("running")
        if self._lost is not None:
            lost, self._lost = self._lost, None
            seq, stamp, source = codec.decode_attachment(lost.attachment) or (None, None, None)
            self.report_error(
                lost.key,
                BusError(f"lost: the {self.service} process was killed while handling it"),
                input_seq=seq,
                input_stamp_ns=stamp,
                input_source=source,
            )

    @property
    def stopping(self) -> bool:
        """True once a stop was asked for."""
        return self._stop.is_set()

    def close(self) -> None:
        """Publish a last status, linger for subscribers still fetching, and close the session."""
        self._stop.set()
        try:
            self._publish_status("stopping")
        except Exception:  # the session may already be gone at interpreter exit
            log.debug("last status not sent", exc_info=True)
        else:
            # a subscriber that finds a sample missing when the last status arrives fetches it from
            # this process's caches: keep them for a round trip (LinkBudget.linger_s)
            time.sleep(self._budget.linger_s)
        with self._publish_lock:
            publishers, self._publishers = list(self._publishers.values()), {}
        for entity in self._subscribers + self._queryables + publishers:
            entity.undeclare()
        self._subscribers, self._queryables = [], []
        if self._alive is not None:
            self._alive.undeclare()
            self._alive = None
        if self._owns_session:
            self.session.close()

    # Inputs ----------------------------------------------------------------------------------

    def _on_sample(self, sample: zenoh.Sample) -> None:
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        raw = _Raw(
            str(sample.key_expr),
            sample.payload.to_bytes(),
            attachment,
            reliable.is_sequenced(sample),
        )
        if raw.key in self._urgent_keys:
            self._urgent.append(raw)
            self._queue.put(_WAKE)
            return
        if self._queue.qsize() >= self._max_queue:
            self.counters.dropped += 1
            return
        self._queue.put(raw)

    def _on_loss(self, loss: Loss) -> None:
        self._queue.put(loss)  # reported by the service thread, in arrival order

    def pending(self) -> int:
        """Inputs received and not yet handed out by ``events()`` (a wake-up of an urgent one counts)."""
        return self._queue.qsize()

    def events(self, timeout_s: float | None = None) -> Iterator[Message]:
        """Decoded inputs in arrival order, the urgent ones first, until stopped (or `timeout_s`
        without input, if given).

        Inputs that fail to decode or validate are reported on the errors key and skipped.
        """
        while not self._stop.is_set():
            if self._urgent:
                raw = self._urgent.popleft()
            else:
                try:
                    raw = self._queue.get(timeout=timeout_s if timeout_s is not None else 0.2)
                except queue.Empty:
                    self._report_drops()
                    if timeout_s is not None:
                        return
                    continue
            if raw is _WAKE:  # an urgent input, already handed out or next
                continue
            if raw is None:
                return
            self._report_drops()
            if isinstance(raw, Loss):
                self._report_loss(raw)
                continue
            self.counters.received += 1
            message = self._decode(raw)
            if message is not None:
                self._journal(raw)
                yield message
                self._journal(None)  # the service asked for the next input: this one is done

    def _decode(self, raw: _Raw) -> Message | None:
        attachment = codec.decode_attachment(raw.attachment)
        source = attachment[2] if attachment else None
        try:
            type_name = keys.message_type(raw.key)
            data = codec.decode(type_name, raw.payload)
        except (SchemaError, BusError) as exc:
            seq, stamp = (attachment[0], attachment[1]) if attachment else (None, None)
            if source is not None and isinstance(seq, int):
                # it arrived: the next one is no gap
                self._check_gap(raw.key, source, seq, report=not raw.sequenced)
            self._count_handled(raw.key)
            self.report_error(
                raw.key, exc, input_seq=seq, input_stamp_ns=stamp, input_source=source
            )
            return None
        if source is not None:
            self._check_gap(raw.key, source, int(data["seq"]), report=not raw.sequenced)
        return Message(raw.key, type_name, data, source)

    def _check_gap(self, key: str, source: str, seq: int, report: bool = True) -> None:
        last = self._last_seq.get((key, source))
        self._last_seq[(key, source)] = seq
        if last is None or seq == last + 1:
            return
        if seq <= last:  # sent again (a lock-step driver re-sends a frame after a restart)
            log.info("sequence %d on %s from %s again after %d", seq, key, source, last)
            return
        if not report:  # Zenoh numbers this publisher: its losses come as a Loss, counted exactly
            return
        self.counters.gaps += 1
        # no stamp: the missing inputs' frames are unknown, so this answers no frame
        self.report_error(
            key,
            BusError(f"sequence gap: inputs {last + 1}..{seq - 1} from {source} never arrived"),
            input_seq=seq,
            input_source=source,
        )

    # State -----------------------------------------------------------------------------------

    def _path(self, suffix: str) -> Path:
        assert self._state_dir is not None
        return self._state_dir / f"{self.service}-{self.uav}.{suffix}"

    def _write(self, path: Path, *parts: bytes) -> None:
        # atomic: a kill leaves either the old file or the new one, never half of one
        tmp = path.with_name(path.name + ".tmp")
        with tmp.open("wb") as f:
            for part in parts:
                f.write(part)
        os.replace(tmp, path)

    def _journal(self, raw: _Raw | None) -> None:
        if self._state_dir is None:
            return
        path = self._path("inflight")
        if raw is None:
            path.unlink(missing_ok=True)
            return
        # the payload is written as it came, after a small header: packing a camera image into one
        # msgpack buffer copied it once more per frame (a tenth of the SfM service's time)
        head = codec.pack({"key": raw.key, "attachment": raw.attachment})
        self._write(path, _JOURNAL_HEAD.pack(len(head)), head, raw.payload)

    def _read_journal(self) -> _Raw | None:
        path = self._path("inflight")
        if not path.is_file():
            return None
        try:
            data = path.read_bytes()
            (head_bytes,) = _JOURNAL_HEAD.unpack_from(data)
            start = _JOURNAL_HEAD.size + head_bytes
            entry = codec.unpack(data[_JOURNAL_HEAD.size : start])
            raw = _Raw(str(entry["key"]), data[start:], entry["attachment"])
        except Exception as exc:  # noqa: BLE001 - a damaged journal is reported, not fatal
            log.warning("journal %s unreadable (%s); ignored", path, exc)
            raw = None
        path.unlink(missing_ok=True)
        return raw

    def save_state(self, state: dict[str, Any]) -> None:
        """Checkpoint the service's state (msgpack; numpy arrays allowed), atomically. No-op without a
        state_dir.
        """
        if self._state_dir is not None:
            self._write(self._path("state"), codec.pack(state))

    def load_state(self) -> dict[str, Any] | None:
        """The last checkpoint of a killed process of this service, or None.

        Raises:
            BusError: the checkpoint cannot be read.

        """
        if self._state_dir is None or not self._path("state").is_file():
            return None
        try:
            return codec.unpack(self._path("state").read_bytes())
        except Exception as exc:
            raise BusError(f"checkpoint {self._path('state')} unreadable: {exc}") from exc

    def _report_loss(self, loss: Loss) -> None:
        self.counters.gaps += 1
        self.counters.lost += loss.count
        self.report_error(loss.key, BusError(loss.reason()), input_source=loss.source)

    def _report_drops(self) -> None:
        dropped = self.counters.dropped
        if dropped > self._dropped_reported:
            lost = dropped - self._dropped_reported
            self._dropped_reported = dropped
            self.report_error(
                "*", BusError(f"input queue full: {lost} input(s) dropped"), input_seq=None
            )

    def _count_handled(self, key: str) -> None:
        self.counters.handled += 1
        self.counters.handled_by_key[key] = self.counters.handled_by_key.get(key, 0) + 1

    @contextmanager
    def handling(self, message: Message) -> Iterator[None]:
        """Isolate the computation for one input: any exception becomes an ErrorReport, not a crash."""
        try:
            yield
        except AtrError as exc:
            self.report_error(message.key, exc, message.seq, message.stamp_ns, message.source)
        except (
            Exception
        ) as exc:  # a bug must not kill the service; it is reported with its traceback
            log.error(
                "unexpected error on %s seq %s:\n%s",
                message.key,
                message.seq,
                traceback.format_exc(),
            )
            self.report_error(message.key, exc, message.seq, message.stamp_ns, message.source)
        finally:
            self._count_handled(message.key)

    # Outputs ---------------------------------------------------------------------------------

    def publish(
        self, key: str, data: dict[str, Any], type_name: str | None = None
    ) -> dict[str, Any]:
        """Validate, encode and put `data` on `key`; fills `seq` (per key) and `version` when absent.

        Returns:
            The message as sent.

        Raises:
            SchemaError: the message breaks its schema (a bug in the service, not in the input).

        """
        type_name = type_name or keys.message_type(key)
        with self._publish_lock:
            seq = self._seq_by_key.get(key, 0)
            message = {"stamp_ns": data.get("stamp_ns", 0), "seq": seq, "version": 1} | data
            payload = codec.encode(type_name, message)
            self._seq_by_key[key] = seq + 1
            attachment = codec.encode_attachment(
                message["seq"], message["stamp_ns"], self.source_id
            )
            self._publisher(key, len(payload)).put(payload, attachment=attachment)
            self.counters.published += 1
            if keys.is_data_key(key):
                self._last_put[key] = (int(message["stamp_ns"]), payload, attachment)
        return message

    def republish(self, key: str, stamp_ns: int) -> bool:
        """Put the last message published on `key` again, the same bytes and attachment (seq and
        stamp), if it is the one of stamp `stamp_ns`: a service's answer to an input sent again
        after a restart downstream (bus/answers.py). Receivers see a repeated seq.

        Returns:
            Whether a message was put.

        """
        with self._publish_lock:
            last = self._last_put.get(key)
            if last is None or last[0] != int(stamp_ns):
                return False
            self._publisher(key, len(last[1])).put(last[1], attachment=last[2])
            self.counters.published += 1
        return True

    def _publisher(self, key: str, sample_bytes: int) -> Any:
        """The key's AdvancedPublisher; the first message's size sizes its cache. Called under
        the publish lock.
        """
        publisher = self._publishers.get(key)
        if publisher is None:
            data = keys.is_data_key(key)
            # Status publishes at the heartbeat, everything else at most once per frame.
            status = key.endswith("/status")
            rate_hz = 1.0 / self._heartbeat_s if status else self._budget.rate_hz
            publisher = reliable.declare_publisher(
                self.session,
                key,
                # Data: BLOCK, a slow link delays the publisher instead of silently dropping data
                # (§5). Status and timing: DROP, a heartbeat must never hold a service (or its
                # shutdown) up; a dropped one is fetched again from the cache.
                congestion=zenoh.CongestionControl.BLOCK if data else zenoh.CongestionControl.DROP,
                cache_samples=self._budget.cache_samples(rate_hz, sample_bytes),
                budget=self._budget,
            )
            self._publishers[key] = publisher
        return publisher

    def report_error(
        self,
        key: str,
        exc: BaseException,
        input_seq: int | None = None,
        input_stamp_ns: int | None = None,
        input_source: str | None = None,
    ) -> None:
        """Count, log and publish an ErrorReport about a rejected input."""
        self.counters.errors += 1
        reason = str(exc) or type(exc).__name__
        log.warning(
            "rejected input on %s (seq %s): %s: %s", key, input_seq, type(exc).__name__, reason
        )
        self.publish(
            keys.service_key(self.uav, self.service, "errors"),
            {
                "stamp_ns": input_stamp_ns or 0,
                "service": self.service,
                "key": key,
                "error_type": type(exc).__name__,
                "reason": reason,
                "input_seq": input_seq,
                "input_stamp_ns": input_stamp_ns,
                "input_source": input_source,
                "count": self.counters.errors,
            },
        )

    def timing(self, input_seq: int, stamp_ns: int, stages_ms: dict[str, float]) -> None:
        """Publish the per-stage wall times of one computation. An entry named "total" is the whole
        computation's wall time, not a stage (the matcher's results carry one): it is the message's
        total_ms; without it, total_ms is the sum of the stages.
        """
        stages = {k: float(v) for k, v in stages_ms.items() if k != "total"}
        self.publish(
            keys.service_key(self.uav, self.service, "timing"),
            {
                "stamp_ns": stamp_ns,
                "service": self.service,
                "input_seq": input_seq,
                "stages_ms": stages,
                "total_ms": float(stages_ms.get("total", sum(stages.values()))),
            },
        )

    # Queries ---------------------------------------------------------------------------------

    def serve(self, key_expr: str, answer: Callable[[str], dict[str, Any] | None]) -> None:
        """Answer queries on `key_expr`: `answer(key)` returns a message (typed by the key) or None."""

        def on_query(query: zenoh.Query) -> None:
            key = str(query.key_expr)
            try:
                message = answer(key)
                if message is None:
                    query.reply_err(f"nothing at {key}")
                    return
                full = {"stamp_ns": 0, "seq": 0, "version": 1} | message
                query.reply(key, codec.encode(keys.message_type(key), full))
            except Exception as exc:  # the query fails, the service does not
                log.warning("query %s failed: %s", key, exc)
                query.reply_err(f"{type(exc).__name__}: {exc}")

        self._queryables.append(self.session.declare_queryable(key_expr, on_query))

    def get(self, key: str, timeout_s: float = 10.0) -> dict[str, Any]:
        """Query `key` and return the first valid answer.

        Raises:
            BusError: no answer within `timeout_s`, or an error reply.
            SchemaError: the answer breaks its schema.

        """
        errors = []
        for reply in self.session.get(key, timeout=timeout_s):
            if reply.ok is not None:
                return codec.decode(keys.message_type(key), reply.ok.payload.to_bytes())
            errors.append(reply.err.payload.to_string())
        detail = "; ".join(errors) if errors else f"no answer within {timeout_s} s"
        raise BusError(f"query {key}: {detail}")

    # Status ----------------------------------------------------------------------------------

    def extra_status(self) -> dict[str, Any]:
        """Fields a subclass adds to (or replaces in) its Status: e.g. more counters. None by default."""
        return {}

    def _publish_status(self, state: str) -> None:
        c = self.counters
        status = {
            "stamp_ns": time.time_ns(),
            "service": self.service,
            "uav": self.uav,
            "host": socket.gethostname(),
            "pid": os.getpid(),
            "state": state,
            "uptime_s": time.monotonic() - self._started,
            "counters": {
                "received": c.received,
                "handled": c.handled,
                "published": c.published,
                "errors": c.errors,
                "gaps": c.gaps,
                "dropped": c.dropped,
                "lost": c.lost,
            },
            "handled_by_key": dict(c.handled_by_key),
        }
        extra = self.extra_status()
        status["counters"] |= extra.pop("counters", {})
        self.publish(keys.service_key(self.uav, self.service, "status"), status | extra)

    def _beat(self) -> None:
        while True:
            try:
                self._publish_status(self._state)
            except Exception:  # a heartbeat failure must not end the service
                log.debug("status not sent", exc_info=True)
            if self._stop.wait(self._heartbeat_s if self._state == "running" else 0.2):
                return
