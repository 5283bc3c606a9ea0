"""The fuzz harnesses of fuzz/ stay runnable without atheris: each one passes its golden
seeds and a bounded hypothesis run (the real fuzzing is ``make fuzz``)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import pytest
import reference
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "fuzz"))

import fuzz_decoders  # noqa: E402
import fuzz_framers  # noqa: E402
import run  # noqa: E402

GOLDEN = reference.golden_frames()


def _harness(name: str) -> tuple[Callable[[bytes], None], list[bytes]]:
    if name.startswith("framer-"):
        one_input, kinds = fuzz_framers.target(name)
        frames = [f for k, _, f in GOLDEN if k in kinds]
        return one_input, fuzz_framers.seed_inputs(frames)
    one_input, kinds = fuzz_decoders.TARGETS[name]
    frames = [f for k, _, f in GOLDEN if k in kinds]
    return one_input, fuzz_decoders.seed_inputs(name, frames)


def test_every_target_is_runnable() -> None:
    assert set(run.NAMES) == set(fuzz_framers.TARGETS) | set(fuzz_decoders.TARGETS)


@pytest.mark.parametrize("name", run.NAMES)
def test_harness_passes_its_seeds(name: str) -> None:
    one_input, seeds = _harness(name)
    assert len(seeds) >= 10
    for seed in seeds:
        one_input(seed)


@pytest.mark.parametrize("name", run.NAMES)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_harness_on_random_inputs(name: str, data: st.DataObject) -> None:
    one_input, seeds = _harness(name)
    seed = data.draw(st.sampled_from(seeds))
    cut = data.draw(st.integers(0, len(seed)))
    one_input(seed[:cut] + data.draw(st.binary(max_size=64)) + seed[cut:])


def test_framer_harness_detects_a_difference(monkeypatch: pytest.MonkeyPatch) -> None:
    """The differential oracle can fail: a reference framer that drops frames is caught."""
    one_input, seeds = _harness("framer-arcos")
    monkeypatch.setattr(reference.RefFramer, "feed", lambda self, data: [])
    with pytest.raises(AssertionError):
        one_input(seeds[0])
