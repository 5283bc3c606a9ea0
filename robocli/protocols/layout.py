"""Fixed-size ``construct`` declarations as ``struct`` formats and NumPy dtypes.

A message is declared once with ``construct`` (slow, about 20 k parses/s, but symmetric and
with errors that name the failing field). Hot paths read the same bytes through a
``struct.Struct`` or a NumPy structured dtype generated here from that declaration, so the
two can never disagree on a layout. Supported: named fixed-size primitive fields
(``Int16ul``, ``Float64l``, ...), fixed-count ``Array`` of them, nested ``Struct`` and
``Optional(x)`` (laid out as ``x``, present). Anything else raises ``TypeError``.

NumPy is imported only by :func:`numpy_dtype`, so a module that needs struct views only
(the ARCOS client path) does not pay for it.
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Any

import construct as cs

if TYPE_CHECKING:
    import numpy as np

#: struct format code -> NumPy type code (without byte order).
_NUMPY_CODES = {
    "b": "i1",
    "B": "u1",
    "h": "i2",
    "H": "u2",
    "i": "i4",
    "I": "u4",
    "l": "i4",
    "L": "u4",
    "q": "i8",
    "Q": "u8",
    "e": "f2",
    "f": "f4",
    "d": "f8",
}


def _unwrap(con: Any) -> Any:
    """The declaration under names and ``Optional`` (``Select(x, Pass)``)."""
    while True:
        if isinstance(con, cs.Renamed):
            con = con.subcon
        elif isinstance(con, cs.Select):
            con = con.subcons[0]
        else:
            return con


def _primitive(con: Any, path: str) -> tuple[str, str]:
    """(byte order, code) of a ``FormatField``."""
    fmt = str(con.fmtstr)
    order, code = fmt[0], fmt[1:]
    if order not in "<>=" or code not in _NUMPY_CODES:
        raise TypeError(f"{path}: unsupported format {fmt!r}")
    return order, code


def _codes(con: Any, path: str, orders: set[str]) -> str:
    con = _unwrap(con)
    if isinstance(con, cs.FormatField):
        order, code = _primitive(con, path)
        if code not in "bB":  # single bytes have no byte order
            orders.add(order)
        return code
    if isinstance(con, cs.Array) and isinstance(con.count, int):
        return _codes(con.subcon, path, orders) * con.count
    if isinstance(con, cs.Struct):
        return "".join(_codes(sub, f"{path}.{sub.name}", orders) for sub in con.subcons)
    raise TypeError(f"{path}: {type(con).__name__} is not a fixed-size declaration")


def struct_codes(con: Any, path: str = "struct") -> str:
    """``struct`` format codes of a fixed-size declaration, without the byte order.

    >>> struct_codes(cs.Struct("a" / cs.Int16ul, "b" / cs.Array(2, cs.Int8ub)))
    'HBB'
    """
    return _codes(con, path, set())


def struct_of(con: Any, path: str = "struct") -> struct.Struct:
    """A ``struct.Struct`` reading the same bytes as a fixed-size declaration.

    Its values come in declaration order, arrays and nested structs flattened. Raises
    ``TypeError`` for a declaration mixing byte orders or without a fixed layout.
    """
    orders: set[str] = set()
    codes = _codes(con, path, orders)
    if len(orders) > 1:
        raise TypeError(f"{path}: mixes byte orders {sorted(orders)}")
    return struct.Struct((orders.pop() if orders else "<") + codes)


def field_names(con: Any) -> tuple[str, ...]:
    """Names of the fields of a declaration that is a ``Struct`` (else empty)."""
    con = _unwrap(con)
    if isinstance(con, cs.Struct):
        return tuple(str(sub.name) for sub in con.subcons)
    return ()


def _dtype_spec(con: Any, path: str) -> Any:
    import numpy as np

    con = _unwrap(con)
    if isinstance(con, cs.FormatField):
        order, code = _primitive(con, path)
        return np.dtype(("<" if order == "=" else order) + _NUMPY_CODES[code])
    if isinstance(con, cs.Array) and isinstance(con.count, int):
        return (_dtype_spec(con.subcon, path), (con.count,))
    if isinstance(con, cs.Struct):
        return numpy_dtype(con, path)
    raise TypeError(f"{path}: {type(con).__name__} has no fixed NumPy layout")


def numpy_dtype(con: Any, path: str = "struct") -> np.dtype[Any]:
    """A packed NumPy structured dtype with the same layout as a ``construct`` Struct.

    Fields keep their names; arrays become sub-array fields, nested structs nested dtypes.
    ``dtype.itemsize == con.sizeof()`` is checked. Raises ``TypeError`` for unnamed fields
    or a declaration without a fixed layout.
    """
    import numpy as np

    con = _unwrap(con)
    if not isinstance(con, cs.Struct):
        raise TypeError(f"{path}: {type(con).__name__} is not a Struct")
    fields: list[Any] = []
    for sub in con.subcons:
        if not sub.name:
            raise TypeError(f"{path}: unnamed field {sub!r}")
        spec = _dtype_spec(sub, f"{path}.{sub.name}")
        fields.append((sub.name, *spec) if isinstance(spec, tuple) else (sub.name, spec))
    dtype = np.dtype(fields)  # a list of fields gives a packed dtype
    if dtype.itemsize != con.sizeof():
        raise TypeError(f"{path}: dtype of {dtype.itemsize} bytes != sizeof {con.sizeof()}")
    return dtype


__all__ = ["field_names", "numpy_dtype", "struct_codes", "struct_of"]
