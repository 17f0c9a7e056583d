"""The link emulator's outages on loopback (no namespaces, no root): `drop` cuts what is open and
refuses what dials, `hold` keeps connections open and delivers what waited once the link is back."""

from __future__ import annotations

import socket
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _link_emulator import LinkEmulator  # noqa: E402


@pytest.fixture
def echo() -> Iterator[tuple[str, int]]:
    """A TCP server on loopback that sends back what it receives, one thread per connection."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.2)
    stop = threading.Event()
    conns: list[socket.socket] = []

    def serve(conn: socket.socket) -> None:
        try:
            while data := conn.recv(65536):
                conn.sendall(data)
        except OSError:
            pass

    def accept() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            conns.append(conn)
            threading.Thread(target=serve, args=(conn,), daemon=True).start()

    acceptor = threading.Thread(target=accept, daemon=True)
    acceptor.start()
    yield ("127.0.0.1", server.getsockname()[1])
    stop.set()
    acceptor.join()
    server.close()
    for conn in conns:
        conn.close()


def _dial(emulator: LinkEmulator) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", emulator.port), timeout=2.0)
    sock.settimeout(2.0)
    return sock


def _closed(sock: socket.socket) -> bool:
    """True when the other end closed or reset the connection (a timeout raises)."""
    try:
        return sock.recv(1) == b""
    except ConnectionResetError:
        return True


def test_a_drop_outage_cuts_open_links_and_refuses_new_ones(echo: tuple[str, int]) -> None:
    with LinkEmulator(("127.0.0.1", 0), echo) as emulator:
        before = _dial(emulator)
        before.sendall(b"ping")
        assert before.recv(4) == b"ping"
        emulator.down("drop")
        assert _closed(before)
        during = _dial(emulator)  # the listening socket accepts, then closes at once
        assert _closed(during)
        emulator.up()
        after = _dial(emulator)
        after.sendall(b"pong")
        assert after.recv(4) == b"pong"
        stats = emulator.snapshot()
    assert stats["refused"] == 1
    ((start, end, mode),) = stats["outages"]
    assert mode == "drop" and end is not None and end >= start


def test_a_hold_outage_delivers_what_waited_once_the_link_is_back(echo: tuple[str, int]) -> None:
    with LinkEmulator(("127.0.0.1", 0), echo, delay_s=0.01) as emulator:
        sock = _dial(emulator)
        sock.sendall(b"ping")
        assert sock.recv(4) == b"ping"  # connected through, before the outage
        emulator.down("hold")
        sock.sendall(b"held")
        sock.settimeout(0.5)
        with pytest.raises(TimeoutError):
            sock.recv(4)  # nothing crosses while the link is down
        t_up = time.monotonic()
        emulator.up()
        sock.settimeout(2.0)
        assert sock.recv(4) == b"held"  # the same connection, the same bytes
        assert time.monotonic() - t_up < 1.0
