"""Lock-step's question: whether the pipeline has answered the camera frame of stamp S.

An answer is a message on the answer key (Detections by default) whose stamp_ns is S, or an ErrorReport on any
`atr/{uav}/{service}/errors` key whose input_stamp_ns is S (docs/architecture.md, "One answer per frame").
The waiting side's own error reports (e.g. its timeout warnings) answer nothing.
"""

from __future__ import annotations

import threading
import time

import zenoh

from bus import codec
from bus.stopping import StopRequest

DEFAULT_ANSWER_KEY = "atr/{uav}/detections"
STOP_POLL_S = 0.1  # how often a waiting `wait` looks at its stop request, s


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
        self._subscribers = [
            session.declare_subscriber(answer_key.replace("{uav}", "*"), self._on_answer),
            session.declare_subscriber("atr/*/*/errors", self._on_error_report),
        ]

    def _on_answer(self, sample: zenoh.Sample) -> None:
        self._note(sample, "stamp_ns")

    def _on_error_report(self, sample: zenoh.Sample) -> None:
        if str(sample.key_expr).split("/")[2] != self._own_service:
            self._note(sample, "input_stamp_ns")

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
        self, uav: str, stamp_ns: int, timeout_s: float, stop: StopRequest | None = None
    ) -> bool:
        """True once frame `stamp_ns` of `uav` was answered; False after `timeout_s` or on `stop`.

        `stop` is looked at every `STOP_POLL_S`: a signal handler sets it and must not take our lock
        to wake us (bus/stopping.py).
        """
        deadline = time.monotonic() + timeout_s
        key = (uav, stamp_ns)
        with self._cv:
            while key not in self._answers and not (stop is not None and stop.is_set()):
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._cv.wait(min(left, STOP_POLL_S))
            answered = key in self._answers
            self._answers.discard(key)
        return answered and not (stop is not None and stop.is_set())

    def close(self) -> None:
        """Stop watching."""
        for subscriber in self._subscribers:
            subscriber.undeclare()
        self._subscribers = []
