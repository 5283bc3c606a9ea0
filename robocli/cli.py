"""The ``robocli`` command line: Typer commands grouped by verb, one module per robot type.

Each command parses its arguments, calls one public library function and renders the result.
Modules here import the library lazily so that ``robocli --help`` stays fast in shell loops.
Errors become one line on stderr and an exit code (see :mod:`robocli.errors`).
"""

from __future__ import annotations

import sys
from typing import Any

import typer
from typer.core import TyperGroup

from robocli._version import __version__
from robocli.commands import arm, bench, kinematics, pioneer, plot, ports, record
from robocli.commands import bridge as bridge_commands
from robocli.commands import convert as convert_command
from robocli.commands import create as create_commands
from robocli.commands import doctor as doctor_command
from robocli.commands import dump as dump_commands
from robocli.commands import export as export_command
from robocli.commands import hub as hub_commands
from robocli.commands import laser as laser_commands
from robocli.commands import models as model_commands
from robocli.commands import recover as recover_command
from robocli.commands import router as router_commands
from robocli.commands import serial as serial_command
from robocli.commands import serve as serve_command
from robocli.commands import teleop as teleop_commands
from robocli.commands._common import PlainCommand
from robocli.commands._options import LAB, PANELS, RECORDING, ROBOTS, SENSORS, TOOLS
from robocli.commands._zenoh import ZenohCommand


class PanelGroup(TyperGroup):
    """A group whose -h lists its commands under the panels of what users do
    (:data:`~robocli.commands._options.PANELS`), each with its whole short help (never cut
    with "...")."""

    def format_commands(self, ctx: Any, formatter: Any) -> None:
        panels: dict[str, list[tuple[str, str]]] = {}
        for name in self.list_commands(ctx):
            cmd = self.get_command(ctx, name)
            if cmd is None or cmd.hidden:
                continue
            panel = PANEL_OF.get(name, "Commands")
            panels.setdefault(panel, []).append((name, cmd.get_short_help_str(limit=10_000)))
        for panel in (*PANELS, "Commands"):
            if panels.get(panel):
                with formatter.section(panel):
                    formatter.write_dl(panels[panel])


class _Typer(typer.Typer):
    """Commands default to :class:`PlainCommand`: man-page help, no ``<bool>`` placeholders."""

    def command(self, *args: Any, **kwargs: Any) -> Any:
        kwargs["cls"] = kwargs.get("cls") or PlainCommand
        return super().command(*args, **kwargs)


app = _Typer(
    cls=PanelGroup,
    name="robocli",
    help="Drive robots and read their sensors from a laptop, byte for byte: Pioneer mobile "
    "robots (ARCOS), ABB and other industrial arms (ROS-Industrial Simple Message), the ros4mat "
    "sensor hub; a built-in simulator for each.",
    no_args_is_help=True,
    add_completion=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # plain help: no `<bool>` placeholders, fits any terminal
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"robocli {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
    verbose: int = typer.Option(0, "--verbose", "-v", count=True, help="Log more (-vv: debug)."),
) -> None:
    """robocli: real protocols, byte for byte, with a simulator for every robot."""
    if verbose:
        import logging

        logging.basicConfig(
            level=logging.DEBUG if verbose > 1 else logging.INFO,
            format="%(asctime)s %(name)s %(levelname)s %(message)s",
        )


def _group(name: str, help_text: str) -> typer.Typer:
    group = _Typer(name=name, help=help_text, no_args_is_help=True, rich_markup_mode=None,
                   cls=PanelGroup)  # fmt: skip
    app.add_typer(group)
    return group


connect = _group("connect", "Connect to a robot and show its live state.")
teleop = _group("teleop", "Drive a robot from the keyboard.")
dump = _group("dump", "Show every packet, named and decoded, like a protocol analyser.")
sim = _group("sim", "Run a built-in simulator speaking the robot's real protocol.")
bench_group = _group("bench", "Measure latency, jitter and per-packet cost.")

connect.command("pioneer", cls=ZenohCommand)(pioneer.connect)
teleop.command("pioneer", cls=ZenohCommand)(teleop_commands.pioneer)
dump.command("pioneer", cls=PlainCommand)(dump_commands.pioneer)
sim.command("pioneer", cls=PlainCommand)(pioneer.simulate)
app.command("ports", cls=PlainCommand)(ports.ports)
bench_group.command("rtt", cls=PlainCommand)(bench.rtt)
bench_group.command("jitter", cls=PlainCommand)(bench.jitter)
bench_group.command("sip", cls=PlainCommand)(bench.sip)

traj = _group("traj", "Generate an arm trajectory, sample it ideally and write the JSON log.")
traj.command("circle")(kinematics.circle)
traj.command("rectangle")(kinematics.rectangle)
traj.command("ptp-joint")(kinematics.ptp_joint)
traj.command("ptp-cartesian")(kinematics.ptp_cartesian)
traj.command("file")(kinematics.file)
app.command("validate")(kinematics.validate)

upload = _group("upload", "Upload a trajectory to a robot.")
monitor = _group("monitor", "Record a robot's state stream to a log.")
sim.command("abb", cls=PlainCommand)(arm.simulate)
upload.command("arm", cls=PlainCommand)(arm.upload)
monitor.command("arm", cls=PlainCommand)(arm.monitor)
connect.command("arm", cls=PlainCommand)(arm.connect)
dump.command("arm", cls=PlainCommand)(dump_commands.arm)
teleop.command("arm", cls=PlainCommand)(teleop_commands.arm)

app.command("subscribe", cls=ZenohCommand)(hub_commands.subscribe)
app.command("serial", cls=serial_command.SerialCommand)(serial_command.serial)
connect.command("hub")(hub_commands.connect)
dump.command("hub")(dump_commands.hub)
bench_group.command("throughput")(hub_commands.throughput)
app.command("serve", cls=ZenohCommand)(serve_command.serve)
app.command("doctor", cls=PlainCommand)(doctor_command.doctor)
app.command("record", cls=PlainCommand)(record.record)
connect.command("laser", cls=PlainCommand)(laser_commands.connect)
sim.command("laser", cls=PlainCommand)(laser_commands.simulate)
sim.command("create", cls=PlainCommand)(create_commands.simulate)
dump.command("laser", cls=PlainCommand)(dump_commands.laser)

bridge = _group("bridge", "Put a robot on Eclipse Zenoh: state for many, commands from one.")
bridge.command("pioneer", cls=ZenohCommand)(bridge_commands.pioneer)
bridge.command("arm", cls=ZenohCommand)(bridge_commands.arm)
app.command("info", cls=PlainCommand)(record.info)
app.command("plot", cls=PlainCommand)(plot.plot)
app.command("export", cls=PlainCommand)(export_command.export)
app.command("recover", cls=PlainCommand)(recover_command.recover)
app.command("convert", cls=PlainCommand)(convert_command.convert)
app.command("router", cls=ZenohCommand)(router_commands.router)
app.command("list", cls=ZenohCommand)(router_commands.list_)
app.command("urdf", cls=PlainCommand)(model_commands.urdf)


#: Where ``robocli -h`` lists each command, by what users do.
PANEL_OF = {
    **dict.fromkeys(("connect", "teleop", "upload", "monitor", "traj", "bridge"), ROBOTS),
    **dict.fromkeys(("subscribe", "serial", "serve"), SENSORS),
    **dict.fromkeys(("record", "info", "plot", "export", "recover", "convert", "dump"), RECORDING),
    **dict.fromkeys(("sim", "bench", "router", "list", "validate"), LAB),
    **dict.fromkeys(("doctor", "ports", "urdf"), TOOLS),
}
#: Each command's line in its group's -h: set here, whole (Typer would cut the docstring's
#: first sentence with "...").
SHORT_HELP = {
    "ports": "List serial ports, with their description and hardware id.",
    "validate": "Compare a measured arm run with its simulation: RMSE, MAE, TCP error.",
    "subscribe": "Stream a hub sensor's timestamped samples to stdout.",
    "serial": "Write to and read from a serial port on the hub.",
    "serve": "Run the sensor hub (ros4mat v3), optionally on Zenoh and Foxglove.",
    "doctor": "Check this machine for robocli: versions, C core, serial access, devices.",
    "record": "Record robots, arms, a hub and a laser into one MCAP file.",
    "info": "Summarise a recording: duration, channels, counts and rates.",
    "plot": "Draw a recording's channels into a PNG.",
    "export": "Export a recording to CSV, JSON Lines, NPZ or an IRB120 log.",
    "recover": "Rewrite what is readable of a recording cut short.",
    "convert": "Turn a robocli recording into a ROS 2 bag (--ros2).",
    "urdf": "Print a robot's URDF model, generated from robocli's own model of it.",
    "router": "Run a Zenoh router (the lab server's), until Ctrl-C.",
    "list": "List the hubs and robots that are up on Zenoh.",
    "connect pioneer": "Show a Pioneer's identity and live state.",
    "connect arm": "Show an arm's live joints, TCP pose and status.",
    "connect hub": "Survey a hub: running sensors, rates, round trip, clock offset.",
    "connect laser": "Show a Hokuyo laser's identity and live scans.",
    "teleop pioneer": "Drive a Pioneer from the keyboard.",
    "teleop arm": "Jog an arm from the keyboard.",
    "dump pioneer": "Every ARCOS packet both ways, named and decoded.",
    "dump arm": "Every Simple Message frame of both ports, named and decoded.",
    "dump hub": "Every ros4mat message both ways, named and decoded.",
    "dump laser": "Every SCIP line both ways, named and decoded.",
    "sim pioneer": "Run a Pioneer simulator (ARCOS, like MobileSim).",
    "sim abb": "Run an ABB controller simulator (Simple Message: motion, state).",
    "sim laser": "Run a Hokuyo laser simulator (SCIP 2.0).",
    "sim create": "Run an iRobot Create 2 simulator (Open Interface) on a pty or a port.",
    "bench rtt": "Round-trip statistics, beside the C floor measured in the same run.",
    "bench jitter": "Period statistics: SIPs, arm states or laser scans.",
    "bench sip": "Client work per SIP and the keep-alive period.",
    "bench throughput": "Many clients pulling many hub sensors: rates, latency, losses.",
    "traj circle": "A circle in a plane, sampled ideally, to a log.",
    "traj rectangle": "A rectangle in a plane, sampled ideally, to a log.",
    "traj ptp-joint": "A point-to-point move in joint space, to a log.",
    "traj ptp-cartesian": "A straight TCP move to a point, to a log.",
    "traj file": "A trajectory through a file's waypoints, to a log.",
    "upload arm": "Upload a trajectory to an arm and wait for its end.",
    "monitor arm": "Record an arm's state stream to a log.",
    "bridge pioneer": "Put a Pioneer on Zenoh: state for many, commands from one.",
    "bridge arm": "Put an arm on Zenoh: state for many, commands from one.",
}


def _set_short_help(group: Any, path: str = "") -> None:
    """Give every command its :data:`SHORT_HELP` line (a test checks that none is missing)."""
    for name, cmd in getattr(group, "commands", {}).items():
        full = f"{path} {name}".strip()
        if hasattr(cmd, "commands"):
            _set_short_help(cmd, full)
        elif full in SHORT_HELP:
            cmd.short_help = SHORT_HELP[full]


def build_command() -> Any:
    """The Click command of :data:`app`, every command's short help set."""
    command = typer.main.get_command(app)
    _set_short_help(command)
    return command


def _hoist_verbose(argv: list[str]) -> list[str]:
    """``-v``/``-vv``/``--verbose`` anywhere before ``--`` count as the root option, so
    ``robocli connect pioneer sim -v`` works like ``robocli -v connect pioneer sim``."""
    end = argv.index("--") if "--" in argv else len(argv)
    verbose = [
        a for a in argv[:end] if a == "--verbose" or (len(a) > 1 and a == "-" + "v" * (len(a) - 1))
    ]
    rest = [a for a in argv[:end] if a not in verbose]
    return verbose + rest + argv[end:]


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the app, map errors to one line and an exit code."""
    from typer.exceptions import TyperException

    from robocli.errors import EXIT_INTERRUPTED, InvalidArgument, RobocliError

    args = _hoist_verbose(sys.argv[1:] if argv is None else list(argv))
    try:
        # Typer returns (rather than raises) the code of an Exit, including 130 for Ctrl-C
        with recover_command.truncation_notes():  # a recording cut short: one note line
            code = build_command().main(args=args, prog_name="robocli", standalone_mode=False)
        if code == EXIT_INTERRUPTED:
            typer.echo("robocli: interrupted", err=True)
        return code if isinstance(code, int) else 0
    except typer.Exit as exc:
        return int(exc.exit_code)
    except ImportError as exc:  # an optional extra that is not installed: which one
        extra = _EXTRAS.get((exc.name or "").partition(".")[0])
        if extra is None:
            raise
        typer.echo(f"robocli: this needs the {exc.name} package, from the {extra} extra: "
                   f"pip install 'robocli-robots[{extra}]'", err=True)  # fmt: skip
        return 1
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("robocli: interrupted", err=True)
        return EXIT_INTERRUPTED
    except RobocliError as exc:
        # -h helps with a value given on the command line (InvalidArgument: a URL, a range),
        # not with a file's contents (a log with NaN, an unreachable point, a missing folder)
        hint = f" Try 'robocli {_command_of(args)} -h'." if isinstance(exc, InvalidArgument) else ""
        message = str(exc).rstrip(".") + "." if hint else str(exc)
        typer.echo(f"robocli: {message}{hint}", err=True)
        return exc.exit_code
    except TyperException as exc:  # usage errors (bad option, missing argument: code 2)
        if type(exc).__name__ == "NoArgsIsHelpError":  # a group without its command: help
            typer.echo(exc.format_message())
            return 0
        # "Value error, ": how pydantic (Typer's coercion) words a rejected choice
        message = exc.format_message().replace("Value error, ", "").rstrip(".")
        message += _given_value(exc, args)
        typer.echo(f"robocli: {message}.{_help_hint(exc)}", err=True)
        return int(exc.exit_code)


#: The extra (pyproject.toml) that brings each optional package.
_EXTRAS = {
    "mcap": "record", "zstandard": "record", "lz4": "record", "matplotlib": "plot",
    "websockets": "foxglove", "zenoh": "zenoh", "cv2": "camera", "PIL": "camera",
}  # fmt: skip


def _command_of(args: list[str]) -> str:
    """The command words of ``args`` (``connect pioneer``): the leading non-options."""
    words = [a for a in args if not a.startswith("-")]
    groups = {
        info.name or (info.typer_instance.info.name if info.typer_instance else None)
        for info in app.registered_groups
    }
    return " ".join(words[:2] if words[:1] and words[0] in groups else words[:1])


def _given_value(exc: Exception, args: list[str]) -> str:
    """`` (got 'fast')``: the value a rejected option was given, when its message omits it."""
    opts = getattr(getattr(exc, "param", None), "opts", None) or []
    for i, arg in enumerate(args):
        name, eq, value = arg.partition("=")
        if name in opts and (eq or i + 1 < len(args)):
            value = value if eq else args[i + 1]
            return "" if value in exc.format_message() else f" (got {value!r})"  # type: ignore[attr-defined]
    return ""


def _help_hint(exc: Exception) -> str:
    """`` Try 'robocli dump pioneer -h'.`` for a usage error, naming the command it was in."""
    ctx = getattr(exc, "ctx", None)
    if ctx is None or getattr(exc, "exit_code", 0) != 2:
        return ""
    return f" Try '{ctx.command_path} -h'."


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
