"""The lab's counting window (robocli.bench.lab.bench.Window) on a fake clock: a counter's
rate is its increase over the time between its own two reads, however long each read takes
(an ``ip``/``tc`` process each, slow on a loaded machine). Before, the bytes counted between
the first reads and the last were divided by a clock started after the first and stopped
before the last: 26.6 MB in "10.0 s" through a 20 Mbit/s token bucket. No namespaces: this
is arithmetic."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from robocli.bench.lab.bench import LabRun, Window
from robocli.bench.lab.netns import LabError

RATE = 2.5e6  #: bytes per second: a 20 Mbit/s token bucket, full
READ_S = 0.3  #: what one counter read takes on the fake clock (a process started under load)


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def link(clock: Clock, taken_at: float = 0.5) -> Callable[[], float]:
    """A byte counter growing at :data:`RATE`; a read takes :data:`READ_S`, its value taken
    ``taken_at`` of the way through."""

    def read() -> float:
        clock.now += READ_S * taken_at
        value = RATE * clock.now
        clock.now += READ_S * (1 - taken_at)
        return value

    return read


def test_each_rate_is_over_its_own_reads_not_the_window_clock() -> None:
    clock = Clock()
    window = Window(clock)
    for i in range(3):  # three robots' uplinks, read one after the other at each end
        window.add(f"tx{i}", link(clock))
    window.start()
    began = clock.now
    clock.now += 10.0  # the counting window, as the bench sleeps it
    counted = clock.now - began
    window.end()
    for i in range(3):
        assert window.rate(f"tx{i}") == pytest.approx(RATE)  # at the bucket's rate, not over
        assert window.seconds(f"tx{i}") == pytest.approx(10.0 + 3 * READ_S)
        # what dividing by the window's own clock gave: 9 % over the bucket's rate
        assert window.delta(f"tx{i}") / counted == pytest.approx(RATE * 1.09)


@pytest.mark.parametrize("first, last", [(0.0, 1.0), (1.0, 0.0), (0.5, 0.5)])
def test_error_bounds_where_in_its_read_a_value_was_taken(first: float, last: float) -> None:
    clock = Clock()
    window = Window(clock)
    where = [first, last]

    def read() -> float:  # the value taken at `first` of the way through at the start, ...
        return link(clock, where.pop(0))()

    window.add("tx", read)
    window.start()
    clock.now += 10.0
    window.end()
    assert window.error() == pytest.approx(READ_S / (10.0 + READ_S))
    assert abs(window.rate("tx") / RATE - 1) <= window.error() + 1e-12


def test_a_counter_read_at_one_end_only_is_an_error() -> None:
    window = Window(Clock())
    window.add("tx", lambda: 0.0)
    with pytest.raises(LabError, match="not at both ends"):
        window.rate("tx")
    window.start()
    with pytest.raises(LabError, match="not at both ends"):
        window.delta("tx")
    window.end()
    with pytest.raises(LabError, match="0 s apart"):  # a clock that stood still
        window.rate("tx")


def test_the_busiest_uplink_is_each_robots_bytes_over_its_own_window() -> None:
    run = LabRun("tcp", 2, 4, seconds=10.0, uplink_mbit=20.0,
                 uplink_bytes=[26_600_000, 20_000_000], uplink_seconds=[10.9, 8.0])  # fmt: skip
    assert run.uplink_mbit_s == pytest.approx(20e6 * 8 / 8.0 / 1e6)
    assert run.as_dict()["uplink_mbit_s"] == run.uplink_mbit_s
