"""Run one fuzz harness with atheris: ``python fuzz/run.py TARGET [libFuzzer options]``.

Targets: ``framer-arcos``, ``framer-sm-le``, ``framer-sm-be``, ``framer-ros4mat``,
``framer-scip2`` (the C framers against the reference framer), ``framer-scip2-requests``
(the Hokuyo simulator's request framer against an oracle), ``decode-arcos``,
``decode-simple_message``, ``decode-ros4mat`` (the Python protocol decoders),
``decode-scip2`` (the C scan decoder against the pure-Python one, and the SCIP parsers),
``decode-hub-reply`` (the hub client's whole receive path: framing, inflation, records, JPEG
frames, clock mapping),
``hub-server-requests`` (a hub server session fed one client's bytes, in-process),
``capture-readers`` (``.jsonl`` and raw capture files), ``file-readers`` (trajectory logs,
waypoints, robot models), ``recording-readers`` (every command that opens an MCAP
recording, and ``recover``) and ``create-oi`` (the Create 2 command framer against an
oracle, each command into the simulator's OI in-process). ``list`` prints them. Example::

    python fuzz/run.py decode-ros4mat -max_total_time=600

``make fuzz FUZZ_SECONDS=600`` runs every target for that long; CI runs each for 30 s.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import harness

NAMES = (
    "framer-arcos",
    "framer-sm-le",
    "framer-sm-be",
    "framer-ros4mat",
    "framer-scip2",
    "framer-scip2-requests",
    "decode-arcos",
    "decode-simple_message",
    "decode-ros4mat",
    "decode-scip2",
    "decode-hub-reply",
    "hub-server-requests",
    "capture-readers",
    "file-readers",
    "recording-readers",
    "create-oi",
)

#: Packages instrumented for coverage besides the protocols, by target.
INSTRUMENTED = {
    "recording-readers": (
        "robocli.io", "robocli.sim", "robocli.serving", "robocli.hub_server", "mcap"
    ),
    "create-oi": ("robocli.sim", "robocli.serving"),
}
#: libFuzzer options of a target besides :data:`harness.DEFAULTS` (recordings are larger
#: than protocol frames).
OPTIONS = {"recording-readers": {"-max_len": "65536"}}


def load(name: str) -> tuple[Callable[[bytes], None], list[bytes]]:
    """(one-input function, seed corpus) of a target (imported as they are: call it inside
    :func:`harness.instrumented` to fuzz with coverage)."""
    import fuzz_capture
    import fuzz_create
    import fuzz_decoders
    import fuzz_files
    import fuzz_framers
    import fuzz_hub
    import fuzz_recordings

    if name.startswith("framer-"):
        one_input, kinds = fuzz_framers.target(name)
        if name == "framer-scip2-requests":
            return one_input, fuzz_framers.request_seeds(harness.seeds(kinds))
        return one_input, fuzz_framers.seed_inputs(harness.seeds(kinds))
    if name in fuzz_hub.TARGETS:
        one_input, kinds = fuzz_hub.TARGETS[name]
        return one_input, fuzz_hub.seed_inputs(name, harness.seeds(kinds))
    if name in fuzz_create.TARGETS:
        return fuzz_create.fuzz_create, fuzz_create.seed_inputs()
    if name in fuzz_recordings.TARGETS:
        return fuzz_recordings.fuzz_recordings, fuzz_recordings.seed_inputs()
    if name in fuzz_files.TARGETS:
        return fuzz_files.fuzz_files, fuzz_files.seed_inputs()
    if name in fuzz_capture.TARGETS:
        one_input, kinds = fuzz_capture.TARGETS[name]
        return one_input, fuzz_capture.seed_inputs({k: harness.seeds((k,)) for k in kinds})
    one_input, kinds = fuzz_decoders.TARGETS[name]
    return one_input, fuzz_decoders.seed_inputs(name, harness.seeds(kinds))


def main() -> None:
    if len(sys.argv) < 2 or sys.argv[1] not in (*NAMES, "list"):
        raise SystemExit(f"usage: run.py TARGET [libFuzzer options]; TARGET one of {NAMES}")
    name = sys.argv.pop(1)
    if name == "list":
        print("\n".join(NAMES))
        return
    with harness.instrumented(INSTRUMENTED.get(name, ())):
        one_input, corpus = load(name)
    for seed in corpus:  # the seeds themselves must pass before fuzzing starts
        one_input(seed)
    harness.run(name, one_input, corpus, OPTIONS.get(name))


if __name__ == "__main__":
    main()
