"""The ``robocli`` command line: Typer commands grouped by verb, one module per robot type.

Each command parses its arguments, calls one public library function and renders the result.
Modules here import the library lazily so that ``robocli --help`` stays fast in shell loops.
Errors become one line on stderr and an exit code (see :mod:`robocli.errors`).
"""

from __future__ import annotations

import sys

import typer

from robocli._version import __version__
from robocli.commands import bench, kinematics, pioneer

app = typer.Typer(
    name="robocli",
    help="Drive robots and read their sensors from a laptop: Pioneer (ARCOS), built-in simulators.",
    no_args_is_help=True,
    add_completion=True,
    pretty_exceptions_enable=False,
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
    group = typer.Typer(name=name, help=help_text, no_args_is_help=True)
    app.add_typer(group)
    return group


connect = _group("connect", "Connect to a robot and show its live state.")
teleop = _group("teleop", "Drive a robot from the keyboard.")
dump = _group("dump", "Show every packet, named and decoded, like a protocol analyser.")
sim = _group("sim", "Run a built-in simulator speaking the robot's real protocol.")
bench_group = _group("bench", "Measure latency, jitter and per-packet cost.")

connect.command("pioneer")(pioneer.connect)
teleop.command("pioneer")(pioneer.teleop)
dump.command("pioneer")(pioneer.dump)
sim.command("pioneer")(pioneer.simulate)
bench_group.command("rtt")(bench.rtt)
bench_group.command("jitter")(bench.jitter)
bench_group.command("sip")(bench.sip)

traj = _group("traj", "Generate an arm trajectory, sample it ideally and write the JSON log.")
traj.command("circle")(kinematics.circle)
traj.command("rectangle")(kinematics.rectangle)
traj.command("ptp-joint")(kinematics.ptp_joint)
traj.command("ptp-cartesian")(kinematics.ptp_cartesian)
traj.command("file")(kinematics.file)
app.command("validate")(kinematics.validate)


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the app, map errors to one line and an exit code."""
    from robocli.errors import EXIT_INTERRUPTED, RobocliError

    try:
        # Typer returns (rather than raises) the code of an Exit, including 130 for Ctrl-C
        code = app(args=argv, prog_name="robocli", standalone_mode=False)
        if code == EXIT_INTERRUPTED:
            typer.echo("robocli: interrupted", err=True)
        return code if isinstance(code, int) else 0
    except typer.Exit as exc:
        return int(exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("robocli: interrupted", err=True)
        return EXIT_INTERRUPTED
    except RobocliError as exc:
        typer.echo(f"robocli: {exc}", err=True)
        return exc.exit_code
    except Exception as exc:
        # Typer's usage errors (bad option, missing argument: exit code 2) carry their own
        # message and code; anything else is a bug and keeps its traceback.
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code"):
            if type(exc).__name__ == "NoArgsIsHelpError":
                return 0
            typer.echo(f"robocli: {exc.format_message()}", err=True)
            return int(exc.exit_code)
        raise


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
