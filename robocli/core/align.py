"""Map sorted sample times of K streams onto one sorted reference timeline (in C)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from robocli._core import ffi, lib

if TYPE_CHECKING:  # NumPy is imported by the functions that need it
    import numpy as np
    import numpy.typing as npt


def _times(a: npt.ArrayLike, what: str) -> npt.NDArray[np.float64]:
    import numpy as np

    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{what} must be one-dimensional")
    return arr


def _streams(
    streams: Sequence[npt.ArrayLike] | npt.NDArray[Any],
) -> tuple[list[npt.NDArray[np.float64]], bool]:
    """The list of streams, and whether a single 1-D stream was given."""
    import numpy as np

    if isinstance(streams, np.ndarray):
        if streams.ndim == 1:
            return [_times(streams, "stream")], True
        if streams.ndim == 2:
            return [_times(row, "stream") for row in streams], False
        raise ValueError("streams must be a 1-D array, a 2-D array or a sequence of 1-D arrays")
    return [_times(s, "stream") for s in streams], False


def _long_out(shape: tuple[int, ...]) -> npt.NDArray[Any]:
    import numpy as np

    # C ``long`` is int64 on LP64 (Linux, macOS) but int32 on Windows: index outputs are
    # written as C long and returned as int64.
    return np.empty(shape, dtype=np.dtype("l"))


def _as_int64(a: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
    import numpy as np

    return a if a.dtype == np.dtype(np.int64) else a.astype(np.int64)


def _per_stream(fn: Callable[..., None], ss: Sequence[npt.NDArray[Any]], r: npt.NDArray[Any],
                outputs: Callable[[int], tuple[Any, ...]]) -> None:  # fmt: skip
    """``fn(stream k, its length, ref, M, *outputs(k))`` for every stream k (the C calls)."""
    rbuf = ffi.from_buffer("double[]", r)
    for k, s in enumerate(ss):
        fn(ffi.from_buffer("double[]", s), s.shape[0], rbuf, r.shape[0], *outputs(k))


def align_nearest(
    streams: Sequence[npt.ArrayLike] | npt.NDArray[Any], ref: npt.ArrayLike, tol: float
) -> npt.NDArray[np.int64]:
    """Index of the sample nearest each reference time, per stream.

    ``streams``: K sorted sample-time arrays (a list, or a 2-D array of K rows), or one 1-D
    array. ``ref``: M sorted reference times on the same clock. Returns int64 of shape (K, M)
    (or (M,) for a single 1-D stream): the index of the nearest sample if it is within
    ``tol`` seconds, else -1; ties go to the earlier sample. Unsorted input gives
    meaningless (but memory-safe) results. O(n + M) per stream.
    """
    ss, single = _streams(streams)
    r = _times(ref, "ref")
    m = r.shape[0]
    out = _long_out((len(ss), m))
    _per_stream(lib.rc_align_nearest, ss, r,
                lambda k: (float(tol), ffi.from_buffer("long[]", out[k])))  # fmt: skip
    res = _as_int64(out)
    return res[0] if single else res


def align_linear(
    ts: Sequence[npt.ArrayLike] | npt.NDArray[Any], ref: npt.ArrayLike
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """Linear-interpolation indices and weights of each reference time, per stream.

    For each ``ref[i]`` inside ``[ts[0], ts[-1]]``: ``idx[i] = j`` with
    ``ts[j] <= ref[i] <= ts[j+1]`` and ``w[i]`` the weight of sample j+1, so the value is
    ``(1 - w) * x[j] + w * x[j+1]``. A reference equal to the last sample gives j = n-2,
    w = 1 (j = 0, w = 0 for a one-sample stream). Outside: idx -1, w 0. ``ts`` is one 1-D
    sorted array (results of shape (M,)) or K of them (results of shape (K, M)).
    """
    import numpy as np

    ss, single = _streams(ts)
    r = _times(ref, "ref")
    m = r.shape[0]
    idx = _long_out((len(ss), m))
    w = np.empty((len(ss), m), dtype=np.float64)
    _per_stream(lib.rc_align_linear, ss, r,
                lambda k: (ffi.from_buffer("long[]", idx[k]),
                           ffi.from_buffer("double[]", w[k])))  # fmt: skip
    ires = _as_int64(idx)
    if single:
        return ires[0], w[0]
    return ires, w
