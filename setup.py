"""The C core is compiled by cffi at install time; everything else lives in pyproject.toml.

The extension is built against the stable ABI (cffi defines ``Py_LIMITED_API``), so the
wheel is tagged ``cp310-abi3``: one wheel per platform serves every CPython >= 3.10.

Building from source needs a C compiler and the Python headers. Without a compiler the build
stops with one line that says so (and how to get a prebuilt wheel) before anything is compiled,
instead of a raw ``command 'gcc' failed: No such file or directory``; a failed compile ends
with one line that says what to install.
"""

from __future__ import annotations

import shutil
import sys
import sysconfig

from setuptools import setup
from setuptools.command.build_ext import build_ext
from setuptools.errors import CompileError

# A debug or free-threaded interpreter has no limited API: build a plain wheel there.
_ABI3 = not hasattr(sys, "gettotalrefcount") and not sysconfig.get_config_var("Py_GIL_DISABLED")

_HINT = (
    "install a C compiler and the Python headers (Debian/Ubuntu: apt install gcc python3-dev;"
    " Fedora: dnf install gcc python3-devel; macOS: xcode-select --install),"
    " or install a prebuilt wheel: pip install --only-binary robocli-robots robocli-robots"
)


def _build_problem(cmd: build_ext) -> str | None:
    """Why the C core cannot be compiled here, in one line, or None. Only for unix-style
    compilers: on Windows, setuptools already names the missing Build Tools itself."""
    compiler = cmd.compiler
    if getattr(compiler, "compiler_type", "") != "unix":
        return None
    for what, argv in (("C compiler", compiler.compiler_so), ("linker", compiler.linker_so)):
        exe = argv[0] if argv else ""
        if not exe or shutil.which(exe) is None:
            env = "CC" if what == "C compiler" else "LDSHARED"
            return (
                f"robocli: cannot build its C core: no {what} found ({exe or '(empty)'!r}, "
                f"set by {env} or Python's build configuration); {_HINT}"
            )
    return None


class build_ext_checked(build_ext):
    """build_ext that says in one line why the C core cannot be built (cffi wraps it)."""

    def build_extensions(self) -> None:
        problem = _build_problem(self)
        if problem is not None:
            raise CompileError(problem)
        try:
            super().build_extensions()
        except CompileError as exc:
            raise CompileError(
                f"robocli: its C core did not compile ({exc}; the compiler's messages are above;"
                " 'Python.h: No such file' means the Python headers are missing); " + _HINT
            ) from None


setup(
    cmdclass={"build_ext": build_ext_checked},
    cffi_modules=["csrc/build_core.py:ffibuilder"],
    options={"bdist_wheel": {"py_limited_api": "cp310"}} if _ABI3 else {},
)
