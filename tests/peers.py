"""What tests see of a server from a bare socket (``from tests import peers``), a free
loopback endpoint for a server that cannot report the port it took, and whether this machine
has an IPv6 loopback."""

from __future__ import annotations

import socket
import time

import pytest


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


def ipv6_loopback() -> bool:
    """Whether this machine can listen on [::1] (containers often have no IPv6)."""
    if not socket.has_ipv6:
        return False
    try:
        with socket.socket(socket.AF_INET6, socket.SOCK_STREAM) as s:
            s.bind(("::1", 0))
    except OSError:
        return False
    return True


needs_ipv6 = pytest.mark.skipif(not ipv6_loopback(), reason="no IPv6 loopback ([::1]) here")
