"""The settings queryable under fuzzed requests, over a real Zenoh session: every request
gets a reply, and a refused one changes neither the sensor's settings nor its publishing
(issue 21, point 6: ``"channels": []`` stopped the ADC, ``1e400`` got no reply, an
OverflowError escaped on every sensor and refused requests still changed settings)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robocli.zenoh import open_session
from robocli.zenoh.keys import settings_key
from robocli.zenoh.session import close_session
from tests.hub_server.test_hub_zenoh import Lab
from tests.peers import free_endpoint
from tests.waiting import wait_for

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")

SENSORS = ("adc", "imu", "battery", "gps", "camera", "sysinfo", "laser", "depth", "stereo")
QUIET = {"freq_acquisition": 20, "fps": 10, "fps_rgb": 10, "width": 32, "height": 24,
         "width_rgb": 32, "height_rgb": 24}  # fmt: skip
"""Settings every sensor takes, light enough to keep all nine running in a test."""

BAD = st.sampled_from([1e400, 10**400, -(10**400), [], [1], {}, "x", "", None, True, -1])
"""What the fuzzer of issue 21 found refused badly (an OverflowError, a TypeError)."""
VALUES = st.one_of(
    BAD, st.none(), st.booleans(), st.integers(-(2**70), 2**70), st.integers(-3, 3000),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e400, 10**400, 1e308]),
    st.text(max_size=4), st.lists(st.integers(0, 9), max_size=2),
    st.dictionaries(st.text(max_size=2), st.integers(), max_size=1),
)  # fmt: skip
RATES = st.fixed_dictionaries({k: st.sampled_from([10, 15, 20]) for k in QUIET if "fps" in k
                               or k == "freq_acquisition"})  # fmt: skip
"""Valid rates, drawn: a request that sets one then fails on another key must change none."""
_IMAGE = ("fps", "width", "height", "compression")
KEYS_OF = {**{s: ("freq_acquisition", "freq_send") for s in SENSORS},
           "adc": ("freq_acquisition", "freq_send", "channels"), "camera": _IMAGE,
           "stereo": _IMAGE, "depth": tuple(f"{k}_rgb" for k in _IMAGE)}  # fmt: skip
"""The keys each sensor reads (others are ignored, which the fuzzer need not try much)."""


def requests(sensor: str) -> st.SearchStrategy[dict[str, Any]]:
    """A settings request for ``sensor``: mostly its own keys with odd values, over a base
    of valid drawn rates (a request that sets a rate then fails on another key must change
    nothing), sometimes ``params`` that is not an object at all."""
    keys = st.sampled_from((*KEYS_OF[sensor], "freq_acquisition", "id", "zz"))
    params = st.dictionaries(keys, st.one_of(BAD, VALUES), min_size=1, max_size=3)
    return st.fixed_dictionaries({"params": params, "rates": RATES})


def known_faults(sensor: str) -> list[dict[str, Any]]:
    """What issue 21's fuzzer and users sent: each of the sensor's keys with a value JSON
    allows and the sensor cannot take, and ``params`` that is no object."""
    odd: list[Any] = [10**400, 1e400, [], "x", {"a": 1}]
    return [{"params": {k: v}, "rates": {"freq_acquisition": 15, "fps": 15, "fps_rgb": 15}}
            for k in KEYS_OF[sensor] for v in odd] + [
        {"params": p, "rates": {}} for p in ([], 1e400, "x", None)]  # fmt: skip


class Asker:
    """A client session asking the lab's settings queryable."""

    def __init__(self, lab: Lab) -> None:
        self.lab = lab
        self.session = open_session(lab.endpoint, "client")

    def ask(self, sensor: str, request: Any) -> list[Any]:
        """Every reply to one settings query (raw payload text: the JSON test suite's
        ``1e400`` is sent as such, not as what Python's json writes for infinity)."""
        payload = request if isinstance(request, str) else json.dumps(request)
        key = settings_key(self.lab.front.name, sensor)
        return list(self.session.get(key, payload=payload, timeout=10))

    def close(self) -> None:
        close_session(self.session)


@pytest.fixture(scope="module")
def lab_and_asker() -> Iterator[tuple[Lab, Asker]]:
    lab = Lab(free_endpoint(), **{s: QUIET for s in SENSORS})
    asker = Asker(lab)
    try:
        yield lab, asker
    finally:
        asker.close()
        lab.close()


def _still_published(lab: Lab, sensor: str) -> None:
    before = lab.published(sensor)
    wait_for(
        lambda: lab.published(sensor) > before,
        f"{sensor} published after a refused request",
    )  # fmt: skip


@pytest.mark.parametrize(
    "payload",
    [
        '{"params": {"channels": []}}',
        '{"params": {"channels": 1e400}}',
        '{"params": {"freq_acquisition": 7, "channels": "x"}}',
    ],
)
def test_a_refused_adc_request_is_answered_and_changes_nothing(
    lab_and_asker: tuple[Lab, Asker], payload: str
) -> None:
    lab, asker = lab_and_asker
    before = lab.server.sensors["adc"]
    replies = asker.ask("adc", payload)
    assert len(replies) == 1 and replies[0].err is not None
    assert "error" in json.loads(replies[0].err.payload.to_bytes())
    assert lab.server.sensors["adc"] == before
    _still_published(lab, "adc")


@pytest.mark.parametrize("sensor", SENSORS)
def test_fuzzed_settings_are_answered_and_a_refusal_changes_nothing(
    lab_and_asker: tuple[Lab, Asker], sensor: str
) -> None:
    lab, asker = lab_and_asker

    def probe(request: dict[str, Any]) -> None:
        params = request["params"]
        if isinstance(params, dict):  # keep what is accepted light: all nine keep running
            base = {**QUIET, **request["rates"]}
            params = {**params, **{k: v for k, v in base.items() if k not in params}}
        before = lab.server.sensors[sensor]
        replies = asker.ask(sensor, {"params": params})
        assert len(replies) == 1, f"{len(replies)} replies to {params}"
        if replies[0].err is not None:
            assert lab.server.sensors[sensor] == before, params
            _still_published(lab, sensor)
        else:
            assert json.loads(replies[0].ok.payload.to_bytes())

    for request in known_faults(sensor):
        probe(request)
    fuzz = settings(
        max_examples=10,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=list(HealthCheck),
    )(given(requests(sensor))(probe))
    fuzz()
    assert lab.front.info()["sensors"][sensor]["published"]
