"""SCIP 2.0 protocol layer (pure Python): checksums, encodings, requests, replies, scans and
the reply framer, against the examples of docs/protocols/scip2.md byte for byte."""

from __future__ import annotations

import hashlib

import pytest

from robocli.errors import ChecksumError, FramingError, InvalidArgument, ProtocolError
from robocli.protocols import scip2

G1 = (
    b"VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\nPROD:SOKUIKI Sensor URG-04LX;[\n"
    b"FIRM:3.1.00(18/Jan./2007);`\nPROT:SCIP 2.0;N\nSERI:H0614967;V\n\n"
)
G2 = (
    b"PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\nDMAX:5600;_\n"
    b"ARES:1024;\\\nAMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n"
)
II = (
    b"II\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nLASR:OFF;7\n"
    b"SCSP:Initial(600[rpm])<-Default setting by user;A\nMESM:IDLE;:\n"
    b"SBPS:19200[bps]<-Default setting by user;A\nTIME:081615;N\nSTAT:Sensor works well.;8\n\n"
)
G8 = b"GD0384038601\n00P\n00?Xg\n0?X1Dh000d\n\n"
G11_ACK = b"ME0384038501001\n00P\n\n"
G11_FRAME = b"ME0384038501000\n99b\n00O@_\n0?X04\\0O@0nPd\n\n"
G12_SHA = "8769aee0ebc13fcfcbd02b2f4258d679cf9b21a6d33e992918d6c64a722a1b81"
G13_SHA = "ece4c0ef47c5fe61e72cf0ed438a7531a6d4caa48aa52403018527ef3b096482"
G12_RANGES = [1000 + s for s in range(44, 726)]


def brief_frame(echo: str, status: str, ts: int, values: list[int], n: int = 3) -> bytes:
    """The brief's generator (section 7), kept independent of the package's encoders."""

    def cs(b: bytes) -> bytes:
        return bytes([(sum(b) & 0x3F) + 0x30])

    def enc(v: int, k: int) -> bytes:
        return bytes([((v >> (6 * (k - 1 - i))) & 0x3F) + 0x30 for i in range(k)])

    payload = b"".join(enc(v, n) for v in values)
    blocks = b"".join(
        payload[i : i + 64] + cs(payload[i : i + 64]) + b"\n" for i in range(0, len(payload), 64)
    )
    t = enc(ts, 4)
    return (
        echo.encode()
        + b"\n"
        + status.encode()
        + cs(status.encode())
        + b"\n"
        + t
        + cs(t)
        + b"\n"
        + blocks
        + b"\n"
    )


G12 = brief_frame("GD0044072501", "00", 1000, G12_RANGES)
G13 = b"MD0044072501001\n00P\n\n" + brief_frame("MD0044072501000", "99", 1100, G12_RANGES)


def test_brief_generator_matches_the_published_hashes() -> None:
    assert hashlib.sha256(G12).hexdigest() == G12_SHA and len(G12) == 2134
    assert hashlib.sha256(G13).hexdigest() == G13_SHA and len(G13) == 2158


# ------------------------------------------------------------------ checksum, encodings


@pytest.mark.parametrize(
    ("text", "char"),
    [(b"00", b"P"), (b"99", b"b"), (b"0E", b"e"), (b"10", b"Q"), (b"02", b"R"),
     (b"00?X", b"g"), (b"00A<", b"M"), (b"DMIN:20", b"4"), (b"SCAN:600", b"e")],
)  # fmt: skip
def test_checksum_examples(text: bytes, char: bytes) -> None:
    assert scip2.sum_char(text) == char
    assert scip2.checksum(text) == char[0]


@pytest.mark.parametrize(
    ("value", "width", "chars"),
    [(1234, 2, b"CB"), (5432, 3, b"1Dh"), (16000000, 4, b"m2@0"), (0xFFFFFF, 4, b"oooo"),
     (20, 3, b"00D"), (4095, 2, b"oo"), (1000, 3, b"0?X"), (1100, 4, b"00A<"), (1000, 4, b"00?X")],
)  # fmt: skip
def test_encoding_examples(value: int, width: int, chars: bytes) -> None:
    assert scip2.encode_value(value, width) == chars
    assert scip2.decode_value(chars) == value
    assert scip2.Enc2.build(1234) == b"CB" and scip2.Enc4.parse(b"m2@0") == 16000000


def test_encoding_limits() -> None:
    with pytest.raises(ValueError):
        scip2.encode_value(4096, 2)
    with pytest.raises(ValueError):
        scip2.encode_value(-1, 3)
    with pytest.raises(FramingError):
        scip2.decode_value(b"0p0")  # 'p' = 0x70 is past 'o'
    with pytest.raises(FramingError):
        scip2.decode_values(b"0?X0", 3)


def test_construct_lines() -> None:
    assert scip2.TimestampLine.build(1000) == b"00?Xg\n"
    assert scip2.TimestampLine.parse(b"4SAF>\n") == 0x123456
    assert scip2.StatusLine.build("99") == b"99b\n"
    with pytest.raises(ChecksumError):
        scip2.StatusLine.parse(b"00Q\n")


# ------------------------------------------------------------------ requests


@pytest.mark.parametrize(
    ("command", "params", "tag", "line"),
    [("VV", {}, None, b"VV\n"), ("PP", {}, None, b"PP\n"), ("II", {}, None, b"II\n"),
     ("BM", {}, "abc", b"BM;abc\n"), ("QT", {}, None, b"QT\n"), ("RS", {}, None, b"RS\n"),
     ("RB", {}, None, b"RB\n"), ("TM", {"code": 1}, None, b"TM1\n"),
     ("SS", {"bitrate": 115200}, None, b"SS115200\n"), ("CR", {"speed": 99}, None, b"CR99\n"),
     ("HS", {"mode": 1}, None, b"HS1\n"),
     ("GD", {"start": 44, "end": 725}, None, b"GD0044072501\n"),
     ("GS", {"start": 384, "end": 386, "cluster": 3}, None, b"GS0384038603\n"),
     ("MD", {"start": 44, "end": 725, "count": 1}, None, b"MD0044072501001\n"),
     ("ME", {"start": 384, "end": 385, "count": 1}, None, b"ME0384038501001\n"),
     ("MS", {"start": 0, "end": 1080, "cluster": 2, "interval": 1}, "x", b"MS0000108002100;x\n"),
     ("SCIP2.0", {}, None, b"SCIP2.0\n"), ("%ST", {}, None, b"%ST\n"),
     ("%SL", {}, "z", b"%SL;z\n")],
)  # fmt: skip
def test_build_and_parse_requests(
    command: str, params: dict[str, int], tag: str | None, line: bytes
) -> None:
    assert scip2.build_request(command, tag=tag, **params) == line
    req = scip2.parse_request(line)
    assert req.error is None and req.command == command and req.tag == tag
    assert req.echo == line[:-1]
    for key, value in params.items():
        assert req.params[key] == value


def test_request_terminators() -> None:
    for end in (b"\n", b"\r", b"\r\n", b""):
        req = scip2.parse_request(b"GD0044072501" + end)
        assert req.error is None and req.echo == b"GD0044072501"


@pytest.mark.parametrize(
    ("line", "status"),
    [(b"XX", "0E"), (b"GD00440725", "0C"), (b"GD004407250101", "0D"), (b"VV1", "0D"),
     (b"GDx044072501", "01"), (b"GD0044x72501", "02"), (b"GD00440725x1", "03"),
     (b"MD0044072501x01", "06"), (b"MD00440725010x1", "07"), (b"TMx", "01"),
     (b"BM;" + b"a" * 17, "0G"), (b"BM;a-b", "0H"), (b"%STX", "0D"), (b"%SX", "0E"),
     (b"%S", "0E")],
)  # fmt: skip
def test_malformed_requests_get_the_sensor_status(line: bytes, status: str) -> None:
    assert scip2.parse_request(line).error == status


def test_bad_request_arguments() -> None:
    with pytest.raises(InvalidArgument):
        scip2.build_request("GD", start=10000, end=1)
    with pytest.raises(InvalidArgument):
        scip2.build_request("ZZ")
    with pytest.raises(InvalidArgument):
        scip2.build_request("BM", tag="no;semicolons")
    with pytest.raises(InvalidArgument):
        scip2.build_request("GD", start=1)


# ------------------------------------------------------------------ replies


def test_vv_pp_ii_replies() -> None:
    vv = scip2.parse_reply(G1).raise_for_status()
    assert scip2.parse_info(vv.body)["SERI"] == "H0614967"
    pp = scip2.parse_info(scip2.parse_reply(G2).body)
    assert pp == {
        "MODL": "URG-04LX(Hokuyo Automatic Co.,Ltd.)", "DMIN": "20", "DMAX": "5600",
        "ARES": "1024", "AMIN": "44", "AMAX": "725", "AFRT": "384", "SCAN": "600",
    }  # fmt: skip
    ii = scip2.parse_info(scip2.parse_reply(II).body)
    assert ii["SCSP"] == "Initial(600[rpm])<-Default setting by user" and ii["TIME"] == "081615"
    # the simulator side builds the same bytes
    assert scip2.build_reply(b"PP", "00", scip2.build_info(pp)) == G2
    assert scip2.build_reply(b"VV", "00", scip2.build_info(scip2.parse_info(vv.body))) == G1


def test_info_checksum_variants() -> None:
    # urg_library's alternative coverage (';' included) and a UTM '<-' tail left out
    incl = b"DMIN:20;" + scip2.sum_char(b"DMIN:20;")
    cut = b"SCSP:Initial(2400[rpm])<-Default;" + scip2.sum_char(b"SCSP:Initial(2400[rpm])")
    assert scip2.parse_info([incl, cut]) == {
        "DMIN": "20",
        "SCSP": "Initial(2400[rpm])<-Default",
    }
    bad = b"SERI:H0614967;W"
    with pytest.raises(ChecksumError):
        scip2.parse_info([bad])
    assert scip2.parse_info([bad, b"odd line"], check=False) == {"SERI": "H0614967"}
    with pytest.raises(ProtocolError):
        scip2.parse_info([b"odd line"])


@pytest.mark.parametrize(
    ("block", "status", "ok"),
    [(b"BM\n00P\n\n", "00", True), (b"BM\n02R\n\n", "02", True), (b"BM;abc\n00P\n\n", "00", True),
     (b"QT\n00P\n\n", "00", True), (b"GD0044072501\n10Q\n\n", "10", False),
     (b"XX\n0Ee\n\n", "0E", False), (b"TM0\n00P\n\n", "00", True), (b"SCIP2.0\n0\n\n", "0", True),
     (b"RB\n01Q\n\n", "01", True)],
)  # fmt: skip
def test_status_replies(block: bytes, status: str, ok: bool) -> None:
    reply = scip2.parse_reply(block)
    assert reply.status == status and reply.ok is ok
    if not ok:
        with pytest.raises(scip2.ScipStatusError) as info:
            reply.raise_for_status()
        assert info.value.status == status and status in str(info.value)
    assert scip2.build_reply(reply.echo, status) == block


def test_status_texts() -> None:
    assert scip2.status_text("GD", "10") == "denied: laser off or not allowed in this state"
    assert scip2.status_text("MD", "07") == "scan count not a number"
    assert scip2.status_text("BM", "01") == "laser malfunction"
    assert scip2.status_text("MD", "55") == "hardware trouble"
    err = scip2.ScipStatusError("GD", "10")
    assert err.code == 10 and err.exit_code == 4
    assert scip2.ScipStatusError("XX", "0E").code is None


def test_tm1_reply() -> None:
    reply = scip2.parse_reply(b"TM1\n00P\n4SAF>\n\n")
    assert scip2.decode_value(scip2.check_line(reply.body[0])) == 0x123456


@pytest.mark.parametrize(
    "block",
    [b"BM\n00P\n", b"BM\n00P", b"BM\n\n", b"BM\n0\x01P\n\n", b"BM\n00\n\n", b"BM\n00P\n\nxx"],
)
def test_bad_reply_framing(block: bytes) -> None:
    with pytest.raises(FramingError):
        scip2.parse_reply(block)


def test_bad_status_checksum() -> None:
    with pytest.raises(ChecksumError):
        scip2.parse_reply(b"BM\n00Q\n\n")
    assert scip2.parse_reply(b"BM\n00Q\n\n", check=False).status == "00"


# ------------------------------------------------------------------ scans


def test_gd_three_char_scan() -> None:
    scan = scip2.decode_scan(G8)
    assert (scan.command, scan.status, scan.timestamp) == ("GD", "00", 1000)
    assert (scan.start, scan.end, scan.cluster, scan.remaining) == (384, 386, 1, None)
    assert scan.ranges.tolist() == [1000, 5432, 0] and scan.intensities is None
    assert scip2.build_scan(b"GD0384038601", "00", 1000, [1000, 5432, 0]) == G8


def test_g12_and_g13() -> None:
    scan = scip2.decode_scan(G12)
    assert scan.ranges.tolist() == G12_RANGES and scan.timestamp == 1000
    assert (
        G12.split(b"\n")[3] == b"0@D0@E" + G12.split(b"\n")[3][6:]
        and G12.split(b"\n")[3][-1:] == b"6"
    )
    assert scip2.build_scan(b"GD0044072501", "00", 1000, G12_RANGES) == G12
    blocks = scip2.ReplyFramer().feed(G13)
    assert len(blocks) == 2
    with pytest.raises(ProtocolError):
        scip2.decode_scan(blocks[0])  # the acknowledgement carries no scan
    frame = scip2.decode_scan(blocks[1])
    assert frame.remaining == 0 and frame.timestamp == 1100 and frame.ranges.tolist() == G12_RANGES


def test_me_with_intensity() -> None:
    ack, frame = scip2.ReplyFramer().feed(G11_ACK + G11_FRAME)
    assert scip2.parse_reply(ack).ok
    scan = scip2.decode_scan(frame)
    assert scan.timestamp == 2000 and scan.remaining == 0
    assert scan.ranges.tolist() == [1000, 2000]
    assert scan.intensities is not None and scan.intensities.tolist() == [300, 4000]
    assert scip2.build_scan(b"ME0384038501000", "99", 2000, [1000, 2000], [300, 4000]) == G11_FRAME


def test_two_char_scan_with_clusters() -> None:
    ranges = [5, 4095, 1234, 0, 77]
    block = scip2.build_scan(b"GS0000000902", "00", 0xFFFFFF, ranges, width=2)
    scan = scip2.decode_scan(block)
    assert scan.ranges.tolist() == ranges and scan.cluster == 2 and scan.timestamp == 0xFFFFFF


def test_scan_errors() -> None:
    with pytest.raises(scip2.ScipStatusError):
        scip2.decode_scan(b"GD0044072501\n10Q\n\n")
    with pytest.raises(ChecksumError):
        scip2.decode_scan(G8.replace(b"000d", b"000e"))
    with pytest.raises(ChecksumError):
        scip2.decode_scan(G8.replace(b"00?Xg", b"00?Xh"))
    # one value short: the block is truncated
    with pytest.raises(FramingError):
        scip2.decode_scan(scip2.build_scan(b"GD0384038601", "00", 1000, [1000, 5432]))
    # a data line cut short in the middle of a block
    lines = G12.split(b"\n")
    lines[5] = lines[5][:30] + scip2.sum_char(lines[5][:30])
    with pytest.raises(FramingError):
        scip2.decode_scan(b"\n".join(lines))
    with pytest.raises(ProtocolError):
        scip2.decode_scan(b"VV\n00P\n\n")
    # without checks the sums are not looked at
    assert scip2.decode_scan(G8.replace(b"000d", b"000e"), check=False).ranges.tolist()[2] == 0


# ------------------------------------------------------------------ framer


def test_framer_any_chunking() -> None:
    stream = G1 + G2 + G8 + G11_ACK + G11_FRAME + G12 + G13 + b"SCIP2.0\n0\n\n"
    whole = scip2.ReplyFramer().feed(stream)
    assert len(whole) == 9
    for size in (1, 2, 3, 7, 64, 1000):
        f = scip2.ReplyFramer()
        got = []
        for i in range(0, len(stream), size):
            got += f.feed(stream[i : i + size])
        assert got == whole and f.stats.dropped_bytes == 0 and f.pending == 0


def test_framer_crlf_and_empty_lines() -> None:
    f = scip2.ReplyFramer()
    blocks = f.feed(b"\n\r\nBM\r\n00P\r\n\r\n")
    assert blocks == [b"BM\r\n00P\r\n\r\n"]
    assert scip2.parse_reply(blocks[0]).status == "00"
    assert f.stats.dropped_bytes == 3


def test_framer_resyncs_on_garbage() -> None:
    f = scip2.ReplyFramer()
    junk = b"\x00\xffnoise\n" + G12[500:900] + b"\n"  # binary bytes, then a torn frame's tail
    blocks = f.feed(junk + G8 + b"QT\n00Q\n\n" + G8)
    assert blocks == [G8, G8]
    st = f.stats
    assert st.frames == 2 and st.bad_checksums == 1
    assert st.dropped_bytes == len(junk) + len(b"QT\n00Q\n\n")


def test_framer_bounds_a_runaway_block() -> None:
    f = scip2.ReplyFramer(max_block=256)
    assert f.feed(b"MD0044072501000\n99b\n" + b"0" * 64 + b"0\n" * 1) == []
    f.feed((b"0" * 64 + b"0\n") * 10)
    assert f.pending <= 256 + 66 and f.stats.bad_lengths >= 1
    assert f.feed(G8) == [G8]


def test_scan_echo_fields() -> None:
    echo = scip2.parse_scan_echo(bytearray(b"MS0010002003110;t1"))
    assert (echo.command, echo.start, echo.end, echo.cluster) == ("MS", 10, 20, 3)
    assert (echo.interval, echo.remaining, echo.tag) == (1, 10, "t1")
    assert (echo.count, echo.width, echo.intensity) == (4, 2, False)
    assert scip2.parse_scan_echo(b"GE0000000000").count == 1  # cluster 00 means 1
    for bad in (b"VV", b"GD00440725", b"GD0725004401"):
        with pytest.raises(ProtocolError):
            scip2.parse_scan_echo(bad)
