"""Who pays when the output budget of a server is full (``robocli.serving.links.limits``), over
real sockets: an echo server whose links the test sends large replies to."""

from __future__ import annotations

import socket
import threading
from typing import Any

import pytest

from robocli.serving.server import Link, Server
from tests.serving.test_serving import Echo, dial
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

REPLY = 8 << 20  # far more than the kernel takes from a peer with a 4 KiB receive window


class WatchedLock:
    """A link's output lock, shared with the link, that tells when another thread waits for
    it (the budget making room) while the test holds it."""

    def __init__(self, lock: Any) -> None:
        self._lock = lock
        self.waited = threading.Event()

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        if blocking and self._lock.locked():
            self.waited.set()
        return bool(self._lock.acquire(blocking, timeout))

    def release(self) -> None:
        self._lock.release()

    def locked(self) -> bool:
        return bool(self._lock.locked())

    def __enter__(self) -> bool:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def new_link(server: Server, known: list[Link]) -> tuple[socket.socket, Link]:
    """A client that never reads, and the server's link to it."""
    sock = dial(server, rcvbuf=4096)
    wait_for(lambda: len(server.links()) == len(known) + 1, "the new link")
    (link,) = [lk for lk in server.links() if lk not in known]
    known.append(link)
    return sock, link


def test_a_silent_link_busy_for_a_moment_still_pays_before_the_reader() -> None:
    """A silent link holds the oldest waiting reply, a reader a newer one, and a third link's
    reply goes over the budget: the silent one pays. That holds when the silent link's own
    thread has its output lock at that moment (a busy machine descheduled it in the middle
    of a write): the budget waits for the lock instead of dropping the reader, which had
    been dropped in a loaded run ("closed after 4.1 of 7.4 MB")."""
    server = Server(lambda link: Echo(link, []), protocol="arcos", name="echo", max_clients=3,
                    send_timeout=60.0, max_backlog=1 << 26,
                    output_budget=REPLY * 5 // 2)  # fmt: skip
    try:
        server.serve_tcp()
        check_who_pays(server)
    finally:
        server.close()


def check_who_pays(server: Server) -> None:
    known: list[Link] = []
    socks = []
    for _ in range(3):
        sock, _link = new_link(server, known)
        socks.append(sock)
    silent, reader, third = known
    assert silent.send(bytes(REPLY)) and reader.send(bytes(REPLY))  # silent's waits longest
    assert silent.pending_output and reader.pending_output
    lock = WatchedLock(silent._tx_lock)
    silent._tx_lock = lock  # type: ignore[assignment]
    sent: list[bool] = []
    with lock:  # the silent link's thread, descheduled in the middle of a write
        t = threading.Thread(target=lambda: sent.append(third.send(bytes(REPLY))))
        t.start()
        wait_for(lambda: lock.waited.is_set() or not t.is_alive(), "the budget to make room")
    t.join(10)
    assert sent == [True]
    assert reader.alive, "the reader paid for the silent link"
    assert not silent.alive
    assert server.budget is not None and server.budget.evicted == 1
    assert server.budget.total <= server.budget.cap  # type: ignore[operator]
    for s in socks:
        s.close()
