"""``robocli dump laser PORT|--file CAPTURE``: every SCIP line both ways, named and decoded
(:mod:`robocli.analysis.scip`), like a protocol analyser.

Live, it connects as a client (the handshake, VV/PP/II, TM, BM are shown as they happen) and
streams MD until ``--count`` scans or Ctrl-C. ``--file`` decodes a capture: a ``.jsonl`` of
``{"t", "dir": "c2s"|"s2c", "hex"}`` chunks (the format of ``dump pioneer --output``), a
recording of ``record --laser`` (``.mcap``: its raw ``scip2`` channels), or raw bytes the
sensor sent.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import typer

from robocli.commands._common import print_json_line, reader_may_leave, sigterm_as_interrupt
from robocli.commands._options import WIRE_DIR, count_option, device_argument, json_option
from robocli.commands.laser import BaudOpt, Model, ModelOpt, TimeoutOpt, laser_url

MAX_CAPTURE_LINE = 1 << 20  #: longest .jsonl line read
MAX_GAP = 16 << 20  #: bytes read without a block before giving up (as robocli.io.capture)


class _View:
    """Prints the lines of requests (``tx``) and replies (``rx``), one output line each.
    JSON: ``t`` Unix time (``offset`` added to a frame's time; None when unknown), ``t_rel``
    seconds since the first line, ``dir`` ``c2s``/``s2c`` as in capture files. A reader that
    left (``| head``) is noted in :attr:`reader_left` (this runs in the link's thread)."""

    def __init__(self, json_out: bool, offset: float | None = None) -> None:
        self.json_out = json_out
        self.offset = offset
        self.t0: float | None = None
        self.lock = threading.Lock()
        self.scans = 0
        self.reader_left = threading.Event()

    def show(self, direction: str, payload: bytes, t: float) -> None:
        try:
            self._show(direction, payload, t)
        except BrokenPipeError:
            self.reader_left.set()

    def _show(self, direction: str, payload: bytes, t: float) -> None:
        from robocli.analysis.scip import describe_reply, describe_request

        if self.t0 is None:
            self.t0 = t
        rel = t - self.t0
        if direction == "tx":
            lines = [describe_request(payload)]
        else:
            lines = describe_reply(payload)
            if payload[:1] == b"M" and b"\n99" in payload[:40]:
                self.scans += 1
        arrow = "->" if direction == "tx" else "<-"
        with self.lock:
            for line in lines:
                if self.json_out:
                    unix = None if self.offset is None else round(t + self.offset, 6)
                    print_json_line({"t": unix, "t_rel": round(rel, 6), "dir": WIRE_DIR[direction],
                                     "line": line.text, "what": line.what})  # fmt: skip
                else:
                    typer.echo(f"{rel:10.6f} {arrow} {line.text[:70]:<70} {line.what}")


def dump(
    port: str | None = device_argument("laser", default=None),
    count: int = count_option(3, "Scans to stream live (0: until Ctrl-C).", min=0),
    json_out: bool = json_option(),
    file: Path | None = typer.Option(
        None,
        "--file",
        "-f",
        metavar="CAPTURE",
        exists=True,
        dir_okay=False,
        help="Decode a capture (.jsonl chunks, a .mcap recording or raw sensor bytes).",
    ),
    model: Model = ModelOpt,
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Show every SCIP line of a laser session both ways, named and decoded."""
    if (port is None) == (file is None):
        raise typer.BadParameter("give a URL or --file CAPTURE (one of them)")
    view = _View(json_out)
    with reader_may_leave(), sigterm_as_interrupt():
        if file is not None:
            _dump_file(view, file)
            return
        assert port is not None
        from robocli.devices.laser import Laser

        view.offset = time.time() - time.monotonic()  # the link stamps on time.monotonic()
        with laser_url(port, model) as url:
            with Laser.connect(url, baudrate=baud, timeout=timeout, listeners=[view.show]) as laser:
                with contextlib.closing(laser.scans(None)) as scans:  # QT now, not at collection
                    for n, _ in enumerate(scans, 1):
                        if view.reader_left.is_set():  # printed in the link's thread
                            raise BrokenPipeError
                        if count and n >= count:
                            break


def _dump_file(view: _View, file: Path) -> None:
    """Show the lines of a capture, streamed in bounded memory: a ``.jsonl`` line longer
    than :data:`MAX_CAPTURE_LINE` is skipped, and :data:`MAX_GAP` bytes without a block
    (``/dev/zero``, noise) end the reading with an error."""
    from robocli.errors import RobocliError
    from robocli.protocols.scip2 import fast
    from robocli.sim.hokuyo.framing import RequestFramer

    if file.suffix == ".mcap":
        _dump_recording(view, file)
        return
    rx, tx = fast.reply_framer(), RequestFramer()
    shown = gap = 0
    with file.open("rb") as stream:
        for t, direction, data, size in _chunks(view, stream, file.suffix == ".jsonl"):
            framer: Any = tx if direction == "tx" else rx
            frames = framer.feed(data)
            for frame in frames:
                view.show(direction, frame, t)
            shown += len(frames)
            gap = 0 if frames else gap + size
            if gap > MAX_GAP:
                raise RobocliError(f"{file}: {MAX_GAP >> 20} MiB without a SCIP block; "
                                   "not a capture")  # fmt: skip
    dropped = rx.stats.dropped_bytes + tx.stats.dropped_bytes
    if shown == 0:
        raise RobocliError(f"{file}: no SCIP line decoded ({dropped} bytes dropped)")
    if dropped:
        typer.echo(f"robocli: {file}: {shown} blocks decoded, {dropped} bytes dropped", err=True)


def _dump_recording(view: _View, file: Path) -> None:
    """Show the lines of a recording's raw ``scip2`` channels (``record --laser``)."""
    from robocli.io.capture import CaptureStats
    from robocli.io.record import info, raw_frames

    stats = CaptureStats()
    view.offset = info(file).start_ns / 1e9  # raw_frames: seconds since the first message
    for t, direction, frame in raw_frames(file, "scip2", stats):
        view.show(direction, frame, t)
    if stats.dropped_bytes:
        typer.echo(f"robocli: {file}: {stats.frames} blocks decoded, {stats.dropped_bytes} "
                   "bytes dropped", err=True)  # fmt: skip


def _chunks(view: _View, stream: IO[bytes], jsonl: bool) -> Iterator[tuple[float, str, bytes, int]]:
    """``(t, direction, bytes, bytes read)`` of a capture: raw bytes (the sensor's side), or
    the records of a ``.jsonl`` capture (a line that is no record gives no bytes)."""
    if not jsonl:
        while data := stream.read(65536):
            yield 0.0, "rx", data, len(data)
        return
    while raw := stream.readline(MAX_CAPTURE_LINE + 1):
        size = len(raw)
        if not raw.endswith(b"\n") and size > MAX_CAPTURE_LINE:  # too long: skip to its end
            while (more := stream.readline(MAX_CAPTURE_LINE + 1)) and not more.endswith(b"\n"):
                size += len(more)
            size += len(more)
            raw = b""
        rec = _record(raw) if raw else None
        if rec is not None and rec[1] == "start":  # {"event": "start", "unix_time": ...}
            view.offset = rec[0]
            rec = None
        yield (*rec, size) if rec is not None else (0.0, "rx", b"", size)


def _record(raw: bytes) -> tuple[float, str, bytes] | None:
    try:
        obj = json.loads(raw)
        if obj.get("event") == "start":
            return float(obj["unix_time"]), "start", b""
        data = bytes.fromhex(obj["hex"])
        direction = {"c2s": "tx", "s2c": "rx"}[obj["dir"]]
        return float(obj.get("t", 0.0)), direction, data
    except (ValueError, KeyError, TypeError, AttributeError):
        return None
