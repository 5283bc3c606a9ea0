"""Hokuyo SCIP 2.0: the ASCII line protocol of URG-04LX, UTM-30LX and UST-10LX/20LX scanners.

Facts from ``docs/protocols/scip2.md`` (SPEC C-42-03320B, the URG Network wiki, urg_library,
hokuyo_node, hokuyolx, urg_stamped). This package knows bytes and field meanings only; the
client and the simulator are built on it.

Wire format::

    request   <symbol><fixed-width decimal params>[;tag]LF      (GD0044072501, MD0044072501001)
    reply     <echo>LF <status 2 chars><sum>LF [<line><sum>LF]* LF
    sum       (sum of the covered bytes & 0x3F) + 0x30          ("00" -> 'P', "99" -> 'b')
    values    2/3/4 chars of 6 bits each, + 0x30, most significant first
    data      the value stream cut into lines of 64 chars + sum; values straddle lines

Modules: :mod:`~robocli.protocols.scip2.wire` (sum, encodings, data lines, statuses,
:class:`ScipStatusError`), :mod:`~robocli.protocols.scip2.commands` (requests declared with
``construct``, built and parsed), :mod:`~robocli.protocols.scip2.replies` (reply blocks,
VV/PP/II bodies, scans; building them for a simulator), :mod:`~robocli.protocols.scip2.framing`
(the pure-Python reply framer) and :mod:`~robocli.protocols.scip2.fast` (the C framer and scan
decoder; same results, same errors).

Choices where the sources disagree:

* Info lines (``KEY:value;S``): the sum is checked over ``KEY:value`` (WIKI, hokuyolx, every
  published example); ``KEY:value;`` (urg_library's alternative) and, for UTM-30LX, the line
  cut before a ``<-`` comment are accepted too. ``parse_info(check=False)`` keeps lines with
  wrong sums (URG-04LX VV SERI quirk); unknown keys are kept.
* Data lines: every sum is checked by default (urg_library ignores them by default);
  ``check=False`` is the opt-out. A non-last data line of other than 64 chars, or a value
  count that does not match the echo's start/end/cluster, is a truncated block
  (:class:`~robocli.errors.FramingError`); a wrong sum is a
  :class:`~robocli.errors.ChecksumError`.
* Status: success is ``00`` (``99`` for M-type frames; BM also ``02`` "already on", RB also
  ``01`` "armed" as urg_library does); anything else raises :class:`ScipStatusError` with the
  2-char code and the meaning from :data:`STATUS_TEXT` / :data:`COMMAND_STATUS`. The
  URG-04LX and UST/UTM tables disagree on ``0C``..``0H``: the texts give both readings. A
  ``0M`` ("unstable") frame is not decoded (hokuyolx decodes it with a warning).
* Malformed requests (simulator side, :func:`parse_request`): ``0E`` unknown command, ``0C`` /
  ``0D`` parameters too short / too long (urg_stamped), ``0G`` / ``0H`` bad tag, ``01``..``03``,
  ``06``, ``07`` a non-numeric start, end, cluster, interval, count.
* Line ends: replies are read to LF; a CR just before an LF is tolerated (urg_library ends a
  line at CR too; sensors send LF only). Requests are built with LF only.
* A 1-char status line (SCIP 1.1, and the ``SCIP2.0`` switch's bare ``0``) carries no sum.
* Multi-echo (HD/HE/ND/NE, ``&`` prefixes) requests are built and parsed, but their scans are
  not decoded.
"""

from __future__ import annotations

from robocli.protocols.scip2.commands import (
    PARAMS,
    SCAN_COMMANDS,
    SCIP20,
    Request,
    ScanEcho,
    build_request,
    parse_request,
    parse_scan_echo,
)
from robocli.protocols.scip2.framing import ReplyFramer, ReplyFramerStats
from robocli.protocols.scip2.replies import (
    Reply,
    ScanReply,
    build_info,
    build_reply,
    build_scan,
    decode_scan,
    parse_info,
    parse_reply,
    scan_header,
    split_lines,
)
from robocli.protocols.scip2.wire import (
    BLOCK_CHARS,
    COMMAND_STATUS,
    MAX_BLOCK,
    MAX_ECHO,
    MAX_LINE,
    MAX_TAG,
    STATUS_TEXT,
    SUCCESS,
    TIMESTAMP_WRAP,
    Enc2,
    Enc3,
    Enc4,
    ScipStatusError,
    StatusLine,
    TimestampLine,
    check_line,
    checksum,
    data_lines,
    decode_value,
    decode_values,
    encode_value,
    encode_values,
    is_success,
    join_data_lines,
    status_text,
    strip_eol,
    sum_char,
    with_sum,
)

__all__ = [
    "BLOCK_CHARS",
    "COMMAND_STATUS",
    "MAX_BLOCK",
    "MAX_ECHO",
    "MAX_LINE",
    "MAX_TAG",
    "PARAMS",
    "SCAN_COMMANDS",
    "SCIP20",
    "STATUS_TEXT",
    "SUCCESS",
    "TIMESTAMP_WRAP",
    "Enc2",
    "Enc3",
    "Enc4",
    "Reply",
    "ReplyFramer",
    "ReplyFramerStats",
    "Request",
    "ScanEcho",
    "ScanReply",
    "ScipStatusError",
    "StatusLine",
    "TimestampLine",
    "build_info",
    "build_reply",
    "build_request",
    "build_scan",
    "check_line",
    "checksum",
    "data_lines",
    "decode_scan",
    "decode_value",
    "decode_values",
    "encode_value",
    "encode_values",
    "is_success",
    "join_data_lines",
    "parse_info",
    "parse_reply",
    "parse_request",
    "parse_scan_echo",
    "scan_header",
    "split_lines",
    "status_text",
    "strip_eol",
    "sum_char",
    "with_sum",
]
