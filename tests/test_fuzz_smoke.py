"""The fuzz harnesses of fuzz/ stay runnable without atheris: each one passes its golden
seeds and a bounded hypothesis run (the real fuzzing is ``make fuzz``)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "fuzz"))
# The harnesses import the reference models as `reference`, with tests/ on the path as
# fuzz/harness.py puts it; appended, so that no folder of tests/ hides an installed package.
sys.path.append(str(Path(__file__).resolve().parent))

import fuzz_capture
import fuzz_create
import fuzz_decoders
import fuzz_files
import fuzz_framers
import fuzz_hub
import fuzz_recordings
import reference  # the very module the harnesses import, which a test patches
import run

ROOT = Path(__file__).resolve().parent.parent


def _harness(name: str) -> tuple[Callable[[bytes], None], list[bytes]]:
    return run.load(name)


def test_every_target_is_runnable() -> None:
    modules = (fuzz_framers, fuzz_decoders, fuzz_hub, fuzz_capture, fuzz_files, fuzz_recordings,
               fuzz_create)  # fmt: skip
    assert set(run.NAMES) == set().union(*(m.TARGETS for m in modules))


def test_make_fuzz_runs_every_target() -> None:
    """CI's `make fuzz` runs the targets of its FUZZ_TARGETS line: all of them."""
    text = (ROOT / "Makefile").read_text().replace("\\\n", " ")
    line = next(x for x in text.splitlines() if x.startswith("FUZZ_TARGETS"))
    assert line.split(":=", 1)[1].split() == list(run.NAMES)


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
