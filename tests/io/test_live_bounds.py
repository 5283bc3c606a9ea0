"""The live view's server under clients that subscribe to the camera and never read (issue
21: each cost about 315 MB, and 300 connections were accepted): real WebSocket clients over
loopback, the server's own accounting asserted, and a client that reads still served."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import ExitStack

import pytest

pytest.importorskip("websockets")

from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from robocli.io import schemas as S
from robocli.io.record.links import json_text
from robocli.io.record.live import LiveView
from tests.io.foxglove_client import SUBPROTOCOLS, FoxgloveClient
from tests.waiting import wait_for

MiB = 1 << 20
#: one 640x480 rgb8 frame as the hub's camera channel carries it (JSON, base64: ~1.2 MB)
FRAME = json_text(S.raw_image(0, "hub/camera", 640, 480, "rgb8", 1920,
                              bytes(range(256)) * 3600)).encode()  # fmt: skip


def _silent(url: str, stack: ExitStack) -> FoxgloveClient:
    """A client that subscribes to the camera, then never reads again."""
    client = stack.enter_context(FoxgloveClient(url, max_queue=1, close_timeout=0.5))
    client.subscribe(client.wait_for_topics({"/hub/camera"})["/hub/camera"])
    return client


@pytest.fixture
def view() -> Iterator[LiveView]:
    with LiveView(port=0, max_clients=4, max_client_bytes=16 * MiB, stall_s=600) as v:
        yield v


def test_silent_clients_cost_their_share_and_a_reader_still_gets_every_frame(
        view: LiveView) -> None:  # fmt: skip
    cid = view.channel("/hub/camera", "foxglove.RawImage")
    server = view.server
    got: list[int] = []
    with ExitStack() as stack:
        silent = [_silent(view.url, stack) for _ in range(3)]
        reader = stack.enter_context(FoxgloveClient(view.url))
        sub = reader.subscribe(reader.wait_for_topics({"/hub/camera"})["/hub/camera"])
        wait_for(lambda: server.subscribers(cid) == 4, what="four subscribed clients")
        # the connection cap: a fifth is refused before its handshake
        with pytest.raises(InvalidStatus, match="503"):
            connect(view.url, subprotocols=list(SUBPROTOCOLS), open_timeout=30)  # type: ignore[arg-type]
        assert server.refused == 1
        done = threading.Event()

        def read() -> None:
            while not done.is_set():
                got.extend(ns for ns, _ in reader.messages(sub, 1))

        thread = threading.Thread(target=read, daemon=True)
        thread.start()
        frames = 60  # 72 MB to each silent client: far past what the kernel's buffers take
        for i in range(frames):
            view.write(cid, FRAME, 10**18 + i)
            assert server.queued_bytes <= 16 * MiB
            wait_for(lambda i=i: len(got) > i or not thread.is_alive(), what=f"frame {i}")
        done.set()
        view.write(cid, FRAME, 10**18 + frames)  # (wakes the reader's last wait)
        thread.join(60)
    # the reader got every frame, in order; the silent clients lost what passed their share
    assert got[:frames] == [10**18 + i for i in range(frames)]
    assert server.peak_queued <= 16 * MiB
    assert server.dropped >= 3 * (frames - 20), server.dropped  # each kept at most its share
    assert server.client_share == 4 * MiB
    assert len(silent) == 3 and server.slow_disconnected == 0


def test_a_client_that_reads_nothing_is_disconnected_and_its_place_given_back() -> None:
    with LiveView(port=0, max_clients=1, max_client_bytes=8 * MiB, stall_s=1.0) as view:
        cid = view.channel("/hub/camera", "foxglove.RawImage")
        server = view.server
        with ExitStack() as stack:
            _silent(view.url, stack)
            wait_for(lambda: server.subscribers(cid) == 1, what="the client's subscription")

            def gone() -> bool:
                view.write(cid, FRAME, 10**18)
                return server.slow_disconnected == 1 and server.clients == 0

            wait_for(gone, what="the silent client disconnected")
            assert server.queued_bytes == 0  # what it held is given back
        # its place is free: a new client connects and reads
        with FoxgloveClient(view.url) as client:
            sub = client.subscribe(client.wait_for_topics({"/hub/camera"})["/hub/camera"])
            wait_for(lambda: server.subscribers(cid) == 1, what="its subscription")
            view.write(cid, FRAME, 10**18 + 1)
            assert client.messages(sub, 1)[0][0] == 10**18 + 1


def test_what_a_client_sends_is_bounded_and_a_bad_request_harms_no_one(view: LiveView) -> None:
    cid = view.channel("/hub/camera", "foxglove.RawImage")
    with FoxgloveClient(view.url) as good, FoxgloveClient(view.url) as bad:
        for junk in ("not json", "[1, 2]", '{"op": "subscribe"}',
                     '{"op": "subscribe", "subscriptions": [{"id": -1, "channelId": 1}]}',
                     '{"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 99}]}',
                     '{"op": "unsubscribe", "subscriptionIds": "x"}'):  # fmt: skip
            bad.ws.send(junk)
        bad.ws.send(b"x" * (1 << 17))  # past the largest request: that client is closed
        wait_for(lambda: view.server.clients == 1, what="the bad client closed")
        sub = good.subscribe(good.wait_for_topics({"/hub/camera"})["/hub/camera"])
        wait_for(lambda: view.server.subscribers(cid) == 1, what="the good subscription")
        view.write(cid, FRAME, 10**18)
        assert good.messages(sub, 1)[0][0] == 10**18
