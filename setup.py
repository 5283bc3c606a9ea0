"""The C core is compiled by cffi at install time; everything else lives in pyproject.toml.

The extension is built against the stable ABI (cffi defines ``Py_LIMITED_API``), so the
wheel is tagged ``cp310-abi3``: one wheel per platform serves every CPython >= 3.10.
"""

import sys
import sysconfig

from setuptools import setup

# A debug or free-threaded interpreter has no limited API: build a plain wheel there.
_ABI3 = not hasattr(sys, "gettotalrefcount") and not sysconfig.get_config_var("Py_GIL_DISABLED")

setup(
    cffi_modules=["csrc/build_core.py:ffibuilder"],
    options={"bdist_wheel": {"py_limited_api": "cp310"}} if _ABI3 else {},
)
