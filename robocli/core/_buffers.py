"""Zero-copy views of byte buffers and arrays for the cffi calls of :mod:`robocli.core`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Union

from robocli._core import ffi

if TYPE_CHECKING:
    import numpy.typing as npt

Buffer = Union[bytes, bytearray, memoryview]  # noqa: UP007 (a runtime alias on 3.10)


def _view(data: Any) -> memoryview:
    """A memoryview of any buffer-protocol object (bytes, arrays)."""
    return memoryview(data)


def _bytes_view(data: Buffer | npt.NDArray[Any]) -> Any:
    """A cffi ``unsigned char[]`` view of a bytes-like object or array (no copy when it is
    contiguous; a non-contiguous one is copied)."""
    if not isinstance(data, bytes | bytearray):
        view = _view(data)
        if not view.c_contiguous:
            data = view.tobytes()
    return ffi.from_buffer("unsigned char[]", data)
