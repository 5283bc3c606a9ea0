"""``robocli convert IN.mcap OUT --ros2``: a robocli recording rewritten as a ROS 2 bag.

Every message of a decoded channel is mapped as ``record --ros2`` maps it
(:mod:`robocli.ros2.mapping`, the same code), at the same log time; raw channels become
``robocli_msgs/msg/RawFrame`` (those of older recordings, plain bytes, too), with their
metadata, so that ``dump --file`` and ``--replay`` read the bag as they read the recording.
A channel whose schema has no ROS 2 mapping is left out and counted.

``OUT`` ending in ``.mcap`` is one file (what ``ros2 bag play OUT.mcap`` takes); any other
name is a bag folder as ``ros2 bag record`` makes one: ``OUT/OUT_0.mcap`` and
``OUT/metadata.yaml``. The output is checked before the input is read, written beside its
name and put in place once whole (:mod:`robocli.output`): an existing file is replaced
only with ``overwrite``, an existing folder never, and a failure leaves nothing behind.
"""

from __future__ import annotations

import base64
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robocli._version import __version__
from robocli.errors import RobocliError
from robocli.output import OutputError, check_output, replace_output

log = logging.getLogger("robocli.ros2")

__all__ = ["ConvertStats", "convert"]


@dataclass
class ConvertStats:
    """What :func:`convert` wrote: ROS 2 messages by topic, the input's messages read,
    and those of channels with no ROS 2 mapping (by topic)."""

    path: str
    read: int = 0
    written: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)


def convert(path: str | Path, out: str | Path, *, overwrite: bool = False,
            prefix_frames: bool = False) -> ConvertStats:  # fmt: skip
    """Rewrite the robocli recording at ``path`` as a ROS 2 bag at ``out`` (see the module
    docstring). Raises :class:`~robocli.output.OutputError` for an output it may not
    write, :class:`~robocli.io.record.BadRecording` for an input that is not MCAP,
    :class:`~robocli.errors.RobocliError` for one that is a ROS 2 bag already or a message
    that does not decode, :class:`~robocli.ros2.types.Ros2Unavailable` without rosbags."""
    from robocli.io.record.recover import _check_output
    from robocli.ros2.types import typestore

    typestore()
    src, dst = Path(path), Path(out)
    folder = dst.suffix != ".mcap"
    if folder:
        if dst.exists() or dst.is_symlink():
            raise OutputError(f"{dst} exists: a bag folder is never replaced (name a new one)")
        check_output(dst)  # its parent: there and writable
        bag_file = dst / f"{dst.name}_0.mcap"
    else:
        _check_output(src, dst, overwrite)
        bag_file = dst
    _refuse_bag(src)
    stats = ConvertStats(str(dst))
    if not folder:
        with replace_output(dst, overwrite) as stream:
            document = _write(src, stream, bag_file.name, prefix_frames, stats)
        return stats
    from robocli.ros2.bag import metadata_yaml

    dst.mkdir()
    try:
        with replace_output(bag_file) as stream:
            document = _write(src, stream, bag_file.name, prefix_frames, stats)
        with replace_output(dst / "metadata.yaml", text=True) as text:
            text.write(metadata_yaml(document))
    except BaseException:
        for made in (dst / "metadata.yaml", bag_file):
            made.unlink(missing_ok=True)
        dst.rmdir()
        raise
    return stats


def _refuse_bag(src: Path) -> None:
    from mcap.records import Header

    from robocli.io.record.mcapfile import BadRecording, McapFile

    with McapFile(src) as f:
        header = f.header()
    if not isinstance(header, Header):
        raise BadRecording(f"{src} has no complete header record")
    if header.profile == "ros2":
        raise RobocliError(f"{src} is a ROS 2 bag already")


def _write(src: Path, stream: Any, name: str, prefix_frames: bool,
           stats: ConvertStats) -> dict[str, Any]:  # fmt: skip
    """Map every message of ``src`` into a bag on ``stream``; its metadata document."""
    from mcap.records import Channel, Message, Schema
    from mcap.writer import CompressionType, Writer

    from robocli.io.record.fastwrite import MessageAdder
    from robocli.io.record.links import RAW_ENCODING, RAW_SCHEMA
    from robocli.io.record.reader import iter_messages
    from robocli.ros2.bag import PROFILE, BagChannels

    writer = Writer(stream, chunk_size=4 << 20, compression=CompressionType.ZSTD)
    writer.start(profile=PROFILE, library=f"robocli {__version__} (convert)")
    bag = BagChannels(writer, prefix_frames=prefix_frames)
    add = MessageAdder(writer).add
    sequence: dict[int, int] = {}
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str, dict[str, str], bool]] = {}
    for record in iter_messages(src):
        if isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            schema = schemas.get(record.schema_id, "")
            old_raw = record.message_encoding == RAW_ENCODING
            if old_raw:
                schema = RAW_SCHEMA  # older raw channels: their bytes, mapped as RawFrame
            elif record.message_encoding != "json":
                schema = ""  # not robocli's: left out, counted
            channels[record.id] = (record.topic, schema, dict(record.metadata), old_raw)
        elif isinstance(record, Message) and record.channel_id in channels:
            stats.read += 1
            topic, schema, meta, old_raw = channels[record.channel_id]
            sample = _sample(topic, schema, meta, old_raw, record) if schema else None
            mapped = bag.map(schema, topic, sample, meta) if sample is not None else []
            if not mapped and not bag.mapper.maps(schema):
                stats.skipped[topic] = stats.skipped.get(topic, 0) + 1
            for cid, m in mapped:
                seq = sequence.get(cid, 0)
                sequence[cid] = seq + 1
                add(cid, record.log_time, m.data, m.t_ns or record.publish_time, seq)
                bag.count(m.topic, record.log_time)
                stats.written += 1
    stats.topics = dict(bag.counts)
    bag.finish(name)
    writer.finish()  # type: ignore[no-untyped-call]
    if stats.skipped:
        log.info("convert: no ROS 2 mapping for %s", ", ".join(sorted(stats.skipped)))
    return bag.document(name)


def _sample(topic: str, schema: str, meta: dict[str, str], old_raw: bool,
            record: Any) -> dict[str, Any] | None:  # fmt: skip
    """The JSON message of ``record`` as a dict, or the RawFrame message of an older raw
    channel's bytes."""
    data = record.data
    if old_raw:
        return {"timestamp": _stamp(record.log_time), "link": meta.get("link", ""),
                "protocol": meta.get("protocol", ""), "direction": meta.get("direction", ""),
                "port": meta.get("port", ""), "data": base64.b64encode(data).decode()}  # fmt: skip
    try:
        message = json.loads(data)
    except (ValueError, UnicodeDecodeError, RecursionError):
        raise RobocliError(f"{topic}: a message is not JSON") from None
    return message if isinstance(message, dict) else None


def _stamp(ns: int) -> dict[str, int]:
    sec, nsec = divmod(ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}
