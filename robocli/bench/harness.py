"""What every benchmark runs on: child processes that start, report one line and always stop,
CPU pinning, and the machine's floor, a C ping-pong over loopback TCP
(:class:`robocli.core.PingPong`) with **both ends pinned to one CPU**, so figures mean the
same on any machine (unpinned, the two ends land on one CPU or on two from run to run, and
the floor changes by an order of magnitude).
"""

from __future__ import annotations

import contextlib
import os
import selectors
import subprocess
import sys
import time
from collections.abc import Iterator

from robocli.bench.stats import Progress, Run

#: Longest a single C call of the floor may last (seconds), so Ctrl-C is seen quickly.
CHUNK_SECONDS = 0.1
#: Largest number of round trips in one C call of the floor.
MAX_CHUNK = 10_000


@contextlib.contextmanager
def child_process(
    code: str, *args: str, timeout: float = 20.0
) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """A Python child running ``code`` (``args`` as its argv), stdin and stdout piped, in its
    own session (a Ctrl-C reaches only us; we stop it). Yields it and the first line it
    printed within ``timeout`` s ("" if none). On the way out: the end of its stdin (children
    wait for it: :func:`wait_for_stdin_eof`), then SIGTERM, then SIGKILL, 1 s each."""
    proc = subprocess.Popen(
        [sys.executable, "-c", code, *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        text=True, start_new_session=True,
    )  # fmt: skip
    try:
        yield proc, read_line(proc, timeout)
    finally:
        with contextlib.suppress(OSError):
            if proc.stdin is not None:
                proc.stdin.close()
        for stop in (None, proc.terminate, proc.kill):
            if stop is not None:
                stop()
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(1.0)
                break
        if proc.stdout is not None:
            proc.stdout.close()


def read_line(proc: subprocess.Popen[str], timeout: float) -> str:
    """The next line a child prints within ``timeout`` s, stripped ("" if none)."""
    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        ready = sel.select(timeout)
    return proc.stdout.readline().strip() if ready else ""


def wait_for_stdin_eof() -> None:
    """Block until standard input ends: how a benchmark's child process learns that its
    parent is done (or gone). Reads in fixed chunks, so a chatty parent costs no memory."""
    while sys.stdin.buffer.read(4096):
        pass


# ---------------------------------------------------------------------------- CPUs


def allowed_cpus() -> list[int]:
    """CPUs this process may run on (empty where the platform cannot pin threads)."""
    from robocli.core import pin_supported

    if not pin_supported() or not hasattr(os, "sched_getaffinity"):
        return []
    return sorted(os.sched_getaffinity(0))


@contextlib.contextmanager
def pinned(cpu: int | None) -> Iterator[None]:
    """Pin the calling thread to ``cpu`` (None: leave it) for the block, then restore its
    affinity. Threads started inside the block inherit the pinning (Linux)."""
    if cpu is None or not hasattr(os, "sched_setaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {cpu})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


def cpu_label(cpu: int | None) -> str:
    return "unpinned" if cpu is None else f"CPU {cpu}"


# ---------------------------------------------------------------------------- C floor


def c_floor(
    run: Run,
    cpu: int | None = None,
    echo_cpu: int | None = None,
    msg_size: int = 16,
    progress: Progress | None = None,
) -> Run:
    """Fill ``run`` with C ping-pong round trips, the caller's end on ``cpu`` and the echo
    thread on ``echo_cpu``. Runs in chunks of at most :data:`CHUNK_SECONDS` (and
    :data:`MAX_CHUNK` round trips) so Ctrl-C stops it between two chunks."""
    from robocli.core import PingPong

    with PingPong(msg_size, echo_cpu) as pp:
        chunk = 200
        while run.count < run.n:
            k = min(chunk, run.n - run.count)
            start = time.perf_counter()
            run.samples[run.count : run.count + k] = pp.run(k, cpu)
            run.count += k
            took = max(time.perf_counter() - start, 1e-6)
            chunk = max(50, min(MAX_CHUNK, int(k * CHUNK_SECONDS / took)))
            if progress is not None:
                progress(run.count)
    return run
