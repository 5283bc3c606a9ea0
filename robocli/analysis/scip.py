"""Every SCIP line, named and decoded, for a protocol analyser (``robocli dump laser``):
:func:`describe_request` for a request line, :func:`describe_reply` for a reply block (each
line with what it is: echo, status and its meaning, ``KEY:value`` with its sum checked,
timestamp, data lines, and a summary of the decoded scan). Never raises on bad input: what
does not decode is said so."""

from __future__ import annotations

from dataclasses import dataclass

from robocli.errors import RobocliError
from robocli.protocols import scip2

__all__ = ["Line", "describe_reply", "describe_request"]


@dataclass(frozen=True)
class Line:
    """One line on the wire (without its LF) and what it is."""

    text: str
    what: str


def _text(raw: bytes) -> str:
    return raw.decode("ascii", "backslashreplace")


def describe_request(line: bytes) -> Line:
    """A request line (terminator stripped or not)."""
    raw = line.rstrip(b"\r\n")
    req = scip2.parse_request(raw)
    if req.error is not None:
        what = f"{req.command}: malformed (the sensor answers {req.error})"
    elif req.command == "SCIP2.0":
        what = "switch to SCIP 2.0"
    else:
        params = " ".join(f"{k} {v}" for k, v in req.params.items())
        what = f"{req.command} {params}".rstrip() + (f"  tag {req.tag!r}" if req.tag else "")
    return Line(_text(raw), what)


def _sum_ok(line: bytes) -> str:
    return "sum ok" if len(line) > 1 and line[-1] == scip2.checksum(line[:-1]) else "BAD SUM"


def describe_reply(block: bytes) -> list[Line]:
    """The lines of one reply block, each named and decoded, then a summary line."""
    lines = block.split(b"\n")
    while lines and lines[-1] == b"":
        lines.pop()
    if not lines:
        return [Line("", "empty")]
    out = [Line(_text(lines[0]), "echo")]
    command = "SCIP2.0" if lines[0] == scip2.SCIP20 else _text(lines[0][:2])
    if len(lines) < 2:
        return out + [Line("", "no status line: truncated")]
    st = lines[1]
    code = _text(st[:2]) if len(st) == 3 else _text(st)
    meaning = scip2.status_text(command, code) if len(st) == 3 else "SCIP 1.1 / switch status"
    out.append(Line(_text(st), f"status {code}: {meaning}" +
                    (f", {_sum_ok(st)}" if len(st) == 3 else "")))  # fmt: skip
    body = lines[2:]
    scan = command[:1] in ("G", "M") and command in scip2.SCAN_COMMANDS and body
    if scan:
        stamp = body[0]
        try:
            value = scip2.decode_value(stamp[:4])
            out.append(Line(_text(stamp), f"timestamp {value} ms, {_sum_ok(stamp)}"))
        except RobocliError as exc:
            out.append(Line(_text(stamp), f"timestamp: {exc}"))
        for i, line in enumerate(body[1:]):
            out.append(Line(_text(line), f"data {i + 1}/{len(body) - 1}, {len(line) - 1} "
                                         f"chars, {_sum_ok(line)}"))  # fmt: skip
        out.append(Line("", _scan_summary(block)))
        return out
    for line in body:
        if b":" in line and line[-2:-1] == b";":
            key, _, text = line[:-2].partition(b":")
            ok = _info_ok(line)
            out.append(Line(_text(line), f"{_text(key)} = {_text(text)}, "
                                         f"{'sum ok' if ok else 'BAD SUM'}"))  # fmt: skip
        elif len(line) == 5 and command == "TM":
            out.append(Line(_text(line), f"time {scip2.decode_value(line[:4])} ms, "
                                         f"{_sum_ok(line)}"))  # fmt: skip
        else:
            out.append(Line(_text(line), "line"))
    return out


def _info_ok(line: bytes) -> bool:
    try:
        scip2.parse_info([line], check=True)
    except RobocliError:
        return False
    return True


def _scan_summary(block: bytes) -> str:
    try:
        s = scip2.decode_scan(block)
    except RobocliError as exc:
        return f"scan does not decode: {exc}"
    r = s.ranges
    what = f"= {s.command} {len(r)} values, steps {s.start}..{s.end} cluster {s.cluster}"
    if len(r):
        what += f", {int(r.min())}..{int(r.max())} (mm or codes)"
    if s.remaining is not None:
        what += f", {s.remaining} to come"
    return what
