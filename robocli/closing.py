"""The one ``with`` protocol of everything robocli opens: :class:`Closing`.

A device, transport, recorder, bridge or live view closes on every way out of a ``with``
block (normal exit, exception, Ctrl-C); the class defines ``close()`` (bounded, idempotent)
and inherits ``__enter__``/``__exit__`` from here instead of writing them again.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

__all__ = ["Closing", "closed_on_error", "in_background"]

_C = TypeVar("_C", bound="Closing")


class Closing:
    """Mixin: ``with obj:`` gives ``obj`` and calls ``obj.close()`` on every way out."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self: _C) -> _C:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextlib.contextmanager
def closed_on_error(thing: Any) -> Iterator[None]:
    """Close ``thing`` (what is being set up: a device, a link, a simulator) when the block
    raises anything (Ctrl-C included), then let the exception through."""
    try:
        yield
    except BaseException:
        thing.close()
        raise


@contextlib.contextmanager
def in_background(work: Callable[[threading.Event], None], name: str,
                  join_s: float) -> Iterator[None]:  # fmt: skip
    """Run ``work(stop)`` in a daemon thread called ``name`` while the block runs; on every
    way out, set ``stop`` (``work`` returns soon after it is set) and join the thread,
    waiting at most ``join_s`` seconds."""
    stop = threading.Event()
    thread = threading.Thread(target=work, args=(stop,), name=name, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(join_s)
