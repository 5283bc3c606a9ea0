"""ROS-Industrial Simple Message, declared once with ``construct``.

Facts from ``docs/protocols/simple-message.md`` (REP-I0004, REP-I0006, industrial_core,
abb_driver, motoman_driver) and the frames recorded from the reference C++ library
(``tests/data/simple_message/``). Reimplemented from those facts; no reference code is used.

Wire format (no sync bytes, no checksum, segmentation by byte counting)::

    int32 length | int32 msg_type | int32 comm_type | int32 reply_code | body
    <- prefix -> <----------------- header (12 B) ----------------> <- length - 12 ->

The byte order is not fixed by the protocol: ``"<"`` (ABB, DX100/DX200/YRC1000 MotoROS, the
plain library on x86) or ``">"`` (Fanuc, FS100, the library's ``_bswap`` flavour; every field
is swapped on its own, the length prefix included). Reals are float32, or float64 for the
library's ``FLOAT64`` flavour (ints stay int32). :func:`messages` returns the declarations for
one combination.

Bodies decoded by :data:`SimpleMessageSpec.Frame` are chosen by ``msg_type`` *and* body
length: a header-only frame has body ``None``; a body of the standard size is parsed into a
dict; any other size is kept as raw ``bytes``. Unlike the reference library, which parses
bodies from the end (``ByteArray::unload`` is LIFO, so extra *leading* bytes are silently
ignored), a body of a non-standard size is never guessed at.

JOINT_TRAJ (12) uses the **library layout** (``JointTraj::load``): the points first, the
``int32 size`` last. REP-I0006 puts ``size`` first; :attr:`SimpleMessageSpec.JointTrajRep`
declares that layout, but :attr:`SimpleMessageSpec.Frame` decodes the library layout only.

Values are raw protocol values (radians, metres, seconds are already the protocol's units).

The package holds :mod:`~robocli.protocols.simple_message.constants` (ports, sizes, field
values), :mod:`~robocli.protocols.simple_message.spec` (the ``construct`` declarations,
:func:`messages`) and :mod:`~robocli.protocols.simple_message.codec` (:func:`encode`,
:func:`decode`, :func:`validate_header`). Import from here.
"""

from __future__ import annotations

from robocli.protocols.common import plain
from robocli.protocols.simple_message.codec import SimpleMessage, decode, encode, validate_header
from robocli.protocols.simple_message.constants import (
    HEADER_SIZE,
    MAX_FRAME_SIZE,
    MAX_JOINTS,
    MAX_LENGTH,
    MIN_LENGTH,
    MOTOMAN_PORT_IO,
    MOTOMAN_PORT_MOTION,
    MOTOMAN_PORT_STATE,
    PORT_IO,
    PORT_MOTION,
    PORT_STATE,
    PORT_SYSTEM,
    PREFIX_SIZE,
    UDP_HANDSHAKE,
    CommType,
    MotomanCommand,
    MotomanResult,
    ReplyCode,
    RobotMode,
    SimpleMessageType,
    SpecialSeq,
    TriState,
    ValidFields,
)
from robocli.protocols.simple_message.spec import ByteOrder, RealSize, SimpleMessageSpec, messages

__all__ = [
    "HEADER_SIZE",
    "MAX_FRAME_SIZE",
    "MAX_JOINTS",
    "MAX_LENGTH",
    "MIN_LENGTH",
    "MOTOMAN_PORT_IO",
    "MOTOMAN_PORT_MOTION",
    "MOTOMAN_PORT_STATE",
    "PORT_IO",
    "PORT_MOTION",
    "PORT_STATE",
    "PORT_SYSTEM",
    "PREFIX_SIZE",
    "UDP_HANDSHAKE",
    "ByteOrder",
    "CommType",
    "MotomanCommand",
    "MotomanResult",
    "RealSize",
    "ReplyCode",
    "RobotMode",
    "SimpleMessage",
    "SimpleMessageSpec",
    "SimpleMessageType",
    "SpecialSeq",
    "TriState",
    "ValidFields",
    "decode",
    "encode",
    "messages",
    "plain",
    "validate_header",
]
