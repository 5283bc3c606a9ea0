"""pyserial URLs for a hub's serial ports: ``robocli://HOST[:PORT]/dev/ttyUSB0?baudrate=...``
(:mod:`robocli.devices.hub.urlhandler.protocol_robocli` says the options and where the token
comes from).

>>> from robocli.devices.hub.serial_url import register   # doctest: +SKIP
>>> register()
>>> port = serial.serial_for_url("robocli://robot:1500/dev/ttyUSB0?baudrate=115200")

pyserial finds URL handlers in the packages of ``serial.protocol_handler_packages``;
:func:`register` adds robocli's (once). Nothing is registered at import.
"""

from __future__ import annotations

__all__ = ["PACKAGE", "main", "register"]

PACKAGE = "robocli.devices.hub.urlhandler"


def register() -> None:
    """Make ``serial.serial_for_url`` take ``robocli://`` URLs (idempotent)."""
    import serial

    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)


def main(argv: list[str] | None = None) -> int:
    """``python -m robocli.devices.hub.serial_url PROGRAM.py [ARGS...]``: run an unmodified
    pyserial program with ``robocli://`` registered, so that only its port string changes."""
    import runpy
    import sys

    args = sys.argv[1:] if argv is None else argv
    if not args:
        print("usage: python -m robocli.devices.hub.serial_url PROGRAM.py [ARGS...]",
              file=sys.stderr)  # fmt: skip
        return 2
    register()
    sys.argv = list(args)
    runpy.run_path(args[0], run_name="__main__")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
