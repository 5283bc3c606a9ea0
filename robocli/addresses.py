"""Addresses and URLs, read by one parser used by every command and client.

:func:`parse_address` (``HOST[:PORT]``, ``[IPv6]:PORT``), :func:`parse_host` (an address
without a port, e.g. where to listen), :func:`check_url` (what
:func:`~robocli.transports.open_transport` accepts, checked without opening anything),
:func:`is_tcp` (whether it takes a URL as TCP), :func:`format_address` (back to text) and
:func:`parse_device_url` (a device's one URL: ``sim://``, ``tcp://``, a serial port, a pyserial
URL, ``zenoh/NAME``; an arm's two ports in the query, see ``docs/urls.md``).
Each refuses a malformed value with :class:`InvalidURL`, a usage error. Nothing here resolves,
connects or opens; :mod:`robocli.transports` re-exports every public name.
"""

from __future__ import annotations

import ipaddress
import os
import re
from dataclasses import dataclass, field
from urllib.parse import parse_qsl

from robocli.errors import InvalidArgument, TransportError

#: A host name (or an IPv4 address): letters, digits, ``_``, ``.``, ``-``.
_HOSTNAME = re.compile(r"^[A-Za-z0-9_.\-]+$")
#: A Windows serial port name (``COM1``), which has no slash.
_COM_PORT = re.compile(r"^COM\d+$", re.IGNORECASE)
#: pyserial URL schemes whose part after ``://`` is ``HOST:PORT``.
_NETWORK_SCHEMES = ("socket", "rfc2217")


class InvalidURL(InvalidArgument, TransportError):
    """An address, port or URL that cannot name a stream (bad port number, two ports,
    unknown scheme): the caller's mistake, so a usage error (exit code 2); also a
    :class:`TransportError` for code that catches those around :func:`open_transport`.
    :attr:`reason` is what is wrong, without the value (for callers that rephrase)."""

    def __init__(self, message: str, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason or message


def _bad(what: str, text: str, reason: str, form: str = "") -> InvalidURL:
    expected = f"; expected {form}" if form else ""
    return InvalidURL(f"{what} {text!r}: {reason}{expected}", reason)


def _is_ipv6(text: str) -> bool:
    try:
        ipaddress.IPv6Address(text)  # a zone (fe80::1%eth0) included
    except ValueError:
        return False
    return True


def _check_host(host: str, text: str, what: str, form: str) -> str:
    if _is_ipv6(host) or _HOSTNAME.match(host):
        return host
    which = "" if host == text.strip() else f"{host!r} "
    raise _bad(what, text, f"{which}is not a host name or address", form)


def parse_address(
    text: str,
    default_port: int | None = None,
    *,
    default_host: str | None = None,
    what: str = "address",
    form: str | None = None,
    port_range: tuple[int, int] = (1, 65535),
) -> tuple[str, int]:
    """``HOST``, ``HOST:PORT``, ``[IPv6]:PORT``, a bare IPv6 literal, each optionally after
    ``tcp://`` -> ``(host, port)``, the host without brackets.

    ``default_port``: the port when none is given (None: a port is required).
    ``default_host``: the host when none is given (``:PORT``, or ``PORT`` alone; None: a
    host is required). ``what`` names the value in messages (``--hub``), ``form`` says what
    is expected there (default ``HOST:PORT`` or ``HOST[:PORT]``). Raises :class:`InvalidURL`
    (a usage error) for anything else: two ports (``h:1:2``), a port out of ``port_range``,
    a host that is no name or address; nothing is resolved or connected."""
    if form is None:
        form = ("HOST:PORT" if default_port is None else "HOST[:PORT]") + " ([ADDR]:PORT for IPv6)"
    t = text.strip()
    if t.startswith("tcp://"):
        t = t[len("tcp://") :].removesuffix("/")
    port_text: str | None = None
    if t.startswith("["):
        host, bracket, rest = t[1:].partition("]")
        if not bracket or not _is_ipv6(host):
            raise _bad(what, text, "brackets hold an IPv6 address", form)
        if rest:
            if not rest.startswith(":"):
                raise _bad(what, text, f"{rest!r} after the address", form)
            port_text = rest[1:]
    elif t.count(":") > 1:
        if not _is_ipv6(t):
            raise _bad(what, text, "more than one ':'", form)
        host = t  # a bare IPv6 literal: no port can follow it
    elif ":" in t:
        host, _, port_text = t.partition(":")
    elif t.isdigit() and default_host is not None:
        host, port_text = "", t  # a port alone
    else:
        host = t
    if not host:
        if default_host is None:
            raise _bad(what, text, "no host", form)
        host = default_host
    else:
        host = _check_host(host, text, what, form)
    low, high = port_range
    if port_text is None:
        if default_port is None:
            raise _bad(what, text, "no port", form)
        return host, default_port
    if not port_text.isdigit() or not port_text.isascii():
        shown = repr(port_text) if port_text else "nothing"
        raise _bad(what, text, f"bad port ({shown} after ':')", form)
    port = int(port_text)
    if not low <= port <= high:
        raise _bad(what, text, f"port {port} out of range {low}..{high}", form)
    return host, port


def parse_host(text: str, *, what: str = "address") -> str:
    """A host name, IPv4 address or IPv6 literal (with or without brackets), without a
    port -> the host (IPv6 without brackets), e.g. where a server listens. Raises
    :class:`InvalidURL` for anything else (an empty value, a port, spaces)."""
    t = text.strip()
    if t.startswith("[") and t.endswith("]") and _is_ipv6(t[1:-1]):
        return t[1:-1]
    if _is_ipv6(t) or (t and _HOSTNAME.match(t)):
        return t
    if t and (t.count(":") == 1 or t.startswith("[")):
        raise _bad(what, text, "give the address without a port")
    raise _bad(what, text, "not a host name or address (e.g. 127.0.0.1, ::1)")


def format_address(host: str, port: int) -> str:
    """``host:port`` as :func:`parse_address` reads it back: IPv6 literals in brackets."""
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def check_url(url: str, *, what: str = "PORT") -> str:
    """``url`` stripped, when :func:`open_transport` can open it as something: ``tcp://``
    or ``HOST:PORT`` (:func:`parse_address`), a serial port (a path, ``COMn``), a pyserial
    URL whose scheme has a handler (``socket://HOST:PORT`` checked too). Else
    :class:`InvalidURL`, a usage error naming ``what``. Nothing is opened: a robot that is
    away is not a malformed URL."""
    text = url.strip()
    hint = "give a serial port (/dev/ttyUSB0, COM1), tcp://HOST:PORT or a pyserial URL"
    if not text:
        raise InvalidURL(f"{what}: empty; {hint}", "empty")
    if is_tcp(text):
        parse_address(text, what=what, form="tcp://HOST:PORT or HOST:PORT")
        return text
    if "://" in text:
        scheme, _, rest = text.partition("://")
        if not _pyserial_scheme(scheme):
            reason = f"unknown URL scheme {scheme!r}"
            raise InvalidURL(f"{what}: {reason} in {text!r}; {hint}", reason)
        if scheme in _NETWORK_SCHEMES:
            try:
                parse_address(rest.split("?", 1)[0].removesuffix("/"))
            except InvalidURL as exc:
                raise _bad(what, text, exc.reason, f"{scheme}://HOST:PORT") from None
        return text
    if _is_path(text) or os.path.exists(text):
        return text
    guess = f"/dev/{text}"
    also = f" (did you mean {guess}?)" if os.path.exists(guess) else ""
    reason = f"neither a serial port nor a TCP address{also}"
    raise InvalidURL(f"{what} {text!r} is {reason}; {hint}", reason)


def _is_path(text: str) -> bool:
    """A serial port's name: a path (``/dev/ttyUSB0``, ``./pty``, ``\\\\.\\COM10``) or ``COMn``."""
    return text.startswith(("/", ".", "\\")) or bool(_COM_PORT.match(text))


def is_tcp(text: str) -> bool:
    """Whether :func:`open_transport` takes ``text`` (stripped) as TCP: ``tcp://...``, or
    ``HOST:PORT``, a colon in what is neither a path nor another URL."""
    return text.startswith("tcp://") or (":" in text and "://" not in text and not _is_path(text))


def _pyserial_scheme(scheme: str) -> bool:
    """Whether pyserial has a URL handler for ``scheme`` (``socket``, ``rfc2217``...)."""
    import importlib.util

    if not scheme.isidentifier():
        return False
    try:
        return importlib.util.find_spec(f"serial.urlhandler.protocol_{scheme}") is not None
    except (ImportError, ValueError):
        return False


#: The schemes :func:`parse_device_url` tells apart.
DEVICE_KINDS = ("sim", "tcp", "serial", "zenoh")
#: The ports an arm's URL may carry in its query (``tcp://HOST?motion=11000&state=11002``).
ARM_PORTS = ("motion", "state")
#: Longest URL read (a bound on input; a device URL is a few dozen characters).
MAX_URL = 2048


@dataclass(frozen=True)
class DeviceURL:
    """A device's address as :func:`parse_device_url` read it.

    ``kind``: ``"sim"`` (an in-process simulator: ``model`` is what follows ``sim://``, e.g.
    ``p3dx``; ``options`` its query, e.g. ``time_scale=4``), ``"tcp"`` (``host``, ``port``
    or None when the URL gave none; ``ports`` the named ports of its query), ``"serial"``
    (``target`` a path, ``COMn`` or a pyserial URL) or ``"zenoh"`` (``name`` after
    ``zenoh/``; ``options`` its query: ``zenoh``, the endpoint or configuration file).
    ``target`` is what :func:`~robocli.transports.open_transport` opens."""

    kind: str
    text: str
    target: str = ""
    host: str = ""
    port: int | None = None
    model: str = ""
    name: str = ""
    options: dict[str, str] = field(default_factory=dict)
    ports: dict[str, int] = field(default_factory=dict)


def _query(text: str, query: str) -> dict[str, str]:
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query),
                          max_num_fields=32)  # fmt: skip
    except ValueError as exc:
        raise _bad("URL", text, f"bad query ({exc})") from None
    out: dict[str, str] = {}
    for key, value in pairs:
        if not key.isidentifier() or key in out:
            raise _bad("URL", text, f"bad or repeated option {key!r} in the query")
        out[key] = value
    return out


def _named_ports(text: str, options: dict[str, str], names: tuple[str, ...]) -> dict[str, int]:
    ports: dict[str, int] = {}
    for key, value in options.items():
        if key not in names:
            known = ", ".join(names) or "none"
            raise _bad("URL", text, f"unknown option {key!r} (ports known here: {known})")
        if not (value.isascii() and value.isdigit() and 1 <= int(value) <= 65535):
            raise _bad("URL", text, f"{key} port {value!r} is not a number in 1..65535")
        ports[key] = int(value)
    return ports


def parse_device_url(
    url: str, *, default_port: int | None = None, ports: tuple[str, ...] = (),
    what: str = "URL",
) -> DeviceURL:  # fmt: skip
    """Read a device's URL, one grammar for every device (see ``docs/urls.md``):

    - ``sim`` or ``sim://[MODEL][?OPTION=VALUE&...]``: the built-in simulator, in-process;
    - ``tcp://HOST[:PORT]``, ``HOST:PORT`` (``[IPv6]:PORT``), or a bare ``HOST`` when
      ``default_port`` is given; ``ports`` names the ports the query may carry, e.g.
      ``tcp://HOST?motion=11000&state=11002`` for an arm (``ports=ARM_PORTS``);
    - a serial port (``/dev/ttyUSB0``, ``COM3``) or a pyserial URL (``socket://``,
      ``rfc2217://``...): ``kind="serial"``;
    - ``zenoh/NAME[?zenoh=ENDPOINT|CONFIG]``: a robot or hub behind a Zenoh bridge, reached
      through that endpoint or configuration (``--zenoh``'s value; ``options["zenoh"]``).

    Raises :class:`InvalidURL` (a usage error) for anything else; nothing is opened."""
    text = url.strip() if isinstance(url, str) else ""
    if not text:
        raise InvalidURL(f"{what}: empty; give sim://, tcp://HOST:PORT, a serial port or "
                         "zenoh/NAME", "empty")  # fmt: skip
    if len(text) > MAX_URL:
        raise InvalidURL(f"{what}: longer than {MAX_URL} characters", "too long")
    if text == "sim" or text.startswith("sim://"):
        rest, _, query = text.removeprefix("sim").removeprefix("://").partition("?")
        model = rest.removesuffix("/")
        if model and not _HOSTNAME.match(model):
            raise _bad(what, text, f"{model!r} is not a simulator model name", "sim://MODEL")
        return DeviceURL("sim", text, model=model, options=_query(text, query))
    if text.startswith("zenoh/"):
        name, _, query = text.removeprefix("zenoh/").partition("?")
        if not name or not _HOSTNAME.match(name):
            raise _bad(what, text, "not a name after zenoh/", "zenoh/NAME[?zenoh=ENDPOINT]")
        options = _query(text, query)
        if options.keys() - {"zenoh"} or not options.get("zenoh", "-"):
            raise _bad(what, text, "the query takes zenoh=ENDPOINT|CONFIG only (e.g. "
                       "zenoh=tcp/127.0.0.1:7447)", "zenoh/NAME[?zenoh=ENDPOINT]")  # fmt: skip
        return DeviceURL("zenoh", text, name=name, options=options)
    if ports and not text.startswith(("/", "\\")) and ("://" not in text or is_tcp(text)):
        address, _, query = text.partition("?")
        named = _named_ports(text, _query(text, query), ports)
        try:
            host = parse_host(address.removeprefix("tcp://").removesuffix("/"), what=what)
        except InvalidURL as exc:
            form = "tcp://HOST?" + "&".join(f"{p}=PORT" for p in ports)
            raise _bad(what, text, exc.reason, form) from None
        return DeviceURL("tcp", text, host=host, ports=named)
    if default_port is not None and "://" not in text and not _is_path(text):
        host, port = parse_address(text, default_port, what=what)
        return DeviceURL("tcp", text, target=f"tcp://{format_address(host, port)}",
                         host=host, port=port)  # fmt: skip
    checked = check_url(text, what=what)
    if is_tcp(checked):
        host, port = parse_address(checked, what=what)
        return DeviceURL("tcp", text, target=checked, host=host, port=port)
    if checked.lower().startswith("loop://"):
        raise _bad(what, text, "pyserial's loop:// echoes what is sent: no device can answer "
                   "there (for a simulated one, give sim://)")  # fmt: skip
    return DeviceURL("serial", text, target=checked)
