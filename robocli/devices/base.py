"""The one surface every device client has: :class:`Device`.

``Pioneer``, ``Arm``, ``Hub`` (and ``ZenohHub``), ``Laser`` and ``RemotePioneer`` all follow
it, so that a script learnt on one reads the others::

    with Laser.connect("sim://") as laser:               # a URL: docs/urls.md
        handle = laser.add_listener(print)                # every frame: (direction, bytes, t)
        laser.alive, laser.stats.as_dict()
        handle.remove()
    laser.close()                                         # twice is fine

``connect(url, ...)`` (a classmethod) opens the device; ``close(*, stop=True)`` returns None,
is bounded in time and idempotent (``stop``: stop what the device does for this client:
the robot, the trajectory, the hub's buffers, the laser's emission); :attr:`alive` never
blocks; :meth:`check` raises the typed error that ended the link
(:class:`~robocli.errors.ConnectionLost` for a dead one); ``stats.as_dict()`` gives the
counters; ``add_listener(callback, kind=...)`` returns a :class:`ListenerHandle` whose
``remove()`` takes the callback off again. Renamed arguments and methods keep working for
one release through :func:`deprecated`, which warns once per name.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable
from types import TracebackType
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from robocli.addresses import parse_device_url
from robocli.closing import Closing
from robocli.errors import ConnectionLost, InvalidArgument

if TYPE_CHECKING:
    from robocli.devices.listeners import Listeners
    from robocli.devices.session import Session
    from robocli.zenoh.session import ZenohTarget

__all__ = ["Device", "ListenerHandle", "Stats", "deprecated", "renamed_argument"]


@runtime_checkable
class Stats(Protocol):
    """A device's counters."""

    def as_dict(self) -> dict[str, Any]: ...


@runtime_checkable
class Device(Protocol):
    """What every device client offers (see the module)."""

    @property
    def alive(self) -> bool: ...

    @property
    def stats(self) -> Stats: ...

    def check(self) -> None: ...

    def add_listener(self, listener: Callable[..., None], *, kind: str = ...) -> ListenerHandle: ...

    def remove_listener(self, listener: Callable[..., None], *, kind: str = ...) -> None: ...

    def close(self, *, stop: bool = True) -> None: ...

    def __enter__(self) -> Any: ...

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None, /) -> None: ...  # fmt: skip


class ListenerHandle:
    """What ``add_listener`` returns: :meth:`remove` takes the listener off (idempotent);
    also a context manager that removes it on exit."""

    def __init__(self, listener: Callable[..., None], remove: Callable[[], None]) -> None:
        self.listener = listener
        self._remove: Callable[[], None] | None = remove
        self._lock = threading.Lock()

    def remove(self) -> None:
        with self._lock:
            remove, self._remove = self._remove, None
        if remove is not None:
            remove()

    def __enter__(self) -> ListenerHandle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.remove()

    def __repr__(self) -> str:
        state = "removed" if self._remove is None else "active"
        return f"<ListenerHandle {self.listener!r} {state}>"


class ListenersByKind(Closing):
    """The listener part of :class:`Device` for a device that keeps one registry per kind:
    the class says which with ``_listeners_of(kind)`` (an unknown kind:
    :class:`InvalidArgument`) and documents the kinds on its ``add_listener``, which returns
    :meth:`_add_listener`."""

    def _listeners_of(self, kind: str) -> Listeners[Any]:
        raise NotImplementedError

    def _add_listener(self, listener: Callable[..., None], kind: str) -> ListenerHandle:
        registry = self._listeners_of(kind)
        registry.add(listener)
        return ListenerHandle(listener, lambda: registry.remove(listener))

    def remove_listener(self, listener: Callable[..., None], *, kind: str = "frames") -> None:
        """Take ``listener`` off (see ``add_listener``); one not there is ignored."""
        self._listeners_of(kind).remove(listener)


class SessionDevice(ListenersByKind):
    """A device on one link :class:`~robocli.devices.session.Session` (``_session``): its
    :attr:`alive` and :meth:`check` are the link's."""

    _session: Session

    @property
    def alive(self) -> bool:
        """True until the link failed (a device gone silent included) or :meth:`close`
        began. Never blocks."""
        return self._session.alive

    def check(self) -> None:
        """Return while :attr:`alive`; else raise the error that ended the link
        (:class:`ConnectionLost` for a lost one or once closed). Never blocks."""
        with self._session.cond:
            self._session.check()


class ZenohPeer(ListenersByKind):
    """A device reached through Zenoh (``url``): alive until its peer's liveliness token
    goes (``_gone`` says why) or :meth:`close` begins (``_closed``)."""

    _gone: str | None = None
    _closed = False

    @property
    def url(self) -> str:
        """``zenoh/NAME``."""
        raise NotImplementedError

    @property
    def alive(self) -> bool:
        """False once the peer left (its liveliness token went) or :meth:`close` began.
        Never blocks."""
        return self._gone is None and not self._closed

    def check(self) -> None:
        """Return while :attr:`alive`; else :class:`ConnectionLost` saying why. Never blocks."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: closed")
        if self._gone is not None:
            raise ConnectionLost(f"{self.url}: {self._gone}")


def pick_kind(kind: str, kinds: tuple[str, ...], device: str) -> str:
    """``kind`` if it is one of ``kinds``; else :class:`InvalidArgument` naming them."""
    if kind not in kinds:
        raise InvalidArgument(f"{device} listeners are of kind {', '.join(map(repr, kinds))}, "
                              f"not {kind!r}")  # fmt: skip
    return kind


_warned: set[str] = set()
_warned_lock = threading.Lock()


def deprecated(old: str, new: str, stacklevel: int = 3) -> None:
    """Warn once per process (a :class:`DeprecationWarning`, one line) that ``old`` is now
    spelt ``new``; ``old`` keeps working for one release."""
    with _warned_lock:
        if old in _warned:
            return
        _warned.add(old)
    warnings.warn(f"{old} is deprecated; use {new}", DeprecationWarning, stacklevel=stacklevel)


def deprecated_listener(
    device: str, old: str, kind: str, *, remove: bool = False
) -> Callable[[Any, Callable[..., None]], None]:
    """A deprecated method ``device.old(listener)``: warns once that it is now
    ``add_listener(listener, kind=kind)`` (``remove``: ``remove_listener``), then does that."""
    new = "remove_listener" if remove else "add_listener"

    def method(self: Any, listener: Callable[..., None]) -> None:
        deprecated(f"{device}.{old}", f'{device}.{new}(..., kind="{kind}")')
        getattr(self, new)(listener, kind=kind)

    method.__name__ = old
    method.__doc__ = f'Deprecated: ``{new}(listener, kind="{kind}")``.'
    return method


def renamed_argument(where: str, old: str, new: str, old_value: Any, new_value: Any,
                     default: Any) -> Any:  # fmt: skip
    """The value of an argument renamed ``old`` -> ``new``: ``old_value`` (with a one-time
    warning) when given, else ``new_value``; both given and different: InvalidArgument."""
    if old_value is None:
        return default if new_value is None else new_value
    deprecated(f"{where}({old}=)", f"{where}({new}=)", stacklevel=4)
    if new_value is not None and new_value != old_value:
        raise InvalidArgument(f"{where}: give {new}= only ({old}= is its old name)")
    return old_value


def close_simulator(device: Any) -> None:
    """Close the simulator a ``sim://`` device owns (after its link), if any."""
    simulator = getattr(device, "simulator", None)
    if simulator is not None:
        simulator.close()


def zenoh_where(url: str, zenoh: str | ZenohTarget | None,
                device: str) -> tuple[str, str | ZenohTarget | None]:  # fmt: skip
    """A ``zenoh/NAME[?zenoh=ENDPOINT|CONFIG]`` URL (or a bare ``NAME``) and the ``zenoh=``
    keyword -> (NAME, where to reach it: the keyword, else the URL's query; None: the
    default endpoint). Both given and different is an :class:`InvalidArgument`."""
    if not url.startswith("zenoh/"):
        return url, zenoh
    where = parse_device_url(url, what=f"{device} URL")
    in_url = where.options.get("zenoh")
    if zenoh is not None and in_url is not None and str(zenoh) != in_url:
        raise InvalidArgument(f"{url!r}: give the Zenoh endpoint once, in the URL (?zenoh=) "
                              f"or as zenoh=, not both ({in_url} and {zenoh})")  # fmt: skip
    return where.name, in_url if zenoh is None else zenoh


def not_over_zenoh(url: str, device: str, **given: object) -> None:
    """:class:`InvalidArgument` naming the arguments of ``given`` that were set (not None,
    False or empty) for a ``zenoh/NAME`` URL, where they mean nothing (the bridge or
    front-end owns the link to the device)."""
    named = [name for name, value in given.items() if value not in (None, False, 0, ())]
    if named:
        given_names = ", ".join(f"{name}=" for name in named)
        raise InvalidArgument(f"{url!r}: {given_names} cannot be given for a {device} behind "
                              "Zenoh (its bridge owns the link)")  # fmt: skip
