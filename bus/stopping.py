"""A stop request that a SIGTERM/SIGINT handler may raise safely.

Python runs a signal handler in the main thread between two bytecodes, possibly while that thread
holds a lock: inside `threading.Event.wait` or `queue.Queue.get`, say. A handler that then takes the
same lock (`Event.set`, `Queue.put`) waits for itself forever, and the process hangs until it is
killed, which costs the recorder its file's summary. `queue.SimpleQueue` is implemented in C and
reentrant (safe to `put` into from a handler that interrupted a `get`), so `StopRequest` sets a
plain flag and wakes its waiters through one.
"""

from __future__ import annotations

import queue
import signal
import threading
from collections.abc import Callable


class StopRequest:
    """A flag that is set once, from any thread or from a signal handler, and can be waited for."""

    def __init__(self) -> None:
        self._requested = False
        self._wake: queue.SimpleQueue[None] = queue.SimpleQueue()

    def set(self) -> None:
        """Request the stop. Takes no lock, so a signal handler may call it."""
        self._requested = True
        self._wake.put(None)

    def is_set(self) -> bool:
        """True once a stop was requested."""
        return self._requested

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block until the stop is requested or `timeout_s` passes; returns `is_set()`."""
        if self._requested:
            return True
        try:
            self._wake.get(timeout=timeout_s)
        except queue.Empty:
            return self._requested
        self._wake.put(None)  # pass the wake-up on to any other waiting thread
        return True


def stop_on_signals(stop: Callable[[], None]) -> None:
    """Call `stop` on SIGTERM and SIGINT. It runs inside the signal handler, so it must take no lock
    (`StopRequest.set` and `SimpleQueue.put` take none). Only the main thread may install handlers;
    elsewhere (a service run in a test's thread) this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop())
