"""The rmw_zenoh mapping against the golden key expressions and tokens of rmw_zenoh's
design document (docs/design.md: the talker/listener example), the XXH3-128 known answer,
and rosbags' RIHS01 hashes."""

from __future__ import annotations

import pytest

from robocli.errors import InvalidArgument, ProtocolError
from robocli.ros2.rmw import (
    ATTACHMENT_SIZE,
    DEFAULT_QOS,
    LATCHED_QOS,
    SENSOR_QOS,
    Attachment,
    Qos,
    check_cdr,
    dds_type,
    entity_token,
    gid,
    mangle,
    node_token,
    parse_qos,
    parse_token,
    qualified,
    topic_key,
)

pytest.importorskip("rosbags", reason="needs robocli-robots[ros2] (rosbags)")
pytest.importorskip("xxhash", reason="needs robocli-robots[ros2] (xxhash)")

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
# rmw_zenoh docs/design.md, "Topic and Service name mapping" and "Graph Cache"
DESIGN_KEY = f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
DESIGN_LISTENER_NN = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
DESIGN_TALKER_MP = (
    "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
    f"std_msgs::msg::dds_::String_/{STRING_HASH}/::,7:,:,:,,"
)
DESIGN_LISTENER_MS = (
    "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
    f"std_msgs::msg::dds_::String_/{STRING_HASH}/::,10:,:,:,,"
)


def test_the_topic_key_is_the_design_documents() -> None:
    assert topic_key(0, "/chatter", "std_msgs/msg/String", STRING_HASH) == DESIGN_KEY
    # a namespace stays as inner slashes of the key (not mangled), one leading '/' dropped
    assert topic_key(3, "/robot1/chatter", "std_msgs/msg/String", STRING_HASH) == (
        f"3/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )


def test_the_node_and_entity_tokens_are_the_design_documents() -> None:
    zid_l, zid_t = "aac3178e146ba6f1fc6e6a4085e77f21", "8b20917502ee955ac4476e0266340d5c"
    assert node_token(0, zid_l, 0, "/", "listener") == DESIGN_LISTENER_NN
    assert node_token(0, zid_l, 0, "", "listener") == DESIGN_LISTENER_NN
    assert (
        entity_token(
            0,
            zid_t,
            0,
            10,
            "MP",
            "/",
            "talker",
            "/chatter",
            "std_msgs/msg/String",
            STRING_HASH,
            Qos(depth=7),
        )
        == DESIGN_TALKER_MP
    )
    assert (
        entity_token(
            0,
            zid_l,
            0,
            10,
            "MS",
            "",
            "listener",
            "/chatter",
            "std_msgs/msg/String",
            STRING_HASH,
            DEFAULT_QOS,
        )
        == DESIGN_LISTENER_MS
    )


def test_names_are_mangled_and_a_namespace_is_one_chunk() -> None:
    assert mangle("") == "%" and mangle("/a/b") == "%a%b"
    token = entity_token(
        7,
        "ab",
        2,
        5,
        "MP",
        "/lab/p1",
        "p1",
        "/lab/p1/cmd_vel",
        "geometry_msgs/msg/Twist",
        STRING_HASH,
        DEFAULT_QOS,
    )
    assert token.split("/")[7:10] == ["%lab%p1", "p1", "%lab%p1%cmd_vel"]
    parsed = parse_token(token)
    assert (parsed.domain, parsed.namespace, parsed.topic, parsed.kind) == (
        7,
        "/lab/p1",
        "/lab/p1/cmd_vel",
        "MP",
    )
    assert parsed.dds_type == "geometry_msgs::msg::dds_::Twist_"
    assert parse_token(DESIGN_TALKER_MP).qos == Qos(depth=7)
    assert parse_token(DESIGN_LISTENER_NN).topic is None
    assert qualified("/lab", "cmd_vel") == "/lab/cmd_vel" and qualified("", "tf") == "/tf"
    assert qualified("/lab", "/tf") == "/tf"


@pytest.mark.parametrize(
    "bad",
    [
        "@ros2_lv/0/z/0/0/XX/%/%/n",
        "robocli/a/@alive/hub",
        "@ros2_lv/x/z/0/0/NN/%/%/n",
        DESIGN_TALKER_MP + "/extra",
        DESIGN_TALKER_MP.replace("::,7:", "::7:"),
    ],
)
def test_a_key_that_is_no_token_is_a_protocol_error(bad: str) -> None:
    with pytest.raises(ProtocolError):
        parse_token(bad)


def test_qos_is_written_relative_to_rmw_zenohs_defaults() -> None:
    assert Qos().chunk() == "::,:,:,:,,"  # every field rmw_zenoh's default
    assert SENSOR_QOS.chunk() == "2::,5:,:,:,,"  # best effort, depth 5
    assert LATCHED_QOS.chunk() == ":1:,1:,:,:,,"  # transient local, depth 1
    odd = Qos(history=2, deadline=(1, 500), lifespan=(0, 7), liveliness=3, lease=(2, 0))
    assert odd.chunk() == "::2,:1,500:0,7:3,2,0"
    for qos in (Qos(), SENSOR_QOS, LATCHED_QOS, odd):
        assert parse_qos(qos.chunk()) == qos
    with pytest.raises(ProtocolError):
        parse_qos("1:2")


def test_the_type_names_and_hashes() -> None:
    from robocli.ros2.types import type_hash

    assert dds_type("geometry_msgs/msg/Twist") == "geometry_msgs::msg::dds_::Twist_"
    assert type_hash("std_msgs/msg/String") == STRING_HASH  # the design document's
    with pytest.raises(InvalidArgument):
        dds_type("Twist")
    with pytest.raises(InvalidArgument):
        topic_key(0, "/t", "std_msgs/msg/String", "RIHS01_xyz")
    with pytest.raises(InvalidArgument):
        topic_key(233, "/t", "std_msgs/msg/String", STRING_HASH)


def test_the_gid_is_the_xxh3_128_of_the_token_low_half_first() -> None:
    # XXH3-128 of no bytes is 99aa06d3014798d8 6001c324468d497f (high, low): the known
    # answer of the xxHash reference; rmw_zenoh copies low64 then high64 from memory (LE)
    assert gid("").hex() == "7f498d4624c30160d8984701d306aa99"
    assert len(gid(DESIGN_TALKER_MP)) == 16 and gid(DESIGN_TALKER_MP) != gid(DESIGN_LISTENER_MS)


def test_the_attachment_is_33_bytes_and_anything_else_is_refused() -> None:
    g = bytes(range(16))
    raw = Attachment(1, 1_700_000_000_123_456_789, g).encode()
    assert len(raw) == ATTACHMENT_SIZE
    assert raw[:8] == (1).to_bytes(8, "little") and raw[16] == 0x10 and raw[17:] == g
    assert raw[8:16] == (1_700_000_000_123_456_789).to_bytes(8, "little")
    assert Attachment.decode(raw) == Attachment(1, 1_700_000_000_123_456_789, g)
    for bad in (None, b"", raw[:-1], raw + b"\0", raw[:16] + b"\x08" + raw[17:]):
        with pytest.raises(ProtocolError):
            Attachment.decode(bad)


def test_a_payload_must_be_cdr_within_the_limit() -> None:
    assert check_cdr(b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00", 64)
    for bad in (b"", b"{}", b"\x01\x01\x00\x00", b"\x00\x01\x00\x00" + bytes(100)):
        with pytest.raises(ProtocolError):
            check_cdr(bad, 64)
