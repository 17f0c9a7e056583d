"""Lock-step's question: whether the pipeline has answered the camera frame of stamp S.

An answer is a message on the answer key (Detections by default) whose stamp_ns is S, or an ErrorReport on any
`atr/{uav}/{service}/errors` key whose input_stamp_ns is S (docs/architecture.md, "One answer per frame").
The waiting side's own error reports (e.g. its timeout warnings) answer nothing. Answers published while
the link was down arrive when it is back (zenoh-ext's recovery, bus/reliable.py).

A service restarted while a frame is in flight (killed, then started again by its launcher) may have missed
that frame's inputs, or its answer may have been lost with it. The watch follows every service's Status:
a `running` Status from a pid not seen before, of a process started after the watch began, where another
pid of that service ran before, is a restart (two processes of one service, such as the ground's and the
air's recorders, are not restarts of each other). A service's first start is not one: a flight may begin while slow services (the template store building its templates)
are still starting, and re-sending then would cost the radio link a frame's clouds for nothing. `wait` then calls its
`on_restart` (the driver re-publishes the frame's inputs, same bytes and attachments; services answer a
repeat by re-publishing their answer, or ignore it) and goes on waiting (docs/architecture.md, "Recovery").

A recorder killed while a frame is in flight would miss that frame's messages even when the pipeline answers
it. Every Node holds a Zenoh liveliness token `atr/{uav}/{service}/alive` once ready, which disappears within
milliseconds of its process's death; a recorder whose token went away holds the frame until it is back, and
the frame is then sent again, so its inputs and answers are recorded. A recorder the watch never saw alive
(one the link's access control hides) holds nothing.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from bus import codec, reliable
from bus.stopping import StopRequest

log = logging.getLogger("atr")

DEFAULT_ANSWER_KEY = "atr/{uav}/detections"
STOP_POLL_S = 0.1  # how often a waiting `wait` looks at its stop request, s
RESTART_SETTLE_S = (
    0.3  # after a restarted service says `running`: its subscriptions reach every peer
)


class AnswerWatch:
    """Collects (uav, stamp_ns) answers from the bus; `wait` blocks until one arrives.

    Args:
        session: an open Zenoh session (not closed here).
        own_service: the waiting service's name; its own ErrorReports are ignored.
        answer_key: key of the answers; `{uav}` stands for any vehicle.

    """

    def __init__(
        self, session: zenoh.Session, own_service: str, answer_key: str = DEFAULT_ANSWER_KEY
    ) -> None:
        self._own_service = own_service
        self._answers: set[tuple[str, int]] = set()
        self._cv = threading.Condition()
        self._started = time.monotonic()
        self._pids: dict[tuple[str, str], set[int]] = {}  # (uav, service) -> pids seen running
        self.restarts: list[tuple[str, str, int]] = []  # (uav, service, new pid), in order seen
        self._recorders_down: set[tuple[str, str]] = set()  # (uav, service) whose token went away
        self.recorder_returns = 0  # how many times a recorder's token came back
        self._subscribers: list[Any] = [
            reliable.Subscriber(session, answer_key.replace("{uav}", "*"), self._on_answer),
            reliable.Subscriber(session, "atr/*/*/errors", self._on_error_report),
            reliable.Subscriber(session, "atr/*/*/status", self._on_status),
            session.liveliness().declare_subscriber("atr/*/*/alive", self._on_alive, history=True),
        ]

    def _on_answer(self, sample: zenoh.Sample) -> None:
        self._note(sample, "stamp_ns")

    def _on_error_report(self, sample: zenoh.Sample) -> None:
        if str(sample.key_expr).split("/")[2] != self._own_service:
            self._note(sample, "input_stamp_ns")

    def _on_status(self, sample: zenoh.Sample) -> None:
        try:
            status = codec.unpack(sample.payload.to_bytes())
            service, pid, state = str(status["service"]), int(status["pid"]), status["state"]
            uptime_s = float(status.get("uptime_s", 0.0))
        except Exception:  # not ours to judge here; the recorder keeps it
            return
        uav = str(sample.key_expr).split("/")[1]
        if service == self._own_service:
            return
        with self._cv:
            if state == "running":
                seen = self._pids.setdefault((uav, service), set())
                if pid not in seen:
                    started_since = uptime_s < time.monotonic() - self._started
                    if seen and started_since:
                        self.restarts.append((uav, service, pid))
                        log.warning("%s of %s restarted (pid %d)", service, uav, pid)
                        self._cv.notify_all()
                    seen.add(pid)

    def _on_alive(self, sample: zenoh.Sample) -> None:
        parts = str(sample.key_expr).split("/")
        if len(parts) != 4 or "recorder" not in parts[2]:
            return
        recorder = (parts[1], parts[2])
        with self._cv:
            if sample.kind == zenoh.SampleKind.DELETE:
                log.warning("%s of %s is gone: frames wait for it", recorder[1], recorder[0])
                self._recorders_down.add(recorder)
            elif recorder in self._recorders_down:
                self._recorders_down.discard(recorder)
                self.recorder_returns += 1
            self._cv.notify_all()

    def _recorder_down(self, uav: str) -> bool:
        return any(u == uav for u, _ in self._recorders_down)

    def _note(self, sample: zenoh.Sample, field_name: str) -> None:
        try:
            message = codec.unpack(sample.payload.to_bytes())
        except Exception:  # not ours to judge here; the recorder keeps it
            return
        stamp = message.get(field_name) if isinstance(message, dict) else None
        if isinstance(stamp, int):
            with self._cv:
                self._answers.add((str(sample.key_expr).split("/")[1], stamp))
                self._cv.notify_all()

    def wait(
        self,
        uav: str,
        stamp_ns: int,
        timeout_s: float,
        stop: StopRequest | None = None,
        on_restart: Callable[[], None] | None = None,
        since: int | None = None,
    ) -> bool:
        """True once frame `stamp_ns` of `uav` was answered; False after `timeout_s` or on `stop`.

        `stop` is looked at every `STOP_POLL_S`: a signal handler sets it and must not take our lock
        to wake us (bus/stopping.py). `on_restart` is called (outside the lock) each time a
        service of `uav` restarts while the frame waits, or after `since` (a `mark()` taken before
        the frame's first input was sent): the caller sends the frame's inputs again.
        """
        deadline = time.monotonic() + timeout_s
        key = (uav, stamp_ns)

        def stopped() -> bool:
            return stop is not None and stop.is_set()

        with self._cv:
            seen = len(self.restarts) if since is None else since
            returns = self.recorder_returns
        while True:
            with self._cv:
                while key not in self._answers and not stopped() and not self._restarted(uav, seen):
                    left = deadline - time.monotonic()
                    if left <= 0:
                        break
                    self._cv.wait(min(left, STOP_POLL_S))
                answered = key in self._answers
                restarted = not answered and self._restarted(uav, seen)
                seen = len(self.restarts)
                if answered:
                    # a recorder lost meanwhile: hold the frame until it is back, then send it again
                    while self._recorder_down(uav) and not stopped():
                        if time.monotonic() >= deadline:
                            break
                        self._cv.wait(STOP_POLL_S)
                    self._answers.discard(key)
                    lost = self.recorder_returns != returns and not self._recorder_down(uav)
                    returns = self.recorder_returns
                    if not lost or on_restart is None:
                        break
                elif not restarted:
                    self._answers.discard(key)
                    break
            if on_restart is None or stopped():
                continue
            time.sleep(RESTART_SETTLE_S)
            with self._cv:
                if not answered and key in self._answers:  # the restarted process answered it
                    continue
            on_restart()
        return answered and not (stop is not None and stop.is_set())

    def mark(self) -> int:
        """How many restarts were seen so far: `wait(since=...)` of a frame about to be sent."""
        with self._cv:
            return len(self.restarts)

    def _restarted(self, uav: str, seen: int) -> bool:
        return any(u == uav for u, _, _ in self.restarts[seen:])

    def close(self) -> None:
        """Stop watching."""
        for subscriber in self._subscribers:
            subscriber.undeclare()
        self._subscribers = []
