"""A recording as ``robocli info`` shows it, like ``ros2 bag info``: its file, size, times
and a table of its channels, as lines of text (:func:`info_lines`); and as ``record`` says
how far it got (:func:`progress_text`) and what it wrote (:func:`recorded_text`)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from robocli.io.record import Recorder, RecordingInfo
    from robocli.io.record.session import Progress

__all__ = ["info_lines", "progress_text", "recorded_text", "size_text", "when_text"]


def when_text(ns: int) -> str:
    """A time in ns since the epoch as local time and as Unix seconds."""
    try:  # a file's times may be anything: a year past 9999 is shown as its number
        stamp = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(ns // 1_000_000_000))
    except (OverflowError, OSError, ValueError):
        return f"{ns / 1e9:.6f}"
    return f"{stamp}.{ns % 1_000_000_000 // 1000:06d} ({ns / 1e9:.6f})"


def size_text(n: float) -> str:
    """``512 B``, ``1.5 KiB``, ``2.0 MiB``, ``1.1 GiB``."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.1f} GiB"  # pragma: no cover


def info_lines(r: RecordingInfo) -> list[str]:
    """The summary of a recording (:func:`robocli.io.record.info`) as lines of text."""
    out = [f"File:        {r.path}", f"Size:        {size_text(r.size)}"]
    if r.library:
        out.append(f"Written by:  {r.library}")
    if not r.summary:
        cut = " (cut short: everything up to the last complete record was read)" \
            if r.truncated else ""  # fmt: skip
        out.append(f"Summary:     none, the file was scanned{cut}")
        if r.truncated and r.readable_bytes > 8:  # its header at least is whole
            out.append(f"Recover:     robocli recover {r.path}")
    out.append(f"Duration:    {r.duration_s:.3f} s")
    if r.messages:
        out += [f"Start:       {when_text(r.start_ns)}", f"End:         {when_text(r.end_ns)}"]
    out.append(f"Messages:    {r.messages}")
    out.append(f"Chunks:      {r.chunks}" + (f" ({', '.join(r.compression)})" if r.compression
                                              else ""))  # fmt: skip
    out.append(f"Channels:    {len(r.channels)}")
    width = max((len(c.topic) for c in r.channels), default=5)
    swidth = max((len(c.schema or c.encoding) for c in r.channels), default=6)
    out.append(f"  {'topic':<{width}}  {'schema':<{swidth}}  {'count':>8}  {'rate Hz':>9}  "
               f"{'largest gap s':>13}")  # fmt: skip
    for c in r.channels:
        rate = f"{c.rate_hz:9.2f}" if c.rate_hz is not None else f"{'-':>9}"
        out.append(f"  {c.topic:<{width}}  {c.schema or c.encoding:<{swidth}}  {c.count:>8}  "
                   f"{rate}  {c.largest_gap_s:13.3f}")  # fmt: skip
    return out


def progress_text(p: Progress) -> str:
    """A recording under way: messages, bytes written, the message rate, seconds."""
    return f"{p.messages} messages, {size_text(p.size)}, {p.rate:.0f} msg/s, {p.seconds:.0f} s"


def recorded_text(rec: Recorder, seconds: float) -> str:
    """What a closed recording holds: messages, seconds, its file, and what it lost or
    dropped, and why."""
    st = rec.stats
    lost = f", {st.lost} not written (writing failed)" if st.lost else ""
    why = "not written" if rec.error is not None else "the disk was too slow"
    dropped = f", {st.dropped} dropped ({why})" if st.dropped else ""
    return f"recorded {st.messages} messages in {seconds:.1f} s to {rec.path}{lost}{dropped}"
