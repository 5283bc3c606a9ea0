"""The exit-code table of the manual (docs/getting-started.md), checked: every example in its
third column is run here as a command line, and must end with its row's code (issue 13,
finding 15).

Command lines without a signal run in-process through ``robocli.cli.main`` (the mapping of
errors to codes and messages is the same as in a process); Ctrl-C, SIGTERM, a reader that
leaves and a link that drops run ``robocli`` as a process. An example in the table without
a command line here, or a command line here for no example there, fails the test: the table
and the code cannot drift apart.
"""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from robocli.cli import main
from tests.commands.helpers import ROBOCLI, ctrl_c

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT = 60.0


def readme_table() -> dict[tuple[int, str], str]:
    """{(code, example): meaning} from the manual's "Exit codes" table (examples are split
    on "; " in the third column)."""
    text = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8")
    section = text.split("## Exit codes", 1)[1].split("\n#", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        if len(cells) == 3 and cells[0].isdigit():
            for example in cells[2].split("; "):
                rows[(int(cells[0]), example.replace("\\|", "|"))] = cells[1]
    return rows


@dataclass(frozen=True)
class Run:
    """A command line (``{name}``: a place of the ``places`` fixture) and how it is run:
    ``main`` in-process; ``SIGINT``/``SIGTERM`` sent to a process once it printed a line
    (on stdout, or with ``ready`` on stderr); ``pipe``: its stdout closed after a line;
    ``lost``: its simulator closed after a line. ``hint``: whether the error ends with
    ``Try '... -h'.`` (None: not checked)."""

    args: tuple[str, ...]
    how: str = "main"
    hint: bool | None = None
    ready: str = ""


def run(*args: str, **kw: Any) -> Run:
    return Run(args, **kw)


#: The table's examples, each with the command lines that show it.
CASES: dict[tuple[int, str], list[Run]] = {
    (0, "a command that finishes"): [
        run("dump", "pioneer", "--file", str(ROOT / "examples" / "pioneer_drive.jsonl")),
        run("traj", "circle", "-o", "{tmp}/sim.json", "--overwrite"),
    ],
    (0, "`--count`, `--once` or `--duration` reached"): [
        run("connect", "pioneer", "sim", "--once", "--json"),
        run("dump", "arm", "sim", "--count", "3"),
        run("monitor", "arm", "sim", "--duration", "0.5", "-o", "{tmp}/real.json"),
    ],
    (0, "its reader leaves (`| head`)"): [run("dump", "pioneer", "sim", how="pipe")],
    (1, "a capture without a packet, or 16 MiB in a row without one"): [
        run("dump", "pioneer", "--file", "{tmp}/empty.bin"),
        run("dump", "pioneer", "--file", "/dev/zero"),
        run("dump", "arm", "--file", "/dev/zero"),
    ],
    (1, "a server's port already in use (`sim`, `serve`, `dump --listen`)"): [
        run("sim", "pioneer", "--port", "{busy}"),
        run("sim", "abb", "--motion-port", "0", "--state-port", "{busy}"),
        run("serve", "--port", "{busy}"),
        run("dump", "arm", "sim", "--listen", "{busy}"),
        run("dump", "hub", "127.0.0.1:{silent}", "--listen", "127.0.0.1:{busy}"),
    ],
    (1, "a link lost in the middle of a session"): [
        run("connect", "pioneer", "{url}", "--json", how="lost"),
    ],
    (1, "`upload --wait` runs out while the arm moves"): [
        run("upload", "arm", "sim", "--shape", "circle", "--wait", "0.5", hint=False),
    ],
    (2, "an unknown option, or a bad value, URL or port"): [
        run("connect", "pioneer", "sim", "--frobnicate", hint=True),
        run("connect", "pioneer", "tcp://127.0.0.1:99999", hint=True),
        run("subscribe", "adc", "--rate", "10", "--format", "xml", hint=True),
        run("sim", "pioneer", "--port", "70000", hint=True),
    ],
    (2, "a `--bind` or `--listen` address that is not this machine's, or no address at all"): [
        run("sim", "pioneer", "--port", "0", "--bind", "192.0.2.1", hint=True),
        run("sim", "abb", "--motion-port", "0", "--state-port", "0", "--bind", "a..b", hint=True),
        run("serve", "--port", "0", "--bind", "192.0.2.1", hint=True),
        run("dump", "arm", "sim", "--listen", "192.0.2.1:0", hint=True),
    ],
    (2, "the same `--motion-port` and `--state-port`"): [
        run("sim", "abb", "--motion-port", "{free}", "--state-port", "{free}", hint=True),
    ],
    (2, "an output folder that does not exist (said before connecting or moving)"): [
        run("dump", "pioneer", "sim", "-o", "{tmp}/missing/x.jsonl", hint=False),
        run("dump", "arm", "sim", "-o", "{tmp}/missing/x.jsonl", hint=False),
        run("dump", "hub", "127.0.0.1:{free}", "-o", "{tmp}/missing/x.jsonl", hint=False),
        run("monitor", "arm", "127.0.0.1", "--state-port", "{free}", "--duration", "1",
            "-o", "{tmp}/missing/x.json", hint=False),
        run("upload", "arm", "127.0.0.1", "--motion-port", "{free}",
            "--shape", "circle", "--output", "{tmp}/missing/x.json", hint=False),
        run("traj", "circle", "-o", "{tmp}/missing/x.json", hint=False),
    ],
    (2, "an output file that exists (without `--overwrite`) or is a symbolic link (said before "
        "connecting, and nothing is written through a link)"): [
        run("record", "--pioneer", "sim", "-o", "{tmp}/old.mcap", hint=False),
        run("dump", "hub", "127.0.0.1:{free}", "-o", "{tmp}/old.jsonl", hint=False),
        run("traj", "circle", "-o", "{tmp}/sim.json", hint=False),
        run("upload", "arm", "sim", "--shape", "circle", "--record", "{tmp}/link.mcap",
            "--overwrite", hint=False),
    ],
    (2, "a file that cannot be read, or malformed (map, log, waypoints)"): [
        run("validate", "{tmp}/nan.json", "{tmp}/nan.json", hint=False),
        run("validate", "{tmp}/none.json", "{tmp}/sim.json", hint=False),
        run("sim", "pioneer", "--port", "0", "--map", "{tmp}/map.json", hint=False),
        run("traj", "file", "{tmp}/nan.json", hint=False),
    ],
    (2, "an unreachable trajectory point"): [
        run("traj", "ptp-cartesian", "--to", "5,5,5", "-o", "{tmp}/far.json", hint=False),
    ],
    (3, "nobody listening (connection refused)"): [
        run("connect", "pioneer", "tcp://127.0.0.1:{free}", hint=False),
        run("connect", "arm", "127.0.0.1", "--state-port", "{free}", hint=False),
        run("subscribe", "adc", "--rate", "10", "--hub", "127.0.0.1:{free}", hint=False),
    ],
    (3, "no answer within `--timeout`"): [
        run("connect", "pioneer", "127.0.0.1:{silent}", "--timeout", "0.5", hint=False),
    ],
    (3, "a serial port that does not exist"): [
        run("connect", "pioneer", "/dev/ttyROBOCLI_NONE", hint=False),
    ],
    (4, "robot busy: another client holds it"): [
        run("connect", "pioneer", "{held}", "--once", hint=False),
    ],
    (130, "Ctrl-C (SIGINT) or SIGTERM, to any command (clients stop the robot, recorders write "
          "what they have, simulators and `serve` close every connection), said in one line: "
          "`robocli: interrupted`"): [
        run("sim", "pioneer", "--port", "0", how="SIGINT"),
        run("sim", "pioneer", "--port", "0", how="SIGTERM"),
        run("sim", "abb", "--motion-port", "0", "--state-port", "0", how="SIGINT"),
        run("sim", "abb", "--motion-port", "0", "--state-port", "0", how="SIGTERM"),
        run("serve", "--sim", "--port", "0", how="SIGINT"),
        run("serve", "--sim", "--port", "0", how="SIGTERM"),
        run("connect", "pioneer", "sim", "--json", how="SIGINT"),
        run("dump", "pioneer", "sim", how="SIGTERM"),
        run("-v", "monitor", "arm", "sim", "--duration", "600", "-o", "{tmp}/ctrl-c.json",
            how="SIGINT", ready="connected"),
    ],
}  # fmt: skip


def _cases() -> Iterator[Any]:
    for key in sorted(readme_table().keys() | CASES.keys()):
        for i, case in enumerate(CASES.get(key) or [None]):
            yield pytest.param(key, case, id=f"{key[0]}-{key[1][:40]}-{i}")


@pytest.fixture(scope="module")
def places(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """A free port, a busy one, a silent server (accepts, never answers), a Pioneer
    simulator held by a client, and files."""
    from robocli import Pioneer
    from robocli.sim.pioneer.server import PioneerSim

    tmp = tmp_path_factory.mktemp("exit-codes")
    (tmp / "empty.bin").write_bytes(b"")
    (tmp / "nan.json").write_text('{"time": [0, 1], "joints_positions": [[0, 0, 0, 0, 0, NaN], '
                                  '[0, 0, 0, 0, 0, 0]]}')  # fmt: skip
    (tmp / "map.json").write_text('{"walls": [[0, 0, 1]]}')
    for old in ("old.mcap", "old.jsonl"):
        (tmp / old).write_text("a user's file")
    (tmp / "link.mcap").symlink_to(tmp / "old.mcap")
    assert main(["traj", "circle", "-o", str(tmp / "sim.json")]) == 0
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        free = s.getsockname()[1]  # nobody listens there once this socket is closed
    busy = socket.create_server(("127.0.0.1", 0))
    silent = socket.create_server(("127.0.0.1", 0))
    held_conns: list[socket.socket] = []

    def accept() -> None:
        while True:
            try:
                held_conns.append(silent.accept()[0])
            except OSError:
                return

    threading.Thread(target=accept, daemon=True).start()
    sim = PioneerSim()
    held = sim.serve_tcp("127.0.0.1", 0)
    holder = Pioneer.connect(held)
    try:
        yield {"tmp": tmp, "free": free, "busy": busy.getsockname()[1],
               "silent": silent.getsockname()[1], "held": held}  # fmt: skip
    finally:
        holder.close()
        sim.close()
        for s in (busy, silent, *held_conns):
            s.close()


def _process(args: list[str]) -> subprocess.Popen[str]:
    return subprocess.Popen([*ROBOCLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, text=True)  # fmt: skip


def _wait_for(stream: Any, needle: str) -> None:
    """Read ``stream`` until a line holding ``needle`` (any line for "")."""
    for line in stream:
        if needle in line:
            return
    raise AssertionError(f"the process ended without printing {needle!r}")


def _run(case: Run, places: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """(exit code, stderr) of ``case``."""
    args = [a.format(url="{url}", **places) for a in case.args]
    if case.how == "main":
        code = main(args)
        return code, capsys.readouterr().err
    if case.how == "lost":
        from robocli.sim.pioneer.server import PioneerSim

        sim = PioneerSim()
        try:
            url = sim.serve_tcp("127.0.0.1", 0)
            proc = _process([a.replace("{url}", url) for a in args])
            assert proc.stdout is not None
            _wait_for(proc.stdout, "")
        finally:
            sim.close()
    else:
        proc = _process(args)
        assert proc.stdout is not None and proc.stderr is not None
        if case.how == "pipe":
            _wait_for(proc.stdout, "")
            proc.stdout.close()  # like `| head -1`
        else:
            _wait_for(proc.stderr if case.ready else proc.stdout, case.ready)
            proc.send_signal(getattr(signal, case.how))
    try:
        _, err = proc.communicate(timeout=TIMEOUT)
    except ValueError:  # stdout closed by us
        proc.wait(TIMEOUT)
        err = proc.stderr.read() if proc.stderr else ""
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(TIMEOUT)
    return proc.returncode, err


@pytest.mark.parametrize(("row", "case"), list(_cases()))
def test_the_readme_exit_code_table(row: tuple[int, str], case: Run | None, places: dict[str, Any],
                                    capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    code, example = row
    assert row in readme_table(), f"{example!r}: a command line here, no such example there"
    assert case is not None, f"{example!r}: an example in the table with no command line here"
    got, err = _run(case, places, capsys)
    lines = err.strip().splitlines()
    assert got == code, f"{case.args}: exit {got}, the manual says {code}: {err}"
    assert "Traceback" not in err
    if code == 0:
        assert lines == [] or case.how == "main", err
        return
    assert lines and lines[-1].startswith("robocli: "), err
    if code == 130:
        assert lines[-1] == "robocli: interrupted" and (case.ready or len(lines) == 1), err
        return
    assert len(lines) == 1, err
    if case.hint is not None:
        assert lines[0].endswith(" -h'.") == case.hint, lines[0]


def test_a_recorder_writes_what_it_has_on_ctrl_c(tmp_path: Path) -> None:
    """``monitor arm`` on Ctrl-C: the log is written (said on stderr), then exit 130."""
    from robocli.sim.abb.server import AbbSim

    out = tmp_path / "m.json"
    with AbbSim(state_ms=5.0) as sim:
        state_port = sim.serve_tcp("127.0.0.1", 0, 0)[1].rsplit(":", 1)[1]
        proc = _process(["monitor", "arm", "127.0.0.1", "--state-port", state_port,
                         "--duration", "600", "-o", str(out)])  # fmt: skip
        try:
            sim.wait_until(lambda s: s.state_accepted, TIMEOUT)
            sent = sim.snapshot().states_sent
            sim.wait_until(lambda s: s.states_sent >= sent + 100, TIMEOUT)  # 0.5 s of states
            _, err = ctrl_c(proc, TIMEOUT)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(TIMEOUT)
    lines = err.strip().splitlines()
    assert proc.returncode == 130 and lines[-1] == "robocli: interrupted", err
    assert lines[0].startswith("recorded ") and len(json.loads(out.read_text())["time"]) >= 2
