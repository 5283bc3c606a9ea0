"""The output budget is charged to the connections that cause it (issue 21, point 4: 50
silent subscribers that pull and never read took a hub from 58 to 328 MB and an authorized
client was cut mid-reply; the README's bound on waiting replies was not true)."""

from __future__ import annotations

import socket
import threading
from typing import Any

import pytest

from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m

TOKEN = b"lab-token"
CAM = {"fps": 30, "width": 640, "height": 480, "compression": 0, "roi": [0] * 4, "id": 0,
       "exposure": 0, "use_roi": 0}  # fmt: skip
FRAME = 640 * 480 * 3
SILENT = 12
PULLS = 15


def _pull_without_reading(sock: socket.socket, pull: bytes, stop: threading.Event) -> None:
    """Send pulls and never read, until the hub stops taking them or drops the link."""
    sock.settimeout(0.5)
    try:
        while not stop.is_set():
            try:
                sock.sendall(pull)
            except TimeoutError:
                continue  # the hub handles no request while a reply waits: keep trying
    except OSError:
        pass  # dropped


@pytest.mark.parametrize("token", [TOKEN, None], ids=["token", "open"])
def test_silent_pullers_are_cut_not_the_reader(raw: Any, wait: Any, token: bytes | None) -> None:
    """An authorized client runs a 640x480 raw camera and pulls it, reading every reply;
    12 clients without the token subscribe silently, pull and never read. Each of their
    replies (up to 8 frames, 7.4 MB) is held by the hub: over all of them, the hub's own
    account of the output it holds (whole replies: memory, not just the unsent tail) stays
    within the budget, the silent ones pay for it (cut), and the reader, whose large
    replies wait in the hub while it reads them, gets every reply."""
    budget = 16 << 20
    with HubServer(port=0, token=token, ring_budget=16 << 20, output_budget=budget,
                   send_timeout=60.0) as srv:  # fmt: skip
        good = raw(srv.port)  # a reader on a slow link: most of a reply waits in the hub
        good.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 16)
        good.connect(token=TOKEN)
        assert good.subscribe("camera", CAM, buffer=8).error == 0
        silent = []
        for _ in range(SILENT):
            c = raw(srv.port)
            c.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            c.connect()
            assert c.subscribe("camera", silent=True, buffer=8).error == 0
            silent.append(c)
        ring = srv.hub.channels["camera"].ring
        base = ring.pushed
        wait(lambda: ring.pushed >= base + 8, timeout=30, what="8 frames for every cursor")
        stop = threading.Event()
        threads = [
            threading.Thread(
                target=_pull_without_reading,
                daemon=True,
                args=(c.sock, r4m.encode_request("camera", client_id=c.client_id), stop),
            )
            for c in silent
        ]
        for t in threads:
            t.start()
        ids = {c.client_id for c in silent}
        try:
            frames = replies = 0
            for _ in range(PULLS):  # replies of 6-8 frames: more than the kernel takes at once
                mark = ring.pushed
                wait(lambda m=mark: ring.pushed >= m + 6, timeout=30, what="6 new frames")
                frames += good.pull("camera").size  # a ConnectionError fails the test
                replies += 1
            fit = budget // (8 * FRAME)  # silent replies the budget holds at once

            def cut() -> bool:
                return len([i for i in srv.clients if i.id in ids and i.connected]) <= fit

            wait(cut, timeout=30, what="the silent pullers beyond the budget cut")
            good.pull("camera")  # still served after them
        finally:
            stop.set()
            for t in threads:
                t.join(10)
        held = srv._server.budget
        print(
            f"{replies} replies, {frames} frames to the reader; output held peak "
            f"{srv.output_peak / 1e6:.1f} MB of {budget / 1e6:.1f}; {held.evicted} cut"
        )
        assert replies == PULLS and frames > 0
        assert srv.output_peak <= budget
        assert held.evicted >= 1
        for c in [good, *silent]:
            c.close()
