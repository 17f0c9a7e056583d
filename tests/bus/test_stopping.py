"""StopRequest under signals: a handler that interrupts a wait, thousands of times, never hangs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

# A timer signal every 0.3 ms sets the current request while the main thread polls it with short
# waits, so handlers land at every point of `wait`, including where a lock-taking stop
# (threading.Event.set, queue.Queue.put) would wait for its own thread forever.
_CHILD = """
import signal, sys, time
from bus.stopping import StopRequest
requests = [StopRequest()]
signal.signal(signal.SIGALRM, lambda *_: requests[-1].set())
signal.setitimer(signal.ITIMER_REAL, 3e-4, 3e-4)
stopped = 0
end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < end:
    while not requests[-1].wait(1e-5):
        pass
    stopped += 1
    requests.append(StopRequest())
signal.setitimer(signal.ITIMER_REAL, 0)
print(stopped)
"""


def test_a_signal_handler_can_always_set_a_stop_request_the_main_thread_waits_on() -> None:
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, "2.0"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) > 500  # every handler's set() was seen by a wait


def test_wait_returns_false_on_timeout_and_true_once_set_from_another_thread() -> None:
    import threading

    from bus.stopping import StopRequest

    stop = StopRequest()
    assert stop.wait(0.01) is False and not stop.is_set()
    threading.Timer(0.05, stop.set).start()
    assert stop.wait(5.0) is True
    assert stop.is_set() and stop.wait(0) is True
