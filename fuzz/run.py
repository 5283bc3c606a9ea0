"""Run one fuzz harness with atheris: ``python fuzz/run.py TARGET [libFuzzer options]``.

Targets: ``framer-arcos``, ``framer-sm-le``, ``framer-sm-be``, ``framer-ros4mat`` (the C
framers against the reference framer) and ``decode-arcos``, ``decode-simple_message``,
``decode-ros4mat`` (the Python decoders). ``list`` prints them. Example::

    python fuzz/run.py decode-ros4mat -max_total_time=600

``make fuzz FUZZ_SECONDS=600`` runs every target for that long; CI runs each for 30 s.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import harness  # noqa: E402

NAMES = (
    "framer-arcos",
    "framer-sm-le",
    "framer-sm-be",
    "framer-ros4mat",
    "decode-arcos",
    "decode-simple_message",
    "decode-ros4mat",
)


def main() -> None:
    if len(sys.argv) < 2 or sys.argv[1] not in (*NAMES, "list"):
        raise SystemExit(f"usage: run.py TARGET [libFuzzer options]; TARGET one of {NAMES}")
    name = sys.argv.pop(1)
    if name == "list":
        print("\n".join(NAMES))
        return
    with harness.instrumented():
        import fuzz_decoders
        import fuzz_framers
    if name.startswith("framer-"):
        one_input, kinds = fuzz_framers.target(name)
        corpus = fuzz_framers.seed_inputs(harness.seeds(kinds))
    else:
        one_input, kinds = fuzz_decoders.TARGETS[name]
        corpus = fuzz_decoders.seed_inputs(name, harness.seeds(kinds))
    for seed in corpus:  # the seeds themselves must pass before fuzzing starts
        one_input(seed)
    harness.run(name, one_input, corpus)


if __name__ == "__main__":
    main()
