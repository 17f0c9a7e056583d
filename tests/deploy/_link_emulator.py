"""A userspace radio-link emulator for the deployment tests: a TCP proxy that delays, throttles and "loses".

This kernel has no `netem` queueing discipline, so delay and loss cannot be applied to packets. The emulator sits on
the TCP path instead (air services dial it; it dials the ground router) and shapes the byte stream:

- delay: every segment leaves `delay_s` after it arrived, in each direction (round trip = 2 × delay_s);
- rate: segments of one direction share one serialiser of `rate_bps` bits per second (a radio link is one shared
  channel, whatever the number of TCP connections over it);
- loss: a TCP stream cannot lose bytes. Each `segment_bytes` segment is "lost" with probability `loss`; what a real
  TCP sender then does is retransmit it, after a fast retransmit (about one round trip) or a retransmission timeout
  (Linux: at least 200 ms). The emulator charges `retransmit_s` (default: one RTO of 200 ms + one more one-way
  delay) to the lost segment, and, TCP being in order, to every segment queued behind it (head-of-line
  blocking). The retransmission also uses the link's rate a second time. What is *not* emulated: congestion
  window collapse after a loss, and the real TCP timers of the two ends (the sockets on either side of the proxy
  see a clean link).
- buffering: at most `buffer_bytes` wait in each direction; beyond that the proxy stops reading, so the sender's
  own TCP window fills and its writes block, as on a real bottleneck.
- outage (`down(mode)` ... `up()`; SIGUSR1 / SIGUSR2 to the process): the link is gone. New connections are
  closed as soon as they are accepted (the air router's redials fail). `drop`: every open connection is cut
  at once and what was in flight is lost (the ends see the link close, as when their keep-alive lease
  expires); `hold`: open connections stay open and nothing moves until the link is back, then what waited
  is delivered (a radio fade under TCP; the ends' leases decide whether they wait that long).

Counters: bytes per direction (`up` = client→server, i.e. air→ground), lost segments, connections, connections
refused during outages, the outages (monotonic start and end, mode), and a timeline of (monotonic time, bytes)
per direction for rates.

Run standalone (inside a network namespace, for instance):
    python tests/deploy/_link_emulator.py --listen 127.0.0.1:7000 --to 10.77.0.1:7447 --delay-ms 50 --loss 0.01 \
        --rate-kbps 2000 --stats stats.json --outage-mode drop
It writes its counters as JSON to --stats every second and on SIGTERM; SIGUSR1 takes the link down, SIGUSR2
brings it back.
"""

from __future__ import annotations

import argparse
import json
import queue
import random
import signal
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

OutageMode = Literal["drop", "hold"]

TCP_RTO_MIN_S = 0.2  # Linux's minimum retransmission timeout (include/net/tcp.h TCP_RTO_MIN)


@dataclass
class Flow:
    """What crossed the link in one direction."""

    bytes: int = 0
    segments: int = 0
    lost: int = 0
    timeline: list[tuple[float, int]] = field(default_factory=list)  # (monotonic time, bytes)


@dataclass
class LinkStats:
    """What crossed the emulated link: each direction's flow, connections, refusals and outages."""

    up: Flow = field(default_factory=Flow)
    down: Flow = field(default_factory=Flow)
    connections: int = 0
    refused: int = 0
    outages: list[tuple[float, float | None, str]] = field(default_factory=list)

    def as_dict(self) -> dict:
        """Counters as JSON-able values, a flow's as bytes_up, bytes_down, ... (timelines: the last 20000)."""
        flows = {"up": self.up, "down": self.down}
        counts = {
            f"{name}_{way}": getattr(flow, name)
            for name in ("bytes", "segments", "lost")
            for way, flow in flows.items()
        }
        return counts | {
            "connections": self.connections,
            "refused": self.refused,
            "outages": self.outages,
            "timeline_up": self.up.timeline[-20000:],
            "timeline_down": self.down.timeline[-20000:],
        }


class _Direction:
    """One direction of the link: a shared serialiser and its random loss draws."""

    def __init__(self, name: str, emulator: LinkEmulator, seed: int) -> None:
        self.name = name
        self.emulator = emulator
        self.free_at = 0.0  # when the serialiser finishes what it already has
        self.lock = threading.Lock()
        self.random = random.Random(seed)

    def schedule(self, size: int, after: float) -> tuple[float, bool]:
        """(delivery time, lost?) of a segment of `size` bytes that arrived at `after`."""
        e = self.emulator
        with self.lock:
            airtime = size * 8.0 / e.rate_bps if e.rate_bps else 0.0
            start = max(self.free_at, after)
            self.free_at = start + airtime
            lost = e.loss > 0 and self.random.random() < e.loss
            if lost:
                self.free_at += airtime  # the retransmission occupies the channel again
            return self.free_at + e.delay_s + (e.retransmit_s if lost else 0.0), lost


class LinkEmulator:
    """TCP proxy from `listen` to `target` with delay, rate and loss (see the module docstring).

    Args:
        listen: (host, port) to accept on; port 0 picks a free one (see `port`).
        target: (host, port) to connect each accepted connection to.
        delay_s: one-way delay added in each direction, seconds.
        loss: probability that a segment is lost and retransmitted, in [0, 1).
        rate_bps: link rate per direction, bits per second (None: unlimited).
        retransmit_s: extra delay of a lost segment, seconds (default: TCP_RTO_MIN + delay_s).
        segment_bytes: segment size (a TCP MSS on Ethernet), bytes.
        buffer_bytes: bytes that may wait per direction before the proxy stops reading.
        seed: seed of the loss draws.
    """

    def __init__(
        self,
        listen: tuple[str, int],
        target: tuple[str, int],
        *,
        delay_s: float = 0.0,
        loss: float = 0.0,
        rate_bps: float | None = None,
        retransmit_s: float | None = None,
        segment_bytes: int = 1448,
        buffer_bytes: int = 256 * 1024,
        seed: int = 0,
    ) -> None:
        if delay_s < 0 or not 0 <= loss < 1 or (rate_bps is not None and rate_bps <= 0):
            raise ValueError(
                f"delay {delay_s} s must be >= 0, loss {loss} in [0, 1), rate {rate_bps} > 0"
            )
        self.target = target
        self.delay_s = delay_s
        self.loss = loss
        self.rate_bps = rate_bps
        self.retransmit_s = TCP_RTO_MIN_S + delay_s if retransmit_s is None else retransmit_s
        self.segment_bytes = segment_bytes
        self.buffer_bytes = buffer_bytes
        self.stats = LinkStats()
        self._stats_lock = threading.Lock()
        self._up = _Direction("up", self, seed)
        self._down = _Direction("down", self, seed + 1)
        self._server = socket.create_server(listen, reuse_port=False)
        self._server.settimeout(0.2)
        self.port = int(self._server.getsockname()[1])
        self._stop = threading.Event()
        self._link_up = threading.Event()
        self._link_up.set()
        self._sockets: list[socket.socket] = []
        self._threads: list[threading.Thread] = []

    def start(self) -> LinkEmulator:
        """Start accepting connections."""
        thread = threading.Thread(target=self._accept, name="link-accept", daemon=True)
        thread.start()
        self._threads.append(thread)
        return self

    def __enter__(self) -> LinkEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def stop(self) -> None:
        """Close every connection and the listening socket."""
        self._stop.set()
        self.cut()  # wakes the threads blocked in recv (a close alone does not)
        for sock in [self._server, *self._sockets]:
            try:
                sock.close()
            except OSError:
                pass
        for thread in self._threads:
            thread.join(timeout=2.0)

    def cut(self) -> None:
        """Close every open connection (the link drops); new connections are still accepted."""
        for sock in list(self._sockets):
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def down(self, mode: OutageMode = "drop") -> None:
        """Take the link down until `up()` (see the module docstring for the modes)."""
        if mode not in ("drop", "hold"):
            raise ValueError(f"outage mode {mode!r} must be 'drop' or 'hold'")
        if not self._link_up.is_set():
            return
        self._link_up.clear()
        with self._stats_lock:
            self.stats.outages.append((time.monotonic(), None, mode))
        if mode == "drop":
            self.cut()

    def up(self) -> None:
        """Bring the link back after `down()`."""
        if self._link_up.is_set():
            return
        with self._stats_lock:
            start, _, mode = self.stats.outages[-1]
            self.stats.outages[-1] = (start, time.monotonic(), mode)
        self._link_up.set()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                client, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            if not self._link_up.is_set():  # nothing reaches the other side during an outage
                client.close()
                with self._stats_lock:
                    self.stats.refused += 1
                continue
            try:
                server = socket.create_connection(self.target, timeout=5.0)
            except OSError:
                client.close()
                continue
            for sock in (client, server):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                sock.settimeout(None)
            self._sockets += [client, server]
            with self._stats_lock:
                self.stats.connections += 1
            for src, dst, direction in ((client, server, self._up), (server, client, self._down)):
                self._pump(src, dst, direction)

    def _pump(self, src: socket.socket, dst: socket.socket, direction: _Direction) -> None:
        pending: deque[tuple[float, bytes]] = deque()
        cond = threading.Condition()
        queued = [0]
        closed = [False]

        def read() -> None:
            try:
                while not self._stop.is_set():
                    data = src.recv(65536)
                    if not data:
                        break
                    while not self._link_up.wait(0.5) and not self._stop.is_set():
                        pass  # held: what arrives waits for the link
                    now = time.monotonic()
                    for i in range(0, len(data), self.segment_bytes):
                        segment = data[i : i + self.segment_bytes]
                        with cond:
                            # a full buffer stops reading: the sender's TCP window fills, as on a real bottleneck
                            cond.wait_for(
                                lambda: queued[0] < self.buffer_bytes or self._stop.is_set(), 1.0
                            )
                            deliver_at, lost = direction.schedule(len(segment), now)
                            if pending:  # in-order delivery: a retransmission holds up what follows
                                deliver_at = max(deliver_at, pending[-1][0])
                            pending.append((deliver_at, segment))
                            queued[0] += len(segment)
                            cond.notify_all()
                        self._count(direction.name, len(segment), lost)
            except OSError:
                pass
            with cond:
                closed[0] = True
                cond.notify_all()

        def write() -> None:
            try:
                while True:
                    with cond:
                        cond.wait_for(lambda: pending or closed[0] or self._stop.is_set(), 0.5)
                        if self._stop.is_set() or (closed[0] and not pending):
                            break
                        if not pending:
                            continue
                        deliver_at, segment = pending[0]
                    wait = deliver_at - time.monotonic()
                    if wait > 0:
                        time.sleep(wait)
                    while not self._link_up.wait(0.5) and not self._stop.is_set():
                        pass  # held: nothing leaves until the link is back
                    dst.sendall(segment)
                    with cond:
                        pending.popleft()
                        queued[0] -= len(segment)
                        cond.notify_all()
            except OSError:
                pass
            for sock in (dst, src):
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

        for target, name in ((read, "read"), (write, "write")):
            thread = threading.Thread(
                target=target, name=f"link-{direction.name}-{name}", daemon=True
            )
            thread.start()
            self._threads.append(thread)

    def _count(self, name: str, size: int, lost: bool) -> None:
        now = time.monotonic()
        with self._stats_lock:
            flow = self.stats.up if name == "up" else self.stats.down
            flow.bytes += size
            flow.segments += 1
            flow.lost += int(lost)
            flow.timeline.append((now, size))

    def snapshot(self) -> dict:
        """The counters, as a JSON-able dict."""
        with self._stats_lock:
            return self.stats.as_dict()


def _address(text: str) -> tuple[str, int]:
    host, port = text.rsplit(":", 1)
    return host, int(port)


def main(argv: list[str] | None = None) -> int:
    """Run the emulator until SIGTERM, writing its counters to --stats."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--listen", type=_address, required=True, help="HOST:PORT to accept on")
    parser.add_argument("--to", type=_address, required=True, help="HOST:PORT to forward to")
    parser.add_argument(
        "--delay-ms", type=float, default=0.0, help="one-way delay per direction, ms"
    )
    parser.add_argument("--loss", type=float, default=0.0, help="segment loss probability")
    parser.add_argument("--rate-kbps", type=float, help="rate per direction, kbit/s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--stats", type=Path, help="JSON file for the counters")
    parser.add_argument(
        "--outage-mode",
        choices=["drop", "hold"],
        default="drop",
        help="what SIGUSR1 does to open connections (SIGUSR2 ends the outage)",
    )
    args = parser.parse_args(argv)
    emulator = LinkEmulator(
        args.listen,
        args.to,
        delay_s=args.delay_ms / 1000,
        loss=args.loss,
        rate_bps=args.rate_kbps * 1000 if args.rate_kbps else None,
        seed=args.seed,
    )
    # Signal handlers only queue a command: the main thread may hold the counters' lock when one runs.
    commands: queue.SimpleQueue[str] = queue.SimpleQueue()
    for sig, command in (
        (signal.SIGTERM, "stop"),
        (signal.SIGINT, "stop"),
        (signal.SIGUSR1, "down"),
        (signal.SIGUSR2, "up"),
    ):
        signal.signal(sig, lambda *_, c=command: commands.put(c))
    emulator.start()
    print(f"ready {emulator.port}", flush=True)

    def dump() -> None:
        if args.stats:
            tmp = args.stats.with_suffix(".tmp")
            tmp.write_text(json.dumps(emulator.snapshot()))
            tmp.replace(args.stats)

    next_dump = time.monotonic() + 1.0
    while True:
        try:
            command = commands.get(timeout=max(0.0, next_dump - time.monotonic()))
        except queue.Empty:
            command = None
        if command == "stop":
            break
        if command == "down":
            emulator.down(args.outage_mode)
        elif command == "up":
            emulator.up()
        if command in ("down", "up") or time.monotonic() >= next_dump:
            dump()
            next_dump = time.monotonic() + 1.0
    emulator.stop()
    dump()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
