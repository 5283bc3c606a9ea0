"""The recorder's one-step message writer (:mod:`robocli.io.record.fastwrite`) writes the
same bytes as the mcap package's own ``Writer.add_message``: records, chunk boundaries,
message indexes, statistics and summary, byte for byte."""

from __future__ import annotations

import io
import random

import pytest

pytest.importorskip("mcap")

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from robocli.io.record.fastwrite import MessageAdder


def _file(fast: bool, compression: CompressionType) -> bytes:
    out = io.BytesIO()
    writer = Writer(out, chunk_size=4096, compression=compression)
    writer.start(profile="", library="test")
    schema = writer.register_schema("s", "jsonschema", b"{}")
    channels = [writer.register_channel(f"/c{i}", "json", schema) for i in range(3)]
    adder = MessageAdder(writer)
    assert adder.fast
    add = adder.add if fast else writer.add_message
    rng = random.Random(7)
    t = 1_795_000_000_000_000_000
    for seq in range(3000):
        t += rng.randrange(-5_000, 2_000_000)  # now and then a step back in time
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 300)))
        add(channels[seq % 3], t, data, t - 1000, seq)
        if seq == 1500:
            writer.flush()  # a chunk closed early, as the recorder does every second
    writer.finish()
    return out.getvalue()


@pytest.mark.parametrize("compression", [CompressionType.NONE, CompressionType.ZSTD])
def test_the_same_bytes_as_the_mcap_writer(compression: CompressionType) -> None:
    theirs, ours = _file(False, compression), _file(True, compression)
    assert ours == theirs
    summary = make_reader(io.BytesIO(ours)).get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == 3000 and len(summary.chunk_indexes) > 10
    read = list(make_reader(io.BytesIO(ours)).iter_messages(log_time_order=False))
    assert [m.sequence for _, _, m in read] == list(range(3000))


def _states(as_dict: bool) -> list[bytes]:
    """The state messages of a recorded session's SIPs (trace b), as the writer makes them
    (text) or through the dict and ``json`` (``as_dict``, what it did before)."""
    from pathlib import Path

    from robocli.io.capture import read_capture
    from robocli.io.record import Recorder
    from robocli.io.record.pioneer import PioneerDecoder
    from robocli.robots.pioneer import ROBOT_PARAMS

    trace = Path(__file__).resolve().parents[1] / "data/arcos/b_simpleMotionCommands.jsonl"
    out = io.BytesIO()
    rec = Recorder(out, compression="none")
    rec._epoch_ns = 1_795_000_000_000_000_000
    link = rec.listener("pioneer", "arcos")
    decoder = PioneerDecoder(rec, "pioneer", ROBOT_PARAMS["p3dx"])
    if as_dict:
        import json

        from robocli.io.record.links import json_text

        def state(st: object, stamp: str, sonar: list[float]) -> bytes:
            return json_text(decoder._state_dict(st, json.loads(stamp), sonar)).encode()

        decoder._state = state  # type: ignore[method-assign]
    link.decoder = decoder
    for i, f in enumerate(read_capture(trace)):
        if f.direction == "rx" and f.frame[3] & 0xF0 == 0x30:
            link("rx", f.frame[3:-2], 1000.0 + i * 0.1)
    rec.close()
    reader = make_reader(io.BytesIO(out.getvalue()))
    return [m.data for _, c, m in reader.iter_messages() if c.topic == "/pioneer/state"]


def test_the_state_text_is_the_json_of_its_dict() -> None:
    """The state message is written as text (a SIP's largest message): the same bytes as
    the dict through ``json`` was, for every SIP of a recorded session."""
    text, through_json = _states(False), _states(True)
    assert len(text) > 100 and text == through_json
