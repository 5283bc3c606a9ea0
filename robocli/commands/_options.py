"""The grammar every command shares, written once (docs/cli-grammar.md is its table).

- The device: one positional URL (:func:`device_argument`), read by one parser
  (:mod:`robocli.addresses`): ``sim``, ``tcp://HOST:PORT``, a serial port, a pyserial URL,
  ``zenoh/NAME`` where the command reaches Zenoh. A command with several devices names each
  with the same option everywhere: ``--pioneer``, ``--arm``, ``--hub``, ``--laser``.
- The same option names: ``-o/--output``, ``-n/--count``, ``-d/--duration``, ``-r/--rate``,
  ``--json`` (JSON Lines: one object per line, ``--once`` included).
- A renamed option keeps working for one release: :data:`RENAMED` rewrites it (and says its
  new spelling on stderr, one line) before the command parses (see
  :class:`~robocli.commands._common.PlainCommand`).
"""

from __future__ import annotations

import sys
from typing import Any, Literal, get_args

import typer

#: Help panels of ``robocli -h``, by what users do.
PANELS = ROBOTS, SENSORS, RECORDING, LAB, TOOLS = (
    "Robots", "Sensors", "Recording and replay", "Lab", "Tools",
)  # fmt: skip

#: What each kind of device's URL may be (the positional's help, and docs/cli-grammar.md).
DEVICE_FORMS = {
    "pioneer": "sim, tcp://HOST:PORT, HOST:PORT, a serial port (/dev/ttyUSB0, COM1) or a "
    "pyserial URL (socket://, rfc2217://)",
    "arm": "sim, HOST or tcp://HOST (ports: --motion-port, --state-port)",
    "hub": "sim, HOST[:PORT] or tcp://HOST:PORT",
    "laser": "sim, a serial port (/dev/ttyACM0), tcp://HOST:PORT or a pyserial URL",
}


#: JSON's ``dir`` of a frame, as capture files say it: ``c2s`` computer to device, ``s2c``
#: back (the library's listeners say ``tx``/``rx``).
WIRE_DIR = {"tx": "c2s", "rx": "s2c"}


def device_argument(kind: str, envvar: str | None = None, default: Any = ...) -> Any:
    """The device a command talks to, as one positional ``URL``."""
    return typer.Argument(
        default,
        metavar="URL",
        help=f"The {kind}: {DEVICE_FORMS[kind]}.",
        envvar=envvar,
        show_envvar=envvar is not None,
        show_default=False,
    )


def output_option(default: Any = None, help: str = "File to write.", **more: Any) -> Any:
    return typer.Option(default, "--output", "-o", help=help, **more)


def count_option(default: Any = None, help: str = "Stop after N.", **limits: Any) -> Any:
    return typer.Option(default, "--count", "-n", metavar="N", help=help, **limits)


def duration_option(default: Any = None, help: str = "Stop after S seconds.", **limits: Any) -> Any:
    return typer.Option(default, "--duration", "-d", metavar="S", help=help, **limits)


def rate_option(default: Any = None, help: str = "Rate, Hz.", **limits: Any) -> Any:
    return typer.Option(default, "--rate", "-r", help=help, **limits)


def json_option(help: str = "JSON Lines: one object per line, t in Unix seconds, SI units.") -> Any:
    return typer.Option(False, "--json", help=help)


def flag(name: str, help: str, default: bool = False) -> Any:
    """A flag (``--name``, or ``--name/--no-name``), off unless ``default``."""
    return typer.Option(default, name, help=help)


def device_option(name: str, help: str, default: Any = None, **more: Any) -> Any:
    """A device of a command with several (``--pioneer URL``...), or a device to use."""
    return typer.Option(default, name, metavar="URL", help=help, **more)


def timeout_option(default: float, help: str, least: float, most: float, **more: Any) -> Any:
    return typer.Option(default, "--timeout", min=least, max=most, help=help, **more)


def port_option(default: int | None, help: str) -> Any:
    """A server's TCP port, ``-p/--port``."""
    return typer.Option(default, "--port", "-p", min=0, max=65535, help=help)


def bind_option(help: str = "Address to listen on.") -> Any:
    return typer.Option("127.0.0.1", "--bind", help=help)


def pose_option(help: str) -> Any:
    return typer.Option(None, "--pose", metavar="X,Y,TH", help=help)


def baud_option(default: int, help: str = "Serial baud rate.", least: int = 300,
                metavar: str | None = "RATE") -> Any:  # fmt: skip
    return typer.Option(default, "--baud", min=least, metavar=metavar, help=help)


def overwrite_option(help: str = "Replace an existing output file.") -> Any:
    return typer.Option(False, "--overwrite", help=help)


#: Every command that writes a user's file takes it (see :mod:`robocli.output`).
OverwriteOpt = overwrite_option()
#: What every simulator (``sim abb|pioneer|laser|create``) takes alike.
BindOpt = bind_option()
TimeScaleOpt = typer.Option(1.0, "--time-scale", min=0.1, max=100.0,
                            help="Simulated seconds per wall second.")  # fmt: skip
MapOpt = typer.Option(None, "--map", exists=True, dir_okay=False,
                      help="Map: JSON or text walls (x1 y1 x2 y2).")  # fmt: skip
RobotOpt = typer.Option("irb120", "--robot", help="Robot model name or model file.")
#: The recording ``info`` and ``plot`` read.
RecordingArg = typer.Argument(..., exists=True, dir_okay=False, metavar="FILE",
                              help="A recording (.mcap).")  # fmt: skip
StreamOpt = flag("--stream", "Stream (generic servers, not ABB).")


#: The hub's sensors, by the one set of names every command, help and message uses (the
#: ros4mat names of sysinfo, laser, depth and stereo, ``computer``, ``hokuyo``, ``kinect`` and
#: ``camera_stereo``, stay on the wire: :mod:`robocli.protocols.ros4mat` maps them).
SensorName = Literal["adc", "imu", "gps", "battery", "sysinfo", "laser", "camera", "stereo",
                     "depth"]  # fmt: skip
SENSOR_NAMES: tuple[str, ...] = get_args(SensorName)
#: The wire names, kept working for one release (RENAMED).
_WIRE_SENSOR_NAMES = {"computer": "sysinfo", "hokuyo": "laser", "kinect": "depth",
                      "camera_stereo": "stereo"}  # fmt: skip


#: Old spellings that keep working for one release, by command (the words after ``robocli``):
#: ``old -> new``; a new name of ``""`` makes the value positional; a key ``"OPT VALUE"``
#: matches that option with that value (``-f jsonl`` -> ``--json``).
_TRAJ = {"--out": "--output", "--points": "--count", "-r": "--robot"}
_BENCH = {"--n": "--count", "--url": ""}
_ARM_ROBOT = {"-r": "--robot"}
RENAMED: dict[str, dict[str, str]] = {
    **{f"traj {s}": _TRAJ for s in ("circle", "rectangle", "ptp-joint", "ptp-cartesian", "file")},
    "validate": _ARM_ROBOT,
    "monitor arm": {"--out": "--output", "--samples": "--count", **_ARM_ROBOT},
    "upload arm": {"--points": "--count", "--monitor": "--output", **_ARM_ROBOT},
    "connect arm": _ARM_ROBOT,
    "dump arm": _ARM_ROBOT,
    "teleop arm": _ARM_ROBOT,
    "bridge arm": _ARM_ROBOT,
    "sim abb": _ARM_ROBOT,
    "record": _ARM_ROBOT,
    "bench rtt": _BENCH,
    "bench jitter": _BENCH,
    "bench sip": _BENCH,
    "bench throughput": {"--seconds": "--duration", "--url": ""},
    "subscribe": {"-f jsonl": "--json", "--format jsonl": "--json", **_WIRE_SENSOR_NAMES},
    "connect laser": {
        "-f jsonl": "--json",
        "--format jsonl": "--json",
        "-f text": "",
        "--format text": "",
    },
}


def renamed(command: str, args: list[str]) -> list[str]:
    """``args`` of ``command`` with every old spelling in :data:`RENAMED` replaced by its
    new one, each said once on stderr (arguments after ``--`` are left alone)."""
    table = RENAMED.get(command)
    if not table:
        return args
    out: list[str] = []
    end = args.index("--") if "--" in args else len(args)
    i = 0
    while i < end:
        arg = args[i]
        name, eq, value = arg.partition("=") if arg.startswith("--") else (arg, "", "")
        has_next = i + 1 < end
        pair = f"{name} {value if eq else (args[i + 1] if has_next else '')}"
        if pair in table:  # an option with a value that became a flag (or nothing)
            _notice(pair, table[pair])
            out += [table[pair]] if table[pair] else []
            i += 1 if eq else 2
            continue
        if name in table:
            new = table[name]
            _notice(name, new or "a positional URL")
            if new:
                out.append(f"{new}={value}" if eq else new)
            elif eq:
                out.append(value)
        else:
            out.append(arg)
        i += 1
    return out + args[end:]


def _notice(old: str, new: str) -> None:
    sys.stderr.write(f"robocli: {old} is now {new} (the old spelling goes in the next release)\n")
