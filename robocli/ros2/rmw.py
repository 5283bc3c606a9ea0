"""How ROS 2's Zenoh middleware (``rmw_zenoh_cpp``) lays ROS 2 topics on Zenoh: key
expressions, graph liveliness tokens, QoS chunks, entity GIDs and sample attachments.

Reimplemented from the facts of ros2/rmw_zenoh (Apache-2.0): ``docs/design.md`` and
``rmw_zenoh_cpp/src/detail/`` (``liveliness_utils.cpp``, ``qos.cpp``,
``attachment_helpers.cpp``, ``rmw_publisher_data.cpp``, ``simplified_xxhash3.cpp``):

* **Data key** ``<domain>/<topic>/<pkg>::msg::dds_::<Type>_/RIHS01_<sha256 hex>``: the
  fully qualified topic name with one leading and one trailing ``/`` stripped (inner ones
  kept), the DDS type name, the type's RIHS01 hash.
* **Liveliness token** of every graph entity, ``@ros2_lv/<domain>/<zid>/<nid>/<id>/<kind>/
  <enclave>/<namespace>/<node>`` (a node: ``NN``, its id repeated) followed, for a publisher
  ``MP``, subscription ``MS``, service ``SS`` or client ``SC``, by ``/<topic>/<type>/
  <hash>/<qos>``. Every ``/`` inside a name becomes ``%``; an empty name (the root
  namespace, no enclave) is ``%``.
* **QoS chunk** ``<rel>:<dur>:<hist>,<depth>:<dl s>,<dl ns>:<ls s>,<ls ns>:<liv>,<lease s>,
  <lease ns>``, each field empty when it equals rmw_zenoh's default (reliable, volatile, keep
  last, depth 42, infinite durations, automatic liveliness), else the number of the rmw enum.
* **GID** of an entity: XXH3-128 (seed 0, default secret) of its whole liveliness token
  string, stored as the low 64 bits then the high 64 bits, little-endian.
* **Attachment** of every sample, 33 bytes: sequence number (int64 LE, from 1 per
  publisher), source time (int64 LE, ns since the Unix epoch), ``0x10`` (the zenoh-ext
  serializer's LEB128 length of the 16-byte array), the publisher's GID. rmw_zenoh drops a
  sample without one.
* **Payload**: CDR with its 4-byte encapsulation header (``00 01 00 00``: little-endian CDR).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

from robocli.errors import InvalidArgument, ProtocolError

__all__ = [
    "ADMIN_SPACE",
    "ATTACHMENT_SIZE",
    "CDR_LE_HEADER",
    "DEFAULT_QOS",
    "KINDS",
    "LATCHED_QOS",
    "SENSOR_QOS",
    "Attachment",
    "Qos",
    "Token",
    "check_cdr",
    "dds_type",
    "domain_keys",
    "entity_token",
    "gid",
    "mangle",
    "node_token",
    "parse_qos",
    "parse_token",
    "qualified",
    "topic_key",
]

ADMIN_SPACE = "@ros2_lv"
KINDS = ("NN", "MP", "MS", "SS", "SC")
"""A node, a publisher, a subscription, a service server, a service client."""
ATTACHMENT_SIZE = 33
CDR_LE_HEADER = b"\x00\x01\x00\x00"
_ATTACHMENT = struct.Struct("<qqB16s")
_TYPE = re.compile(r"([A-Za-z][A-Za-z0-9_]*)/(msg|srv)/([A-Za-z][A-Za-z0-9_]*)")
_HASH = re.compile(r"RIHS01_[0-9a-f]{64}")
_NAME = re.compile(r"(/?[A-Za-z_~{][A-Za-z0-9_{}]*)*/?")

# rmw's enums (rmw/types.h): 0 is SYSTEM_DEFAULT in each
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2
AUTOMATIC = 1
_INFINITE = (0x7FFFFFFFFFFFFFFF, 0x7FFFFFFFFFFFFFFF)  # RMW_DURATION_INFINITE (s, ns)


@dataclass(frozen=True)
class Qos:
    """The QoS policies a token writes (durations: rmw's (s, ns), infinite by default)."""

    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = 42
    deadline: tuple[int, int] = _INFINITE
    lifespan: tuple[int, int] = _INFINITE
    liveliness: int = AUTOMATIC
    lease: tuple[int, int] = _INFINITE

    def chunk(self) -> str:
        """The token's QoS chunk: each field written only where it is not rmw_zenoh's."""
        d = _RMW_ZENOH_DEFAULT

        def f(value: int, default: int) -> str:
            return "" if value == default else str(value)

        return (
            f"{f(self.reliability, d.reliability)}:{f(self.durability, d.durability)}:"
            f"{f(self.history, d.history)},{f(self.depth, d.depth)}:"
            f"{f(self.deadline[0], d.deadline[0])},{f(self.deadline[1], d.deadline[1])}:"
            f"{f(self.lifespan[0], d.lifespan[0])},{f(self.lifespan[1], d.lifespan[1])}:"
            f"{f(self.liveliness, d.liveliness)},{f(self.lease[0], d.lease[0])},"
            f"{f(self.lease[1], d.lease[1])}"
        )

    @property
    def transient_local(self) -> bool:
        return self.durability == TRANSIENT_LOCAL


_RMW_ZENOH_DEFAULT = Qos()
DEFAULT_QOS = Qos(depth=10)
"""rclcpp's default for a publisher (reliable, volatile, keep last 10)."""
SENSOR_QOS = Qos(reliability=BEST_EFFORT, depth=5)
"""``rclcpp::SensorDataQoS``: best effort, keep last 5."""
LATCHED_QOS = Qos(durability=TRANSIENT_LOCAL, depth=1)
"""What ``robot_state_publisher`` offers on /robot_description and /tf_static."""


def parse_qos(chunk: str) -> Qos:
    """The :class:`Qos` of a token's QoS chunk (empty fields: rmw_zenoh's defaults);
    :class:`ProtocolError` for anything else."""
    parts = chunk.split(":")
    groups = [p.split(",") for p in parts]
    if [len(g) for g in groups] != [1, 1, 2, 2, 2, 3]:
        raise ProtocolError(f"QoS chunk {chunk[:80]!r} is not rmw_zenoh's")
    d = _RMW_ZENOH_DEFAULT

    def num(text: str, default: int) -> int:
        if not text:
            return default
        if not text.isdigit() or len(text) > 20:
            raise ProtocolError(f"QoS chunk {chunk[:80]!r}: {text[:24]!r} is not a number")
        return int(text)

    (rel,), (dur,), (hist, depth), (dl_s, dl_ns), (ls_s, ls_ns), (liv, le_s, le_ns) = groups
    return Qos(
        num(rel, d.reliability), num(dur, d.durability), num(hist, d.history),
        num(depth, d.depth), (num(dl_s, d.deadline[0]), num(dl_ns, d.deadline[1])),
        (num(ls_s, d.lifespan[0]), num(ls_ns, d.lifespan[1])), num(liv, d.liveliness),
        (num(le_s, d.lease[0]), num(le_ns, d.lease[1])),
    )  # fmt: skip


def mangle(name: str) -> str:
    """A name as one key chunk: every ``/`` becomes ``%``; an empty name is ``%``."""
    return name.replace("/", "%") if name else "%"


def dds_type(ros_type: str) -> str:
    """``std_msgs/msg/String`` -> ``std_msgs::msg::dds_::String_``."""
    m = _TYPE.fullmatch(ros_type)
    if m is None:
        raise InvalidArgument(f"ROS 2 type {ros_type!r}: expected PKG/msg/NAME")
    return f"{m[1]}::{m[2]}::dds_::{m[3]}_"


def qualified(namespace: str, name: str) -> str:
    """The fully qualified name of ``name`` in ``namespace`` (``/robot1`` + ``cmd_vel`` ->
    ``/robot1/cmd_vel``; an absolute ``name`` stays as it is)."""
    if not _NAME.fullmatch(namespace) or not name or not _NAME.fullmatch(name):
        raise InvalidArgument(f"ROS 2 name {namespace!r} / {name!r}: letters, digits, '_', '/'")
    if name.startswith("/"):
        return name
    ns = namespace.strip("/")
    return f"/{ns}/{name}" if ns else f"/{name}"


def _check_hash(type_hash: str) -> str:
    if not _HASH.fullmatch(type_hash):
        raise InvalidArgument(f"type hash {type_hash[:80]!r}: expected RIHS01_<64 hex>")
    return type_hash


def topic_key(domain: int, topic: str, ros_type: str, type_hash: str) -> str:
    """``<domain>/<topic>/<dds type>/<hash>``: where a topic's samples are put (``topic``
    fully qualified; one leading and one trailing ``/`` stripped, as rmw_zenoh does)."""
    name = topic[1:] if topic.startswith("/") else topic
    name = name[:-1] if name.endswith("/") else name
    return f"{_domain(domain)}/{name}/{dds_type(ros_type)}/{_check_hash(type_hash)}"


def domain_keys(domain: int) -> str:
    """``@ros2_lv/<domain>/**``: every graph token of a domain (what ROS 2 nodes watch)."""
    return f"{ADMIN_SPACE}/{_domain(domain)}/**"


def _domain(domain: int) -> int:
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
        raise InvalidArgument(f"ROS domain id {domain!r}: 0..232")
    return domain


def node_token(domain: int, zid: str, nid: int, namespace: str, node: str,
               enclave: str = "") -> str:  # fmt: skip
    """The ``NN`` token of node ``node`` in ``namespace`` (``/`` or empty: the root)."""
    ns = "" if namespace.strip("/") == "" else namespace
    return (f"{ADMIN_SPACE}/{_domain(domain)}/{zid}/{nid}/{nid}/NN/{mangle(enclave)}/"
            f"{mangle(ns)}/{mangle(node)}")  # fmt: skip


def entity_token(domain: int, zid: str, nid: int, eid: int, kind: str, namespace: str,
                 node: str, topic: str, ros_type: str, type_hash: str, qos: Qos,
                 enclave: str = "") -> str:  # fmt: skip
    """The token of a publisher (``MP``), subscription (``MS``), service (``SS``) or client
    (``SC``) of node ``node``: the node's chunks, then topic, type, hash and QoS."""
    if kind not in KINDS[1:]:
        raise InvalidArgument(f"entity kind {kind!r}: one of {', '.join(KINDS[1:])}")
    ns = "" if namespace.strip("/") == "" else namespace
    return (f"{ADMIN_SPACE}/{_domain(domain)}/{zid}/{nid}/{eid}/{kind}/{mangle(enclave)}/"
            f"{mangle(ns)}/{mangle(node)}/{mangle(topic)}/{mangle(dds_type(ros_type))}/"
            f"{_check_hash(type_hash)}/{qos.chunk()}")  # fmt: skip


@dataclass(frozen=True)
class Token:
    """A graph token read back (names unmangled: ``%`` -> ``/``; the root namespace ``/``)."""

    domain: int
    zid: str
    nid: str
    eid: str
    kind: str
    enclave: str
    namespace: str
    node: str
    topic: str | None = None
    dds_type: str | None = None
    type_hash: str | None = None
    qos: Qos | None = None


def parse_token(key: str) -> Token:
    """The :class:`Token` of a liveliness key; :class:`ProtocolError` for any other key."""
    parts = str(key).split("/")
    if len(parts) not in (9, 13) or parts[0] != ADMIN_SPACE or parts[5] not in KINDS:
        raise ProtocolError(f"{str(key)[:120]!r} is not an rmw_zenoh graph token")
    if (parts[5] == "NN") != (len(parts) == 9) or not parts[1].isdigit():
        raise ProtocolError(f"{str(key)[:120]!r} is not an rmw_zenoh graph token")

    def name(chunk: str) -> str:
        return chunk.replace("%", "/")

    topic = None if len(parts) == 9 else parts[9:]
    return Token(
        int(parts[1]), parts[2], parts[3], parts[4], parts[5], name(parts[6]),
        name(parts[7]), name(parts[8]),
        *((name(topic[0]), name(topic[1]), topic[2], parse_qos(topic[3])) if topic else ()),
    )  # fmt: skip


def gid(token: str) -> bytes:
    """The 16-byte GID rmw_zenoh gives the entity of ``token``: its XXH3-128, low then high
    64 bits, little-endian."""
    import xxhash

    return int(xxhash.xxh3_128_intdigest(token.encode())).to_bytes(16, "little")


@dataclass(frozen=True)
class Attachment:
    """What rides with every sample: sequence number, source time (ns), publisher GID."""

    seq: int
    t_ns: int
    gid: bytes

    def encode(self) -> bytes:
        """The 33 bytes rmw_zenoh writes (and requires)."""
        if len(self.gid) != 16:
            raise InvalidArgument("a GID is 16 bytes")
        return _ATTACHMENT.pack(self.seq, self.t_ns, 16, self.gid)

    @classmethod
    def decode(cls, raw: bytes | None) -> Attachment:
        """The attachment of a sample; :class:`ProtocolError` when missing or malformed."""
        if raw is None:
            raise ProtocolError("a ROS 2 sample without its attachment")
        if len(raw) != ATTACHMENT_SIZE or raw[16] != 16:
            raise ProtocolError(f"a ROS 2 attachment of {len(raw)} bytes is not rmw_zenoh's")
        seq, t_ns, _, g = _ATTACHMENT.unpack(raw)
        return cls(seq, t_ns, g)


def check_cdr(payload: bytes, limit: int) -> bytes:
    """``payload`` if it is CDR (a little- or big-endian encapsulation header) of at most
    ``limit`` bytes, else :class:`ProtocolError`."""
    if len(payload) > limit:
        raise ProtocolError(f"a ROS 2 message of {len(payload)} bytes (limit {limit})")
    if len(payload) < 4 or payload[:2] not in (b"\x00\x00", b"\x00\x01"):
        raise ProtocolError("a ROS 2 message that is not CDR (no encapsulation header)")
    return payload
