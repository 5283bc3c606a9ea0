"""Recordings in MCAP, the format of ROS 2 bags and Foxglove: :class:`Recorder` writes them
(needs ``pip install 'robocli-robots[record]'``), :func:`info` summarises them, :func:`raw_frames`
gives their raw frames back to ``dump --file``, :func:`recover` rewrites one that was cut
short (killed, a full disk) whole.

>>> from robocli.io.record import Recorder               # doctest: +SKIP
>>> with Recorder("run.mcap") as rec:
...     rec.add(robot)                                    # a Pioneer, an Arm, a Hub

See :mod:`robocli.io.record.recorder` (threads, bounds, time), :mod:`.sources` (channels)
and :mod:`.reader`.
"""

from robocli.io.record.hub import pull_hub
from robocli.io.record.mcapfile import BadRecording, TruncatedRecording
from robocli.io.record.reader import ChannelInfo, RecordingInfo, info, raw_frames
from robocli.io.record.recorder import (
    COMPRESSIONS,
    RAW_ENCODING,
    RAW_SCHEMA,
    Recorder,
    RecorderStats,
    RecordingError,
)
from robocli.io.record.recover import RecoverStats, recover

__all__ = [
    "COMPRESSIONS",
    "RAW_ENCODING",
    "RAW_SCHEMA",
    "BadRecording",
    "ChannelInfo",
    "Recorder",
    "RecoverStats",
    "RecorderStats",
    "RecordingError",
    "RecordingInfo",
    "TruncatedRecording",
    "info",
    "pull_hub",
    "raw_frames",
    "recover",
]
