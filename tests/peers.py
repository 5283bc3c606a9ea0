"""What tests see of a server from a bare socket (``import peers``)."""

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
