"""Every public class is importable from ``robocli``, lazily: ``import robocli`` loads none
of the device, simulator or recording modules (nor numpy) until a name is used."""

from __future__ import annotations

import importlib
import inspect
import subprocess
import sys

import pytest

import robocli

#: packages whose public classes users reach through ``robocli``
PACKAGES = [
    "robocli.devices.pioneer", "robocli.devices.arm", "robocli.devices.hub",
    "robocli.devices.laser", "robocli.devices.base", "robocli.devices.create", "robocli.errors",
    "robocli.bridge",
]  # fmt: skip
#: (package, name) taken at the top by another class of that name, reachable in its package
SHADOWED = {
    ("robocli.devices.arm", "Recorder"),
    ("robocli.devices.pioneer", "LinkStats"),
    ("robocli.devices.create", "Odometry"),
}


def test_all_lists_exactly_what_resolves() -> None:
    assert robocli.__all__ == sorted(robocli.__all__)
    assert set(robocli.__all__) == {*robocli._LAZY, "__version__"}
    for name in robocli.__all__:
        assert getattr(robocli, name) is not None
    with pytest.raises(AttributeError):
        robocli.NoSuchThing  # noqa: B018


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_class_is_importable_from_robocli(package: str) -> None:
    module = importlib.import_module(package)
    for name in getattr(module, "__all__", ()):
        value = getattr(module, name)
        if not inspect.isclass(value) or (package, name) in SHADOWED:
            continue
        assert getattr(robocli, name, None) is value, f"robocli.{name} ({package})"


def test_import_robocli_stays_light() -> None:
    code = ("import sys, robocli; heavy = sorted(m for m in sys.modules if m.startswith("
            "('robocli.devices', 'robocli.sim', 'robocli.io', 'robocli.hub_server', 'numpy', "
            "'serial', 'zenoh'))); print(heavy)")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=True).stdout.strip()  # fmt: skip
    assert out == "[]"
