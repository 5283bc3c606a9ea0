"""The one ``with`` protocol of everything robocli opens: :class:`Closing`.

A device, transport, recorder, bridge or live view closes on every way out of a ``with``
block (normal exit, exception, Ctrl-C); the class defines ``close()`` (bounded, idempotent)
and inherits ``__enter__``/``__exit__`` from here instead of writing them again.
"""

from __future__ import annotations

from typing import TypeVar

__all__ = ["Closing"]

_C = TypeVar("_C", bound="Closing")


class Closing:
    """Mixin: ``with obj:`` gives ``obj`` and calls ``obj.close()`` on every way out."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self: _C) -> _C:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
