"""Every file robocli writes for a user goes through here, so that none is destroyed.

The rules (the design's "a user's files are never destroyed"):

- **check first**: :func:`check_output` says, before anything is connected or read, whether
  ``path`` could be written: not a directory, not a symbolic link, in a folder that exists
  and is writable, and not an existing file unless ``overwrite`` (``--overwrite``). A
  command calls it while it checks its arguments, so that a bad URL, an unreachable robot
  or a refused output leaves every file as it was.
- **never through a symbolic link**: a link at ``path`` is refused, and nothing opens
  ``path`` in a way that follows one: a new file is created with ``O_EXCL | O_NOFOLLOW``
  (a link or file made there since the check is refused, not followed), and a replaced one
  is written beside it and renamed over it (a rename replaces a name, never a link's target,
  and leaves the old file's other hard links their bytes).
- **whole files appear whole**: :func:`replace_output` writes a temporary file beside the
  output and puts it in place only once written; a failure removes it and leaves what was
  there. Streams that must be readable while they grow (a recording, a capture) are opened
  with :func:`create_output` at their final name, after every source is connected.

Errors are :class:`OutputError` (one line, exit 2).
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import secrets
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from robocli.errors import EXIT_USAGE, RobocliError

__all__ = ["OutputError", "check_output", "create_output", "replace_output", "same_file"]

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_NEW = os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | getattr(os, "O_BINARY", 0)
_NEW_RW = (_NEW & ~os.O_WRONLY) | os.O_RDWR


class OutputError(RobocliError, ValueError):
    """An output that robocli refuses to write, or cannot: exists (without ``overwrite``),
    is a symbolic link or a directory, or its folder is missing or not writable. A file the
    user named is unusable: exit 2, one line (as a log or capture that cannot be read)."""

    exit_code = EXIT_USAGE


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether ``a`` and ``b`` are one file (an output that would empty the input it is
    written from); False when either does not exist (yet)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_output(path: str | Path, overwrite: bool = False) -> Path:
    """Raise :class:`OutputError` unless ``path`` could be written now (see the module
    docstring); returns it as a :class:`~pathlib.Path`. Touches nothing."""
    out = Path(path)
    try:
        st: os.stat_result | None = os.lstat(out)
    except FileNotFoundError:
        st = None
    except OSError as exc:  # a path through a file, a name too long
        raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise OutputError(f"{out} is a symbolic link: robocli does not write through "
                              "one (name the file itself)")  # fmt: skip
        if stat.S_ISDIR(st.st_mode):
            raise OutputError(f"cannot write {out}: a directory")
        if not overwrite:
            raise OutputError(f"{out} exists: give --overwrite to replace it")
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(f"cannot write {out}: not a regular file")
    parent = out.parent
    if not parent.is_dir():
        raise OutputError(f"cannot write {out}: no directory {parent}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write {out}: permission denied")
    return out


def create_output(path: str | Path, overwrite: bool = False, *, text: bool = False,
                  buffered: bool = True) -> IO[Any]:  # fmt: skip
    """Open ``path`` for writing as a stream that grows in place (a recording, a capture):
    a new file, or with ``overwrite`` a fresh file renamed over the old one. Raises
    :class:`OutputError` as :func:`check_output` does (checked again here: a file or link
    made since is refused). Binary unless ``text`` (UTF-8); ``buffered=False``: the raw
    :class:`io.FileIO`, each write a system call, its descriptor also readable (``pread``:
    a writer may check what reached the file)."""
    flags = _NEW if buffered else _NEW_RW
    out = check_output(path, overwrite)
    if overwrite and os.path.lexists(out):
        fd, tmp = _beside(out, flags)
        try:
            os.replace(tmp, out)
        except OSError as exc:
            os.close(fd)
            _remove(tmp)
            raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    else:
        try:
            fd = os.open(out, flags, 0o666)
        except FileExistsError:
            raise OutputError(f"{out} exists: give --overwrite to replace it") from None
        except OSError as exc:
            raise OutputError(f"cannot write {out}: {_why(exc)}") from None
    return _wrap(fd, text) if buffered else io.FileIO(fd, "wb", closefd=True)


@contextlib.contextmanager
def replace_output(path: str | Path, overwrite: bool = False, *,
                   text: bool = False) -> Iterator[IO[Any]]:  # fmt: skip
    """Write a whole file: the block writes into a temporary file beside ``path``, which
    takes its place when the block ends without error (then not before: an existing file
    is kept until then, and kept for good when the block fails). Without ``overwrite``, a
    file that appeared at ``path`` meanwhile is not replaced (:class:`OutputError`). An
    ``OSError`` of the block becomes an :class:`OutputError` naming ``path``."""
    out = check_output(path, overwrite)
    fd, tmp = _beside(out)
    stream = _wrap(fd, text)
    try:
        with stream:
            yield stream
        _commit(tmp, out, overwrite)
    except OSError as exc:
        raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        _remove(tmp)


def _beside(out: Path, flags: int = _NEW) -> tuple[int, str]:
    """A new hidden temporary file in ``out``'s folder: (descriptor, path)."""
    for _ in range(16):
        tmp = str(out.parent / f".{out.name}.{secrets.token_hex(4)}.part")
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputError(f"cannot write {out}: {_why(exc)}") from None
    raise OutputError(f"cannot write {out}: no free temporary name beside it")


def _commit(tmp: str, out: Path, overwrite: bool) -> None:
    if overwrite:
        os.replace(tmp, out)
        return
    try:
        os.link(tmp, out)  # atomic and never replaces: a file made meanwhile stays
    except FileExistsError:
        raise OutputError(f"{out} exists: give --overwrite to replace it") from None
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV):
            raise
        if os.path.lexists(out):  # a file system without hard links: check, then rename
            raise OutputError(f"{out} exists: give --overwrite to replace it") from None
        os.replace(tmp, out)


def _wrap(fd: int, text: bool) -> IO[Any]:
    raw = io.FileIO(fd, "wb", closefd=True)
    buffered = io.BufferedWriter(raw)
    return io.TextIOWrapper(buffered, encoding="utf-8", newline="") if text else buffered


def _remove(tmp: str) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)


def _why(exc: OSError) -> str:
    if exc.errno == errno.ELOOP:
        return "a symbolic link (robocli does not write through one)"
    return exc.strerror or str(exc)
