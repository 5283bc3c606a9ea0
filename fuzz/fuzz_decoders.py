"""Fuzz harnesses of the Python decoders (ARCOS, Simple Message, ros4mat, SCIP 2.0).

Every public decoder gets the input; it must return or raise a
:class:`robocli.errors.RobocliError`. Any other exception is a finding (fix the decoder).
The first byte of an input picks options (Simple Message byte order and real size; whether
to repair a length field so that the bytes reach the body declarations).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from robocli.errors import RobocliError
from robocli.protocols import arcos, scip2
from robocli.protocols import ros4mat as r4m
from robocli.protocols import simple_message as sm
from robocli.protocols.scip2 import fast as scip2_fast

SM_COMBOS: list[tuple[sm.ByteOrder, sm.RealSize]] = [("<", 4), (">", 4), ("<", 8), (">", 8)]


def _call(decoder: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
    try:
        decoder(*args, **kwargs)
    except RobocliError:
        pass


def fuzz_arcos(data: bytes) -> None:
    """An ARCOS frame or payload into every ARCOS decoder."""
    _call(arcos.unframe, data)
    payload = data[3:-2] if data[:2] == arcos.SYNC else data
    _call(arcos.decode_command, payload)
    _call(arcos.decode_server, payload)
    for from_client in (True, False):
        for in_session in (True, False):
            _call(arcos.describe, payload, from_client=from_client, in_session=in_session)
    if payload:
        body = payload[1:]
        _call(arcos.decode_body, payload[0], body)
        _call(arcos.decode_sip, body)
        _call(arcos.decode_sip, memoryview(body))
        for parse in (
            arcos.parse_sync_reply,
            arcos.parse_config,
            arcos.parse_io,
            arcos.parse_encoder,
            arcos.parse_battery,
        ):
            _call(parse, body)


def fuzz_simple_message(data: bytes) -> None:
    """Option byte, then a frame; bit 2 of the option repairs the length prefix."""
    if not data:
        return
    opt, frame = data[0], data[1:]
    byteorder, real = SM_COMBOS[opt & 3]
    if opt & 4 and len(frame) >= 4:
        frame = struct.pack(byteorder + "i", len(frame) - 4) + frame[4:]
    _call(sm.decode, frame, byteorder=byteorder, real=real, validate=bool(opt & 8))


def fuzz_ros4mat(data: bytes) -> None:
    """Option byte, then a frame; bit 0 repairs compress_size (and the error/size fields
    that decide the body length) so that the body reaches inflation and the declarations."""
    if not data:
        return
    opt, frame = data[0], bytearray(data[1:])
    if opt & 1 and len(frame) >= r4m.HEADER_SIZE:
        body = len(frame) - r4m.HEADER_SIZE
        frame[14:18] = body.to_bytes(4, "little")
        if body and frame[1] == 0 and frame[6:10] == b"\0\0\0\0":
            frame[6] = 1  # size 0 means no body
    _call(r4m.decode, bytes(frame))
    if opt & 2:
        _call(r4m.inflate, bytes(frame), opt * 16)


def _scan_outcome(decode: Callable[..., scip2.ScanReply], block: bytes, check: bool) -> Any:
    try:
        scan = decode(block, check)
    except RobocliError as exc:
        return exc
    ints = None if scan.intensities is None else scan.intensities.tolist()
    return (scan.echo, scan.timestamp, scan.remaining, scan.ranges.tolist(), ints)


def fuzz_scip2(data: bytes) -> None:
    """Option byte (bit 0: checks off), then a reply block: the C scan decoder and the
    pure-Python one agree (same scan, or both refuse), and every SCIP parser returns or
    raises a robocli error."""
    if not data:
        return
    check, block = not data[0] & 1, data[1:]
    want = _scan_outcome(scip2.decode_scan, block, check)
    got = _scan_outcome(scip2_fast.decode_scan, block, check)
    if isinstance(want, Exception) or isinstance(got, Exception):
        assert isinstance(want, Exception) and isinstance(got, Exception), (block, want, got)
    else:
        assert want == got, block
    _call(scip2.parse_request, block)
    _call(scip2.parse_scan_echo, block[:40])
    try:
        reply = scip2.parse_reply(block, check)
    except RobocliError:
        return
    _call(scip2.parse_info, reply.body, check)
    _call(reply.raise_for_status)


TARGETS: dict[str, tuple[Callable[[bytes], None], tuple[str, ...]]] = {
    "decode-arcos": (fuzz_arcos, ("arcos",)),
    "decode-simple_message": (fuzz_simple_message, ("sm-le", "sm-be")),
    "decode-ros4mat": (fuzz_ros4mat, ("ros4mat",)),
    "decode-scip2": (fuzz_scip2, ("scip2",)),
}


def seed_inputs(name: str, frames: list[bytes]) -> list[bytes]:
    """Golden frames as inputs of a decoder harness (with the option bytes it reads)."""
    if name == "decode-arcos":
        return frames
    if name == "decode-simple_message":
        out = []
        for f in frames:
            big = f[0] == 0  # a big-endian length prefix of a short frame starts with 0
            out += [bytes((opt | big,)) + f for opt in (0, 8)]
            out += [bytes((opt | big | 2,)) + f for opt in (0, 8)]  # float64 reading
        return out
    return [bytes((opt,)) + f for f in frames for opt in (0, 1, 3)]
