"""Simple Message numbers: the standard ports, the sizes and limits of a frame, and the
values of its fields (message types, comm types, reply codes, special sequences, tri-states,
robot modes, valid-field bits, Motoman commands and results).

Part of :mod:`robocli.protocols.simple_message` (import from there).
"""

from __future__ import annotations

import enum

PORT_MOTION = 11000
"""Trajectory relay (ABB motion server, Fanuc ``ros_relay``, generic downloader/streamer)."""
PORT_SYSTEM = 11001
"""Defined by industrial_core, unused."""
PORT_STATE = 11002
"""State relay (JOINT_POSITION + STATUS from ABB, Fanuc ``ros_state``)."""
PORT_IO = 11003
"""Defined by industrial_core, unused."""
MOTOMAN_PORT_MOTION = 50240
MOTOMAN_PORT_STATE = 50241
MOTOMAN_PORT_IO = 50242

MAX_JOINTS = 10
"""Every joint array has exactly this many elements on the wire (unused ones zero)."""
PREFIX_SIZE = 4
HEADER_SIZE = 12
MIN_LENGTH = HEADER_SIZE
"""Smallest valid ``length`` prefix (a header-only frame)."""
MAX_FRAME_SIZE = 1023
"""Largest whole frame a C++ peer sends (``SimpleSocket`` refuses buffers of 1024 bytes)."""
MAX_LENGTH = MAX_FRAME_SIZE - PREFIX_SIZE
"""Largest ``length`` prefix accepted by :func:`decode` and produced by :func:`encode`."""
UDP_HANDSHAKE = 0x8E
"""Byte exchanged until echoed before framing starts on the (rarely used) UDP variant."""


class SimpleMessageType(enum.IntEnum):
    """Standard message ids (REP-I0004) plus the Motoman ones robocli declares."""

    INVALID = 0
    PING = 1
    GET_VERSION = 2
    JOINT_POSITION = 10
    JOINT = 10  # alias used by industrial_core
    JOINT_TRAJ_PT = 11
    JOINT_TRAJ = 12
    STATUS = 13
    JOINT_TRAJ_PT_FULL = 14
    JOINT_FEEDBACK = 15
    READ_INPUT = 20
    WRITE_OUTPUT = 21
    MOTOMAN_MOTION_CTRL = 2001
    MOTOMAN_MOTION_REPLY = 2002


class CommType(enum.IntEnum):
    INVALID = 0
    TOPIC = 1
    SERVICE_REQUEST = 2
    SERVICE_REPLY = 3


class ReplyCode(enum.IntEnum):
    INVALID = 0
    UNUSED = 0
    SUCCESS = 1
    FAILURE = 2


class SpecialSeq(enum.IntEnum):
    """Special ``sequence`` values of JOINT_TRAJ_PT (N >= 0 is a point index)."""

    START_TRAJECTORY_DOWNLOAD = -1
    START_TRAJECTORY_STREAMING = -2
    END_TRAJECTORY = -3
    STOP_TRAJECTORY = -4


class TriState(enum.IntEnum):
    UNKNOWN = -1
    FALSE = 0
    OFF = 0
    DISABLED = 0
    LOW = 0
    TRUE = 1
    ON = 1
    ENABLED = 1
    HIGH = 1


class RobotMode(enum.IntEnum):
    UNKNOWN = -1
    MANUAL = 1
    AUTO = 2


class ValidFields(enum.IntFlag):
    """``valid_fields`` bits of JOINT_TRAJ_PT_FULL / JOINT_FEEDBACK."""

    TIME = 0x01
    POSITION = 0x02
    VELOCITY = 0x04
    ACCELERATION = 0x08


class MotomanCommand(enum.IntEnum):
    """``command`` of MOTOMAN_MOTION_CTRL (2001)."""

    CHECK_MOTION_READY = 200101
    CHECK_QUEUE_CNT = 200102
    STOP_MOTION = 200111
    START_SERVOS = 200112
    STOP_SERVOS = 200113
    RESET_ALARM = 200114
    START_TRAJ_MODE = 200121
    STOP_TRAJ_MODE = 200122
    DISCONNECT = 200130


class MotomanResult(enum.IntEnum):
    """``result`` of MOTOMAN_MOTION_REPLY (2002)."""

    SUCCESS = 0
    TRUE = 0
    BUSY = 1
    FAILURE = 2
    FALSE = 2
    INVALID = 3
    ALARM = 4
    NOT_READY = 5
    MP_FAILURE = 6
