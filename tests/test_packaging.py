"""Packaging as a user or a packager meets it: the sdist ships every tracked file (the tests'
data, fuzz/, specs/) and runs the tests it ships; a build without a C compiler stops with one
line that says so; the metadata PyPI shows names the license, the authors and the project.

The sdist is built once for this module, from a copy of this checkout, with ``build
--no-isolation``: the setuptools and cffi of this venv (the test extra installs build and
setuptools), no network, a few seconds. The wheel PyPI accepts (manylinux, abi3) is checked
by ``make dist-check``.
"""

from __future__ import annotations

import email.parser
import os
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

pytest.importorskip("build", reason="build is not installed: pip install -e '.[test]'")

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT = 300  # s; bounds a hung build only: a build takes seconds
# tracked files that stay out of the sdist: CI's and the developers' own files
NOT_SHIPPED = (".ci/", ".github/", ".gitignore", ".pre-commit-config.yaml")
# tests that read tests/data and fuzz/ (at import or in the test), run from the unpacked sdist
SHIPPED_TESTS = (
    "tests/hub_server/test_server.py::test_original_client_bytes_are_served",  # original_client.hex
    "tests/sim/test_laser_sim.py::test_reflectors_follow_the_lms200_rules",  # laser_room.map
    "tests/test_fuzz_smoke.py::test_every_target_is_runnable",  # fuzz/
)


def _run(
    argv: list[str], cwd: Path | None = None, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT,
        stdin=subprocess.DEVNULL,
    )  # fmt: skip


def _in_git() -> bool:
    return shutil.which("git") is not None and (ROOT / ".git").exists()


def _git(*args: str) -> list[str]:
    """NUL-separated paths from git in this checkout."""
    proc = _run(["git", "-C", str(ROOT), *args, "-z"])
    assert proc.returncode == 0, proc.stderr
    return [p for p in proc.stdout.split("\0") if p]


# what a developer's checkout holds besides its sources: the compiled core and its C file,
# the C test binaries, objects and caches; none of them may reach the sdist
ARTEFACTS = (
    "robocli/_core.abi3.so", "robocli/_core.c", "robocli/__pycache__/cli.cpython-311.pyc",
    "csrc/test_core", "csrc/test_core_asan", "csrc/test_bench", "csrc/test_bench_asan",
    "csrc/checksum.o", "tests/__pycache__/conftest.cpython-311.pyc",
)  # fmt: skip


@pytest.fixture(scope="module")
def sdist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sdist of this checkout. Built from a copy of the files git does not ignore, with
    the usual build artefacts added: setuptools merges a stale robocli.egg-info/SOURCES.txt
    of the checkout into the sdist, which would hide a file that MANIFEST.in misses."""
    src = ROOT
    if _in_git():
        src = tmp_path_factory.mktemp("checkout")
        for name in _git("ls-files", "--cached", "--others", "--exclude-standard"):
            if (ROOT / name).is_file():
                (src / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(ROOT / name, src / name)
        for name in ARTEFACTS:
            (src / name).parent.mkdir(parents=True, exist_ok=True)
            (src / name).write_bytes(b"\x7fELF not a source")
    out = tmp_path_factory.mktemp("sdist")
    proc = _run(
        [sys.executable, "-m", "build", "--sdist", "--no-isolation", "--outdir", str(out), "."],
        cwd=src,
    )
    assert proc.returncode == 0, f"sdist build failed:\n{proc.stdout[-4000:]}{proc.stderr[-4000:]}"
    (tarball,) = out.glob("robocli_robots-*.tar.gz")
    return tarball


def _members(tarball: Path) -> dict[str, tarfile.TarInfo]:
    """The sdist's regular files by path below its top folder (robocli_robots-X.Y.Z/)."""
    with tarfile.open(tarball) as tar:
        return {m.name.split("/", 1)[1]: m for m in tar.getmembers() if m.isfile()}


def _unpack(tarball: Path, dest: Path) -> Path:
    with tarfile.open(tarball) as tar:
        if hasattr(tarfile, "data_filter"):
            tar.extractall(dest, filter="data")
        else:  # pragma: no cover - Python without the extraction filters
            tar.extractall(dest)
    (top,) = dest.iterdir()
    return top


def test_sdist_ships_every_tracked_file_and_no_build_artefact(sdist: Path) -> None:
    if not _in_git():
        pytest.skip("not a git checkout: no tracked files to compare the sdist with")
    shipped = set(_members(sdist))
    tracked = {
        p for p in _git("ls-files") if not p.startswith(NOT_SHIPPED) and (ROOT / p).is_file()
    }
    missing = sorted(tracked - shipped)
    assert not missing, f"tracked files missing from the sdist (MANIFEST.in): {missing}"
    junk = sorted(shipped & set(ARTEFACTS))
    assert not junk, f"build artefacts in the sdist: {junk}"


def test_the_sdist_runs_the_tests_that_need_its_data(sdist: Path, tmp_path: Path) -> None:
    top = _unpack(sdist, tmp_path / "unpacked")
    for name in ("original_client.hex", "gpsfake.nmea"):
        assert (top / "tests" / "data" / "ros4mat" / name).is_file()
    assert (top / "tests" / "data" / "arcos" / "laser_room.map").is_file()
    # from a folder without a robocli/ in it: the tests import the installed package, and
    # read their data and harnesses from the unpacked sdist
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    proc = _run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--benchmark-disable"]
        + [str(top / t) for t in SHIPPED_TESTS],
        cwd=tmp_path,
        env=env,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]
    assert f"{len(SHIPPED_TESTS)} passed" in out, out[-4000:]
    assert f"rootdir: {top}" in out, out[-4000:]


@pytest.mark.parametrize("case", ["CC names a missing compiler", "no compiler on PATH"])
def test_a_build_without_a_c_compiler_says_so_in_one_line(
    sdist: Path, tmp_path: Path, case: str
) -> None:
    top = _unpack(sdist, tmp_path / "unpacked")
    env = {k: v for k, v in os.environ.items() if k not in ("CC", "LDSHARED", "CFLAGS")}
    if case == "CC names a missing compiler":
        env["CC"] = str(tmp_path / "no-such-dir" / "cc")
        named = env["CC"]
    else:  # what a machine without gcc has: Python's configured compiler is not on PATH
        empty = tmp_path / "bin"
        empty.mkdir()
        env["PATH"] = str(empty)
        named = ""
    proc = _run(
        [sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", "out", "."],
        cwd=top,
        env=env,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0, out[-4000:]
    lines = [line for line in out.splitlines() if "robocli: cannot build its C core" in line]
    assert len(lines) == 1, out[-4000:]
    line = lines[0]
    assert "no C compiler found" in line and named in line, line
    assert "apt install gcc python3-dev" in line, line
    # the hint names this distribution: "robocli" on PyPI is an unrelated package
    assert "pip install --only-binary robocli-robots robocli-robots" in line, line
    assert "Traceback" not in out and "No such file or directory" not in out, out[-4000:]
    assert not list((top / "out").glob("*.whl"))


def test_the_metadata_names_license_authors_and_project(sdist: Path) -> None:
    members = _members(sdist)
    with tarfile.open(sdist) as tar:
        pkg_info = tar.extractfile(members["PKG-INFO"].name)
        lic = tar.extractfile(members["LICENSE"].name)
        assert pkg_info is not None and lic is not None
        meta = email.parser.BytesParser().parse(pkg_info)
        license_text = lic.read().decode()
    assert "MIT License" in license_text and "robocli developers" in license_text
    assert meta["Name"] == "robocli-robots"  # "robocli" on PyPI is an unrelated package
    assert meta["Version"] == "0.1.0"  # a tree without git metadata: setuptools-scm's fallback
    assert meta["License-Expression"] == "MIT"
    assert meta.get_all("License-File") == ["LICENSE"]
    assert meta["Author"] == "robocli developers"
    urls = dict(u.split(", ", 1) for u in meta.get_all("Project-URL") or [])
    assert {"Homepage", "Source", "Issues"} <= set(urls), urls
    classifiers = meta.get_all("Classifier") or []
    assert "Programming Language :: Python :: 3.10" in classifiers
    assert "Operating System :: POSIX :: Linux" in classifiers
    assert "Typing :: Typed" in classifiers
    # the extras a user picks from: runtime alone, plot and record for the demo, foxglove for
    # the live view, test and lint for make test
    extras = set(meta.get_all("Provides-Extra") or [])
    assert {"plot", "record", "foxglove", "test", "lint"} <= extras


def test_the_version_comes_from_the_git_tag(sdist: Path, tmp_path: Path) -> None:
    """setuptools-scm versions a tagged checkout by its tag (the tag is made here, in a
    throwaway repository: the project's tags are the maintainers')."""
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    top = _unpack(sdist, tmp_path / "unpacked")
    (top / "PKG-INFO").unlink()  # a checkout has no PKG-INFO: its version is git's alone
    for info in top.glob("*.egg-info"):  # rewritten by the build: would make the tree dirty
        shutil.rmtree(info)
    ident = ["-c", "user.name=t", "-c", "user.email=t@localhost", "-c", "commit.gpgsign=false"]
    for argv in (["init", "-q"], ["add", "-A"], [*ident, "commit", "-q", "-m", "tree"],
                 [*ident, "tag", "-a", "v9.8.7", "-m", "v9.8.7"]):  # fmt: skip
        proc = _run(["git", "-C", str(top), *argv])
        assert proc.returncode == 0, proc.stderr
    out = tmp_path / "out"
    proc = _run(
        [sys.executable, "-m", "build", "--sdist", "--no-isolation", "--outdir", str(out), "."],
        cwd=top,
    )
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-4000:]
    assert [p.name for p in out.glob("*.tar.gz")] == ["robocli_robots-9.8.7.tar.gz"]
