"""``--zenoh [ENDPOINT|CONFIG]``: one meaning for servers (listen) and clients (connect),
the key layout, and the one-line message without the extra."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import typer
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from robocli.commands._zenoh import ZenohCommand, zenoh_option, zenoh_session
from robocli.errors import InvalidArgument, TransportError
from robocli.zenoh import (
    DEFAULT_ENDPOINT,
    alive_key,
    info_key,
    open_session,
    parse_alive,
    parse_target,
    settings_key,
    topic_key,
    zenoh_config,
)
from tests.waiting import wait_for

DEADLINE_S = 20.0


def test_target_is_an_endpoint_or_a_config_file(tmp_path: Path) -> None:
    assert parse_target(None).endpoint == DEFAULT_ENDPOINT == "tcp/127.0.0.1:7447"
    assert parse_target("tcp/10.0.0.1:7447").endpoint == "tcp/10.0.0.1:7447"
    cfg = tmp_path / "lab.json5"
    cfg.write_text("{ mode: 'client' }")
    assert parse_target(str(cfg)).config_file == cfg
    with pytest.raises(InvalidArgument, match="no configuration file"):
        parse_target(str(tmp_path / "missing.json5"))
    with pytest.raises(InvalidArgument, match="neither an endpoint"):
        parse_target("127.0.0.1:7447")


def test_key_layout() -> None:
    assert topic_key("lab-hub", "adc") == "robocli/lab-hub/adc"
    assert info_key("h") == "robocli/h/@info"
    assert settings_key("h", "imu") == "robocli/h/@settings/imu"
    assert alive_key("r1", "pioneer") == "robocli/r1/@alive/pioneer"
    assert parse_alive("robocli/r1/@alive/pioneer") == ("r1", "pioneer")
    assert parse_alive("robocli/r1/adc") is None
    for bad in ("a/b", "*", "@x", "", "a b"):
        with pytest.raises(InvalidArgument):
            topic_key(bad, "adc")


def test_server_listens_and_client_connects_there(endpoint: str) -> None:
    server = open_session(endpoint, "server")
    try:
        got: list[bytes] = []
        sub = server.declare_subscriber("robocli/t/adc", lambda s: got.append(s.payload.to_bytes()))
        client = open_session(endpoint, "client")
        try:
            # put until the subscription is known
            wait_for(lambda: client.put("robocli/t/adc", b"x") or got, "a put received")
            assert got and got[0] == b"x"
        finally:
            client.close()
        sub.undeclare()
    finally:
        server.close()


def test_client_reaching_nobody_is_unreachable(endpoint: str) -> None:
    with pytest.raises(TransportError, match=f"cannot connect to {endpoint}") as info:
        open_session(endpoint, "client")
    assert info.value.exit_code == 3
    assert "\n" not in str(info.value) and ".rs:" not in str(info.value)


def test_option_value_may_be_left_out() -> None:
    app = typer.Typer()

    @app.command(cls=ZenohCommand)
    def cmd(zenoh: str | None = zenoh_option("client"), other: int = 0) -> None:
        typer.echo(f"zenoh={zenoh} other={other}")

    runner = CliRunner()
    assert runner.invoke(app, ["--zenoh"]).output.strip() == f"zenoh={DEFAULT_ENDPOINT} other=0"
    out = runner.invoke(app, ["--zenoh", "--other", "3"]).output.strip()
    assert out == f"zenoh={DEFAULT_ENDPOINT} other=3"
    out = runner.invoke(app, ["--zenoh", "tcp/127.0.0.1:1"]).output.strip()
    assert out == "zenoh=tcp/127.0.0.1:1 other=0"
    assert runner.invoke(app, []).output.strip() == "zenoh=None other=0"
    out = runner.invoke(app, ["--other", "1", "--zenoh"]).output.strip()
    assert out == f"zenoh={DEFAULT_ENDPOINT} other=1"


def test_bad_value_is_a_usage_error() -> None:
    with pytest.raises(typer.BadParameter, match="neither an endpoint"):
        zenoh_session("nowhere", "client")


BLOCKED = "import sys; sys.modules['zenoh'] = None; "


def test_without_the_extra_one_line_says_how_to_install() -> None:
    code = BLOCKED + (
        "from robocli.zenoh import open_session, ZenohMissing\n"
        "try:\n    open_session(None, 'client')\n"
        "except ZenohMissing as e:\n    print(e.exit_code, e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=True).stdout  # fmt: skip
    assert out == "1 Zenoh support needs Eclipse Zenoh: pip install 'robocli-robots[zenoh]'\n"


def test_an_endpoint_means_no_shared_memory_and_no_multicast() -> None:
    """Zenoh would hand large messages to a process of the same host (another network
    namespace too) through shared memory, around the endpoint and its link."""
    config = zenoh_config("tcp/127.0.0.1:7447", "client")
    assert json.loads(config.get_json("transport/shared_memory/enabled")) is False
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7447"]
    server = zenoh_config(None, "server")
    assert json.loads(server.get_json("listen/endpoints")) == [DEFAULT_ENDPOINT]
    assert json.loads(server.get_json("mode")) == "peer"


def test_payload_decoding_is_bounded_and_typed() -> None:
    """What a callback decodes raises ProtocolError only: deep nesting (RecursionError),
    numbers out of a float's range (OverflowError later), NaN, a size past the cap."""
    from robocli.errors import ProtocolError
    from robocli.zenoh.payload import decode_object

    assert decode_object(b'{"v": 0.5, "w": -3}', "x", 100) == {"v": 0.5, "w": -3}
    for bad in (b"[" * 100_000, b'{"v": 1e400}', b'{"v": -1e400}', b'{"v": 1' + b"0" * 400 + b"}",
                b'{"v": NaN}', b'{"v": Infinity}', b"\xff", b"[1]", b"{" * 10):  # fmt: skip
        with pytest.raises(ProtocolError):
            decode_object(bad, "x", 1 << 20)
    with pytest.raises(ProtocolError, match="more than"):
        decode_object(b"{}" + b" " * 100, "x", 100)


def test_a_server_configured_as_a_client_listens_nowhere(tmp_path: Path) -> None:
    """A hub or bridge behind a lab's ACL router is a client: were it to listen on 7447 as
    well, a program of its host could reach it around the router's checks."""
    from robocli.zenoh.session import zenoh_config

    path = tmp_path / "hub1.json5"
    path.write_text('{ mode: "client", connect: { endpoints: ["tcp/127.0.0.1:9"] } }')
    listen = json.loads(zenoh_config(str(path), "server").get_json("listen/endpoints"))
    assert DEFAULT_ENDPOINT not in json.dumps(listen)
    path.write_text('{ mode: "peer" }')  # a peer's file naming no endpoint: loopback
    listen = json.loads(zenoh_config(str(path), "server").get_json("listen/endpoints"))
    assert listen == [DEFAULT_ENDPOINT]


def test_a_server_is_named_after_its_configurations_user(tmp_path: Path, capsys) -> None:
    """Under a lab's ACL a user serves under its own name only: that is the default name,
    and another one is said on stderr."""
    from robocli.commands._zenoh import server_name

    path = tmp_path / "hub1.json5"
    path.write_text('{ mode: "client", transport: { auth: { usrpwd: { user: "hub1", '
                    'password: "x" } } } }')  # fmt: skip
    assert server_name(None, str(path), "pioneer") == "hub1"
    assert capsys.readouterr().err == ""
    assert server_name("r9", str(path), "pioneer") == "r9"
    assert "--name r9 is not the configuration's user hub1" in capsys.readouterr().err
    assert server_name(None, "tcp/127.0.0.1:7447", "pioneer") == "pioneer"
    with pytest.raises(typer.BadParameter):
        server_name("@x", str(path), "pioneer")


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=256),
                 st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(),
                              lambda c: st.lists(c) | st.dictionaries(st.text(), c),
                              max_leaves=20).map(lambda v: json.dumps(v).encode())))  # fmt: skip
def test_payload_decoding_raises_protocol_errors_only(payload: bytes) -> None:
    from robocli.errors import ProtocolError
    from robocli.zenoh.payload import decode_object

    try:
        data = decode_object(payload, "x", 1 << 20)
    except ProtocolError:
        return
    assert isinstance(data, dict)
