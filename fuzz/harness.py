"""Shared start-up of the fuzz harnesses: golden-vector seeds and the atheris runner.

The seed corpus is written at start-up from ``specs/*.json`` (through the one golden-vector
loader of the test suite, ``tests/reference.py``) into a temporary folder, which libFuzzer
also uses for the inputs it finds; nothing binary is committed. Findings (crashes, hangs,
memory blow-ups) are written to ``build/fuzz/`` unless ``-artifact_prefix=`` says otherwise.
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))  # for `import reference`, once instrumentation is on

#: libFuzzer options every run gets unless the command line gives its own.
DEFAULTS = {
    "-max_len": "4096",
    "-timeout": "10",  # seconds per input: a slower input is a hang, hence a finding
    "-rss_limit_mb": "2048",  # a memory blow-up is a finding
    "-print_final_stats": "1",
}


_scratch: dict[str, tempfile.TemporaryDirectory[str]] = {}


def scratch(name: str) -> Path:
    """A temporary folder for harness ``name``'s input files, made on first use and kept
    for the process (one per harness, removed at exit)."""
    if name not in _scratch:
        _scratch[name] = tempfile.TemporaryDirectory(prefix=f"robocli-fuzz-{name}-")
    return Path(_scratch[name].name)


def seeds(kinds: Iterable[str]) -> list[bytes]:
    """The golden frames of the given framer kinds (``arcos``, ``sm-le``, ...)."""
    import reference

    wanted = set(kinds)
    frames = [frame for kind, _, frame in reference.golden_frames() if kind in wanted]
    if not frames:
        raise SystemExit(f"no golden vectors for {sorted(wanted)} in {reference.SPECS_DIR}")
    return frames


def run(
    name: str,
    test_one_input: Callable[[bytes], None],
    corpus: list[bytes],
    options: dict[str, str] | None = None,
) -> None:
    """Fuzz ``test_one_input`` with atheris (libFuzzer options from ``sys.argv[1:]``, then
    the target's ``options``, then :data:`DEFAULTS`).

    Only robocli's protocol code and the harness's reference models are instrumented for
    coverage (the C core is not: the framer harnesses compare it with the instrumented
    pure-Python reference framer instead). Any exception escaping ``test_one_input`` is a
    finding: libFuzzer writes the input and exits non-zero.
    """
    import atheris

    with tempfile.TemporaryDirectory(prefix=f"robocli-fuzz-{name}-") as tmp:
        seed_dir = Path(tmp)
        for i, frame in enumerate(corpus):
            seed_dir.joinpath(f"seed-{i:04d}").write_bytes(frame)
        artifacts = ROOT / "build" / "fuzz"
        artifacts.mkdir(parents=True, exist_ok=True)
        opts = [a for a in sys.argv[1:] if a.startswith("-")]
        given = {a.split("=", 1)[0] for a in opts}
        extra = [f"{k}={v}" for k, v in {**DEFAULTS, **(options or {})}.items() if k not in given]
        if "-artifact_prefix" not in given:
            extra.append(f"-artifact_prefix={artifacts}/{name}-")
        dirs = [a for a in sys.argv[1:] if not a.startswith("-")] or [str(seed_dir)]
        argv = [sys.argv[0], *opts, *extra, *dirs]
        print(f"fuzz {name}: {len(corpus)} seeds; {' '.join(argv[1:])}", flush=True)
        atheris.Setup(argv, test_one_input)
        atheris.Fuzz()


def instrumented(extra: Iterable[str] = ()) -> Any:
    """Context manager: robocli's protocols, construct, the reference models and the
    packages named in ``extra`` imported inside it are instrumented for coverage."""
    import atheris

    return atheris.instrument_imports(
        include=["robocli.protocols", "reference", "construct", *extra]
    )
