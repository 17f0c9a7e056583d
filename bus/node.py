"""The service runtime every process uses: a Zenoh session, typed input events, publishing, errors, status.

A service is a loop over `node.events()`:

    with Node("sfm", uav, inputs=[keys.image(uav), keys.relative_pose(uav)]) as node:
        for message in node.events():
            with node.handling(message):
                ...  # compute, then node.publish(key, data)

- Zenoh's callback thread only enqueues raw bytes; decoding, validation and computation run in the service thread,
  one input at a time, in arrival order.
- A message that is not msgpack, breaks its schema, or makes the computation raise becomes an ErrorReport on
  `atr/{uav}/{service}/errors` (and the log), is counted, and the loop goes on with the next input.
- A gap in a publisher's sequence numbers is logged, counted and reported.
- SIGTERM / SIGINT end `events()`; the context manager closes the session.
"""

from __future__ import annotations

import logging
import os
import queue
import socket
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import zenoh

from atr.errors import AtrError, BusError, SchemaError
from bus import codec, keys
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


@dataclass
class Counters:
    """What a service has done so far; published in every Status."""

    received: int = 0
    handled: int = 0
    published: int = 0
    errors: int = 0
    gaps: int = 0
    dropped: int = 0
    handled_by_key: dict[str, int] = field(default_factory=dict)


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
    ) -> None:
        self.service = service
        self.uav = uav
        self.source_id = f"{service}@{socket.gethostname()}:{os.getpid()}"
        self.counters = Counters()
        # SimpleQueue, not Queue: a signal handler puts into it (see bus/stopping.py).
        self._queue: queue.SimpleQueue[_Raw | None] = queue.SimpleQueue()
        self._max_queue = max_queue
        self._stop = StopRequest()
        self._publish_lock = threading.Lock()
        self._seq_by_key: dict[str, int] = {}
        self._last_seq: dict[tuple[str, str], int] = {}
        self._dropped_reported = 0
        self._started = time.monotonic()
        self._owns_session = session is None
        self.session = session if session is not None else open_session(zenoh_config)
        self._subscribers = [
            self.session.declare_subscriber(key, self._on_sample) for key in inputs
        ]
        self._queryables: list[Any] = []
        self._heartbeat_s = heartbeat_s
        self._state = "starting"
        self._heartbeat = threading.Thread(target=self._beat, name="heartbeat", daemon=True)
        self._heartbeat.start()

    # Lifecycle -------------------------------------------------------------------------------

    def __enter__(self) -> Node:
        stop_on_signals(self.stop)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def stop(self) -> None:
        """Ask `events()` to end after the input in hand. Takes no lock: signal handlers call it."""
        self._stop.set()
        self._queue.put(None)

    def ready(self) -> None:
        """Declare the service ready (status `running`): launchers wait for this before sending inputs."""
        self._state = "running"
        self._publish_status("running")

    @property
    def stopping(self) -> bool:
        """True once a stop was asked for."""
        return self._stop.is_set()

    def close(self) -> None:
        """Publish a last status and close the session."""
        self._stop.set()
        try:
            self._publish_status("stopping")
        except Exception:  # the session may already be gone at interpreter exit
            log.debug("last status not sent", exc_info=True)
        for entity in self._subscribers + self._queryables:
            entity.undeclare()
        self._subscribers, self._queryables = [], []
        if self._owns_session:
            self.session.close()

    # Inputs ----------------------------------------------------------------------------------

    def _on_sample(self, sample: zenoh.Sample) -> None:
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        raw = _Raw(str(sample.key_expr), sample.payload.to_bytes(), attachment)
        if self._queue.qsize() >= self._max_queue:
            self.counters.dropped += 1
            return
        self._queue.put(raw)

    def pending(self) -> int:
        """Inputs received and not yet handed out by ``events()``."""
        return self._queue.qsize()

    def events(self, timeout_s: float | None = None) -> Iterator[Message]:
        """Decoded inputs in arrival order until stopped (or `timeout_s` without input, if given).

        Inputs that fail to decode or validate are reported on the errors key and skipped.
        """
        while not self._stop.is_set():
            try:
                raw = self._queue.get(timeout=timeout_s if timeout_s is not None else 0.2)
            except queue.Empty:
                self._report_drops()
                if timeout_s is not None:
                    return
                continue
            if raw is None:
                return
            self._report_drops()
            self.counters.received += 1
            message = self._decode(raw)
            if message is not None:
                yield message

    def _decode(self, raw: _Raw) -> Message | None:
        attachment = codec.decode_attachment(raw.attachment)
        source = attachment[2] if attachment else None
        try:
            type_name = keys.message_type(raw.key)
            data = codec.decode(type_name, raw.payload)
        except (SchemaError, BusError) as exc:
            seq, stamp = (attachment[0], attachment[1]) if attachment else (None, None)
            self._count_handled(raw.key)
            self.report_error(
                raw.key, exc, input_seq=seq, input_stamp_ns=stamp, input_source=source
            )
            return None
        if source is not None:
            self._check_gap(raw.key, source, int(data["seq"]))
        return Message(raw.key, type_name, data, source)

    def _check_gap(self, key: str, source: str, seq: int) -> None:
        last = self._last_seq.get((key, source))
        self._last_seq[(key, source)] = seq
        if last is not None and seq != last + 1:
            self.counters.gaps += 1
            log.warning("sequence gap on %s from %s: %d after %d", key, source, seq, last)

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
            # Data: BLOCK, a slow link delays the publisher instead of silently dropping data (§5).
            # Status and timing: DROP, a heartbeat must never hold a service (or its shutdown) up.
            congestion = (
                zenoh.CongestionControl.BLOCK
                if keys.is_data_key(key)
                else zenoh.CongestionControl.DROP
            )
            self.session.put(key, payload, attachment=attachment, congestion_control=congestion)
            self.counters.published += 1
        return message

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
        """Publish the per-stage wall times of one computation."""
        self.publish(
            keys.service_key(self.uav, self.service, "timing"),
            {
                "stamp_ns": stamp_ns,
                "service": self.service,
                "input_seq": input_seq,
                "stages_ms": {k: float(v) for k, v in stages_ms.items()},
                "total_ms": float(sum(stages_ms.values())),
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
