"""Fuzz harness of the MCAP readers: every command that opens a recording (``info``,
``export``, ``dump --file``, ``validate``'s arm log, ``sim pioneer``/``sim abb``/``serve``
``--replay``, ``plot``) and ``recover``.

The option byte picks the reader (run as the CLI runs it, in this process); the rest is
the recording. The seeds are small valid recordings
made by robocli's own :class:`~robocli.io.record.Recorder` from the built-in simulators (a
Pioneer with its laser in each compression, an arm, a hub), whole and cut in the middle as a
kill leaves them, made once per process. Reading must return or raise a
:class:`robocli.errors.RobocliError` (at the CLI: exit 0, 1 or 2, no traceback); a file that
``recover`` rewrote must be read whole by the ``mcap`` package's own reader, summary
included. Anything else is a finding.
"""

from __future__ import annotations

import contextlib
import functools
import io
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from harness import scratch
from mcap.reader import make_reader

from robocli.cli import main
from robocli.errors import RobocliError
from robocli.hub_server.sources.replay import replay_sources
from robocli.io.record import Recorder, info, recover
from robocli.io.record.replay import RecordedPackets
from robocli.sim.abb.replay import AbbReplay
from robocli.sim.pioneer.replay import PioneerReplay

#: The readers, by the option byte (modulo their number).
READERS = ("info", "export", "dump-arcos", "dump-sm", "dump-ros4mat", "arm-log",
           "pioneer-replay", "abb-replay", "hub-replay", "recover", "plot")  # fmt: skip


def _folder() -> Path:
    return scratch("recordings")


def cli(*args: str) -> int:
    """``robocli ARGS`` in this process, its output discarded: its exit code. A traceback
    (an exception that is not a robocli error) escapes."""
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        code = main(list(args))
    assert code in (0, 1, 2), (args, code, sink.getvalue()[-300:])
    return code


def read(reader: str, path: Path, out: Path) -> None:
    """Run ``reader`` on the recording at ``path`` (``out``: a folder for what it writes):
    the CLI's own commands where they only read, the replays' constructors."""
    p = str(path)
    if reader == "info":
        cli("info", p)
        cli("info", p, "--json")
    elif reader == "export":
        cli("export", p, "-f", "csv", "-o", str(out))
    elif reader.startswith("dump-"):
        device = {"arcos": "pioneer", "sm": "arm", "ros4mat": "hub"}[reader[5:]]
        cli("dump", device, "--file", p, "--json")
    elif reader == "arm-log":
        cli("export", p, "-f", "irb120-json", "-o", str(out))
    elif reader == "pioneer-replay":
        PioneerReplay(RecordedPackets(path)).close()
    elif reader == "abb-replay":
        AbbReplay(RecordedPackets(path)).close()
    elif reader == "hub-replay":
        replay_sources(path)
    elif reader == "recover":
        _recover(path, out / "recovered.mcap")
    else:
        _plot(path, out / "plot.png")


def _recover(path: Path, out: Path) -> None:
    """Recover, then read the output with the ``mcap`` package: whole, with its summary."""
    if cli("recover", str(path), "-o", str(out)) != 0:
        return
    stats = recover(path, out, overwrite=True)
    with out.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None, "no summary"
        assert summary.statistics.message_count == stats.messages, (summary.statistics, stats)
        assert sum(1 for _ in reader.iter_messages()) == stats.messages


def _plot(path: Path, out: Path) -> None:
    """A path (a pose and the scans) if the file has a pose channel, else joint states."""
    try:
        channels = info(path).channels
    except RobocliError:
        return
    paths = [c.topic for c in channels if c.schema in ("foxglove.PoseInFrame",
                                                       "foxglove.LaserScan")]  # fmt: skip
    joints = [c.topic for c in channels if c.schema == "robocli.JointState"]
    topics = paths or joints
    if topics:
        cli("plot", str(path), "-o", str(out), *(a for t in topics for a in ("-c", t)))


def fuzz_recordings(data: bytes) -> None:
    """Option byte (the reader), then the recording's bytes."""
    if not data:
        return
    reader = READERS[data[0] % len(READERS)]
    folder = _folder()
    path, out = folder / "input.mcap", folder / "out"
    path.write_bytes(data[1:])
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    try:
        read(reader, path, out)
    except RobocliError:
        pass


def _record(name: str, make: Callable[[Any], None], **options: Any) -> bytes:
    """The bytes of a recording made by ``make(recorder)``."""
    path = _folder() / f"seed-{name}.mcap"
    with Recorder(path, chunk_size=1024, chunk_seconds=0.05, overwrite=True, **options) as rec:
        make(rec)
    return path.read_bytes()


def _pioneer(url: str) -> Callable[[Any], None]:
    def make(rec: Any) -> None:
        from robocli.devices.pioneer import Pioneer

        listener = rec.listener("pioneer", "arcos")
        with Pioneer.connect(url, listeners=[listener], laser=True) as robot:
            rec.add(robot, listener.name)
            robot.set_velocity(0.2, 0.1)
            for _ in range(3):
                robot.wait_for_sip()
            robot.sim.wait_for_laser(10.0)

    return make


def _arm(motion: int, state: int) -> Callable[[Any], None]:
    def make(rec: Any) -> None:
        from robocli.devices.arm import Arm

        with Arm.connect("127.0.0.1", motion, state) as arm:
            samples: list[Any] = []
            arm.add_listener(samples.append, kind="samples")
            rec.add(arm)
            while sum(s.source == "joint_feedback" for s in samples) < 4:
                arm.wait_for_state(5.0)

    return make


def _hub(port: int) -> Callable[[Any], None]:
    def make(rec: Any) -> None:
        from robocli.devices.hub.client import Hub

        with Hub.connect(f"127.0.0.1:{port}") as hub:
            rec.add(hub, sensors=("imu",))
            hub.subscribe("imu", rate=200)
            got, deadline = 0, time.monotonic() + 30
            while got < 4 and time.monotonic() < deadline:  # pulls poll: a short wait each
                got += len(hub.read("imu"))
                time.sleep(0.01)

    return make


@functools.lru_cache(maxsize=1)
def recordings() -> dict[str, bytes]:
    """Small recordings by robocli's recorder, by name (made once per process)."""
    from robocli.hub_server import HubServer
    from robocli.sim.abb.server import AbbSim
    from robocli.sim.pioneer.server import PioneerSim

    out: dict[str, bytes] = {}
    with PioneerSim("p3dx", time_scale=5.0) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        for compression in ("zstd", "lz4", "none"):
            out[f"pioneer-{compression}"] = _record("pioneer", _pioneer(url),
                                                    compression=compression)  # fmt: skip
    with AbbSim("irb120", state_ms=5.0, feedback=True) as abb:
        motion, state = abb.serve_tcp("127.0.0.1", 0, 0)
        out["arm"] = _record("arm", _arm(int(motion.rsplit(":", 1)[1]),
                                         int(state.rsplit(":", 1)[1])))  # fmt: skip
    with HubServer(port=0, sim=True) as hub:
        out["hub"] = _record("hub", _hub(hub.port))
    return out


#: The readers each seed recording is given first (libFuzzer mutates the option byte too).
_SEED_READERS = {
    "pioneer": ("info", "export", "dump-arcos", "pioneer-replay", "recover", "plot"),
    "arm": ("info", "arm-log", "abb-replay", "dump-sm", "recover"),
    "hub": ("info", "hub-replay", "dump-ros4mat", "recover"),
}


def seed_inputs() -> list[bytes]:
    """Each recording, whole and cut in its middle, for each of its readers."""
    seeds = []
    for name, data in recordings().items():
        for reader in _SEED_READERS[name.split("-")[0]]:
            option = bytes((READERS.index(reader),))
            seeds += [option + data, option + data[: len(data) // 2]]
    return seeds


TARGETS: dict[str, tuple[Callable[[bytes], None], tuple[str, ...]]] = {
    "recording-readers": (fuzz_recordings, ()),
}
