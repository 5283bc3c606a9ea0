"""cffi build script of the C core (API mode): ``robocli._core``.

Used by setup.py (``cffi_modules=["csrc/build_core.py:ffibuilder"]``). The cdef is read from
``robocli_core.h`` itself so the header stays the single contract.
"""

from __future__ import annotations

import os
import re
import sys

from cffi import FFI

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCES = ["checksum.c", "scip.c", "framer.c", "ring.c", "align.c", "pingpong.c", "benchnet.c"]


def _rel(path: str) -> str:
    """setuptools wants source paths relative to the project root (the working directory)."""
    try:
        return os.path.relpath(path)
    except ValueError:  # another drive on Windows
        return path


def _cdef() -> str:
    with open(os.path.join(HERE, "robocli_core.h"), encoding="ascii") as fh:
        text = fh.read()
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    keep = []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#"):
            if re.match(r"#define\s+RC_\w+\s+\d+\s*$", s):
                keep.append(s)
            continue
        keep.append(line)
    return "\n".join(keep)


# No -std=c89 here: the generated module includes Python.h, which is not C89 (// comments,
# inline). C89 conformance of csrc/ is enforced by `make test-c` (-std=c89 -pedantic -Werror).
# No -D_POSIX_C_SOURCE either: pyconfig.h defines its own; pingpong.c defines it at its top.
if sys.platform == "win32":
    _args: list[str] = []
    _libs: list[str] = []
else:
    _args = ["-O2"]
    _libs = ["pthread"]

ffibuilder = FFI()
ffibuilder.cdef(_cdef())
ffibuilder.set_source(
    "robocli._core",
    '#include "robocli_core.h"\n',
    sources=[_rel(os.path.join(HERE, name)) for name in SOURCES],
    include_dirs=[_rel(HERE)],
    extra_compile_args=_args,
    libraries=_libs,
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
