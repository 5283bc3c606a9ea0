"""``robocli subscribe``, ``connect hub``, ``bench throughput``:
thin layers over :mod:`robocli.devices.hub.client` and :mod:`robocli.bench.hub`."""

from __future__ import annotations

import sys
import time
from collections import deque
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands import _common as common
from robocli.commands import _options as opt
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt
from robocli.commands._options import SENSOR_NAMES
from robocli.commands._zenoh import zenoh_option, zenoh_target
from robocli.defaults import HUB_ENV
from robocli.errors import EXIT_INTERRUPTED
from robocli.views.hub import header_text, rows_text

if TYPE_CHECKING:
    import numpy as np

    from robocli.devices.hub.client import Hub

HUB_HELP = "Hub address HOST[:PORT] (default 127.0.0.1; port 1500)."
HubOpt = opt.device_option("--hub", HUB_HELP, show_default=False, envvar=HUB_ENV, show_envvar=True)
HubArg = opt.device_argument("hub", HUB_ENV)
TOKEN_ENV = "ROBOCLI_HUB_TOKEN_FILE"
SENSOR_HELP = ", ".join(SENSOR_NAMES)
TokenOpt = typer.Option(
    None, "--token-file", envvar=TOKEN_ENV, dir_okay=False, metavar="FILE",
    show_envvar=False, show_default=False,
    help=f"The hub's token (serve --token-file), needed to change settings or use a serial "
    f"port on a hub that has one (default ${TOKEN_ENV}).",
)  # fmt: skip


def _address(hub: str | None) -> str:
    return hub or "127.0.0.1"  # --hub, else $ROBOCLI_HUB (Typer reads it), else this machine


def open_hub(address: str, *, compress: bool = False, timeout: float = 5.0,
             token_file: Path | None = None, hub_option: bool = True,
             listeners: Iterable[Any] = ()) -> Hub:  # fmt: skip
    """Connect (with the token in ``token_file``, if any); "nobody listens" is one line with
    a hint (exit 3). ``hub_option``: the address came from --hub / $ROBOCLI_HUB.
    ``listeners``: see every frame from CONNECT on (a recorder's raw link)."""
    from robocli.commands.serve import token_from_file
    from robocli.devices.hub.client import Hub, parse_hub
    from robocli.errors import TransportError
    from robocli.transports import InvalidURL

    token = token_from_file(token_file)
    host, port = parse_hub(address)
    try:
        return Hub.connect(host, port, compress=compress, timeout=timeout, token=token,
                           listeners=listeners)  # fmt: skip
    except InvalidURL:
        raise
    except TransportError as exc:
        if not hub_option or type(exc) is not TransportError:
            raise
        raise TransportError(f"{exc} (or give --hub HOST[:PORT] / $ROBOCLI_HUB)") from None


def _open(hub: str | None, zenoh: str | None, *, compress: bool, token_file: Path | None) -> Hub:
    """The hub ``--hub`` names over ros4mat TCP, or with ``--zenoh`` on Zenoh."""
    if zenoh is None:
        return open_hub(_address(hub), compress=compress, token_file=token_file)
    from robocli.commands.serve import token_from_file
    from robocli.devices.hub.over_zenoh import ZenohHub

    if compress:
        raise typer.BadParameter("--compress is for ros4mat TCP; Zenoh sends batches as is")
    return ZenohHub.connect(hub, zenoh=zenoh_target(zenoh), token=token_from_file(token_file))


def _mask(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        raise typer.BadParameter(f"--channels: {text!r} is not a number (255, 0xff)") from None
    if not 0 < value <= 0xFF:
        raise typer.BadParameter(f"--channels: {text} is not an 8-bit mask with a channel set")
    return value


def subscribe(
    sensor: opt.SensorName = typer.Argument(..., metavar="SENSOR", show_default=False,
                                            help=f"The sensor: {SENSOR_HELP}."),  # fmt: skip
    rate: int = opt.rate_option(..., "Sample rate, Hz.", min=1, max=65535),
    hub: str | None = HubOpt,
    buffer: int | None = typer.Option(None, "--buffer", min=1,
                                      help="Samples the hub keeps for us (default: 1 s)."),
    poll: int | None = typer.Option(None, "--poll", min=1, max=65535, help="Pulls per second, Hz: "
                                    "also the hub's batch rate of adc, imu, gps, battery (ros4mat "
                                    "freqSend, at most --rate; default rate/4 + 10)."),  # fmt: skip
    channels: str = typer.Option("0xff", "--channels", help="ADC channel mask."),
    duration: float | None = opt.duration_option(min=0),
    count: int | None = opt.count_option(None, "Stop after N samples.", min=1),
    fmt: Literal["table", "csv"] | None = typer.Option(None, "--format", "-f", help="Text output "
                                                       "(default: table on a terminal, else csv)."),
    json_out: bool = opt.json_option(),
    compress: bool = opt.flag("--compress", "zlib-compressed replies."),
    token_file: Path | None = TokenOpt,
    zenoh: str | None = zenoh_option("client"),
) -> None:
    """Stream a hub sensor's timestamped samples to stdout until Ctrl-C, --duration or
    --count. Times are on this machine's clock (the hub's offset is estimated). With
    --zenoh, from a hub's Zenoh front-end (--hub NAME: which hub; default the one up)."""
    from robocli.devices.hub.streams import sample_rows
    from robocli.protocols.ros4mat import MsgType, sensor_type

    if duration is not None and count is not None:
        raise typer.BadParameter("give --duration or --count, not both")
    if json_out and fmt is not None:
        raise typer.BadParameter("give --format or --json, not both")
    shape: str = "jsonl" if json_out else fmt or ("table" if sys.stdout.isatty() else "csv")
    if sensor_type(sensor) == MsgType.KINECT_DEPTH:  # every name of SENSOR_NAMES is one
        raise typer.BadParameter(f"{sensor!r} (0x28) has no data pull in ros4mat; use depth")
    mask, out = _mask(channels), None
    with common.sigterm_as_interrupt(), common.reader_may_leave():
        try:
            with _open(hub, zenoh, compress=compress, token_file=token_file) as client:
                for batch in sample_rows(client, sensor, rate, buffer=buffer, poll=poll,
                                         channels=mask, duration=duration,
                                         count=count):  # fmt: skip
                    out = out or _Output(shape, batch.columns)  # once subscribed
                    if len(batch.rows):
                        out.write(batch.rows)
                    if batch.lost is not None:
                        typer.echo(f"robocli: {batch.lost}", err=True)
        except KeyboardInterrupt:
            raise typer.Exit(EXIT_INTERRUPTED) from None
        finally:
            if out is not None:
                out.close()


class _Output:
    """Rows as CSV, JSON lines, or a table (live on a terminal, aligned text otherwise)."""

    def __init__(self, fmt: str, cols: tuple[str, ...]) -> None:
        self.fmt, self.cols = fmt, cols
        self.rows = 0
        self.start = time.monotonic()
        self.live: Any = None
        self.recent: deque[Any] = deque(maxlen=20)
        if fmt == "table" and sys.stdout.isatty():
            from rich.live import Live

            self.live = Live(auto_refresh=False)
            self.live.start()
        else:
            self._emit(header_text(fmt, cols))

    def _emit(self, text: str) -> None:
        sys.stdout.write(text)
        sys.stdout.flush()

    def write(self, rows: np.ndarray[Any, Any]) -> None:
        self.rows += len(rows)
        if self.live is None:
            self._emit(rows_text(self.fmt, self.cols, rows))
            return
        self.recent.extend(rows.tolist())
        self._refresh()

    def _refresh(self) -> None:
        from rich.table import Table

        span = max(time.monotonic() - self.start, 1e-9)
        table = Table(
            title=f"{self.rows} samples, {self.rows / span:.1f}/s (Ctrl-C stops)",
            box=None, padding=(0, 1), collapse_padding=True, pad_edge=False,
            title_justify="left",
        )  # fmt: skip
        for c in self.cols:
            table.add_column(c, justify="right", no_wrap=True)
        rows = list(self.recent)[-max(3, self.live.console.height - 4) :]
        for row in rows:
            clock = time.strftime("%M:%S", time.localtime(row[0])) + f"{row[0] % 1:.3f}"[1:]
            table.add_row(clock, *(f"{v:.3f}" if abs(v) < 1000 else f"{v:.4g}" for v in row[1:]))
        self.live.update(table, refresh=True)

    def close(self) -> None:
        if self.live is not None:
            self.live.stop()
            self.live = None


def connect(
    host: str = HubArg,
    once: bool = opt.flag("--once", "Print one survey and exit."),
    json_out: bool = opt.json_option(),
    window: float = typer.Option(0.5, "--window", min=0.05, max=10, help="Rate window, s."),
    token_file: Path | None = TokenOpt,
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
) -> None:
    """Survey a hub over ros4mat: running sensors and their rates, round trip, clock offset,
    the client id it gave us (clients seen). Repeats every window until Ctrl-C (--json: one
    object per line; --foxglove: the running sensors' data to Foxglove, each window)."""
    from robocli.commands._live import live_view
    from robocli.devices.hub.tools import survey
    from robocli.views.hub import survey_lines

    with common.sigterm_as_interrupt(), common.reader_may_leave():
        try:
            with live_view(foxglove, foxglove_host) as view, \
                    open_hub(host, token_file=token_file, hub_option=False) as client:  # fmt: skip
                if view is not None:
                    view.add(client)
                while True:
                    info = survey(client, window, SENSOR_NAMES)
                    if json_out:  # one compact object per survey (JSON Lines)
                        common.print_json(info)
                    else:
                        common.echo_lines(survey_lines(info))
                    if once:
                        return
        except KeyboardInterrupt:
            raise typer.Exit(EXIT_INTERRUPTED) from None


def throughput(
    target: Literal["hub"] = typer.Option("hub", "--target", "-t", help="What to measure: hub."),
    url: str | None = typer.Argument(None, metavar="URL", show_default=False, help="A running "
                                     "hub: HOST[:PORT] or tcp://HOST:PORT (default: a simulated "
                                     "hub process)."),  # fmt: skip
    clients: int = typer.Option(40, "--clients", min=1, max=512, help="Clients at once."),
    sensors: str = typer.Option("imu,adc,laser,camera", "--sensors",
                                help="Sensors, comma-separated."),
    seconds: float = opt.duration_option(10.0, "Measured time, s.", min=0.5, max=3600),
    pull_hz: float = typer.Option(20.0, "--pull-hz", min=0.5, max=1000, help="Pulls/s per sensor."),
    workers: int | None = typer.Option(None, "--workers", min=1, max=64,
                                       help="Client processes (default: one per 5 clients)."),
    json_out: bool = opt.json_option(),
) -> None:
    """Many clients pulling many sensors: pulls/s, samples/s, bytes/s, p99 pull latency,
    lost samples, and the hub's CPU and peak memory (when it runs here)."""
    from robocli.bench import runs

    if target != "hub":
        raise typer.BadParameter(f"--target: only 'hub' has a throughput bench, not {target!r}")
    with common.sigterm_as_interrupt():
        try:
            report = runs.hub_throughput(url, clients, sensors, seconds, pull_hz, workers)
        except KeyboardInterrupt:
            raise typer.Exit(EXIT_INTERRUPTED) from None
    if json_out:
        common.print_json(report)
        return
    from robocli.bench.text import throughput_lines

    common.echo_lines(throughput_lines(report))
