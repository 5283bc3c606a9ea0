"""What tests see of a server from a bare socket (``from tests import peers``), and a free
loopback endpoint for a server that cannot report the port it took."""

from __future__ import annotations

import socket
import time


def closed_by_peer(sock: socket.socket, deadline: float = 30.0) -> bool:
    """Whether the other end closes ``sock`` (end of stream or reset) within ``deadline``
    s, reading and discarding whatever it sends first."""
    end = time.monotonic() + deadline
    while (left := end - time.monotonic()) > 0:
        sock.settimeout(left)
        try:
            if not sock.recv(65536):
                return True
        except TimeoutError:
            return False
        except OSError:
            return True
    return False


def free_endpoint() -> str:
    """``tcp/127.0.0.1:PORT`` on a port free a moment ago (Zenoh does not report the port
    it took for port 0, so the test asks the kernel for one first)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"
