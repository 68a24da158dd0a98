"""Build and run the C++ unit tests of the core (cpp/tests, doctest + CTest).

The build directory is ``build/cpp-tests`` in the repository (ignored by git through
``build/``), so repeated runs only rebuild what changed.  Without cmake or doctest the test
is skipped, unless ``PREISACH_REQUIRE_CPP_TESTS=1`` (set in CI), in which case it fails.
The tests are a unity build at -O1 (cpp/tests/CMakeLists.txt): each test file keeps its
definitions in its own ``namespace unity_<file>``, checked here before the build.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BUILD_DIR = ROOT / "build" / "cpp-tests"
REQUIRED = os.environ.get("PREISACH_REQUIRE_CPP_TESTS", "") == "1"


def _unavailable(reason: str) -> None:
    """Skip, or fail when the C++ tests are required (CI)."""
    if REQUIRED:
        pytest.fail(f"{reason} (PREISACH_REQUIRE_CPP_TESTS=1, so this is an error)", pytrace=False)
    pytest.skip(reason)


def _run(
    cmd: list[str], timeout: float, cwd: Path | None = None
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        cmd,
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        timeout=timeout,
        check=False,
    )


def _tail(text: str, lines: int = 200) -> str:
    parts = text.splitlines()
    if len(parts) <= lines:
        return text
    return "\n".join([f"... ({len(parts) - lines} lines omitted) ..."] + parts[-lines:])


def _cache_value(cache: Path, key: str) -> str | None:
    try:
        for line in cache.read_text(errors="replace").splitlines():
            if line.startswith(key + ":"):
                return line.split("=", 1)[1].strip()
    except OSError:
        pass
    return None


def _drop_stale_cache(generator: str | None) -> None:
    """Remove a build dir configured for another source tree or another generator."""
    cache = BUILD_DIR / "CMakeCache.txt"
    if not cache.exists():
        return
    home = _cache_value(cache, "CMAKE_HOME_DIRECTORY")
    old_generator = _cache_value(cache, "CMAKE_GENERATOR")
    same_home = home is not None and Path(home).resolve() == ROOT
    same_generator = generator is None or old_generator == generator
    if not (same_home and same_generator):
        shutil.rmtree(BUILD_DIR, ignore_errors=True)


@contextlib.contextmanager
def _build_lock():
    """Serialise concurrent pytest runs sharing build/cpp-tests (POSIX only)."""
    BUILD_DIR.parent.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # Windows: no lock
        yield
        return
    with open(BUILD_DIR.parent / "cpp-tests.lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _missing_unity_namespace() -> list[str]:
    """Test files (besides main.cpp and test_umbrella.cpp) without their own namespace."""
    return [
        src.name
        for src in sorted((ROOT / "cpp" / "tests").glob("test_*.cpp"))
        if src.name != "test_umbrella.cpp"
        and f"namespace unity_{src.stem} {{" not in src.read_text()
    ]


def test_cpp_unit_tests() -> None:
    missing = _missing_unity_namespace()
    assert not missing, (
        f"{missing}: wrap each C++ test file's body (after its includes) in "
        "'namespace unity_<file stem> { ... }': the unity build compiles several files as one unit"
    )
    cmake = shutil.which("cmake")
    ctest = shutil.which("ctest")
    if cmake is None or ctest is None:
        _unavailable("cmake/ctest not found on PATH: the C++ unit tests cannot be built")
    assert cmake is not None and ctest is not None

    generator = "Ninja" if shutil.which("ninja") else None
    jobs = str(max(2, min(os.cpu_count() or 2, 8)))

    with _build_lock():
        _drop_stale_cache(generator)
        configure = [
            cmake,
            "-S",
            str(ROOT),
            "-B",
            str(BUILD_DIR),
            "-DPREISACH_BUILD_TESTS=ON",
            "-DPREISACH_BUILD_PYTHON=OFF",
            f"-DPython_EXECUTABLE={sys.executable}",
        ]
        if generator:
            configure += ["-G", generator]
        res = _run(configure, timeout=300)
        if res.returncode != 0:
            out = res.stdout
            flat = " ".join(out.split())  # CMake wraps its messages
            if 'provided by "doctest"' in flat or "doctestConfig.cmake" in flat:
                _unavailable(
                    "doctest not found by CMake (install doctest, e.g. the Debian/Ubuntu package "
                    "doctest-dev, or set doctest_DIR): the C++ unit tests cannot be built"
                )
            if 'provided by "Eigen3"' in flat or "Eigen3Config.cmake" in flat:
                _unavailable(
                    "Eigen3 not found by CMake (install cmeel-eigen in this Python or the system "
                    "Eigen 3): the C++ unit tests cannot be built"
                )
            cmd = " ".join(configure)
            pytest.fail(f"CMake configure failed:\n{cmd}\n\n{_tail(out)}", pytrace=False)

        build = [cmake, "--build", str(BUILD_DIR), "--parallel", jobs]
        res = _run(build, timeout=900)
        if res.returncode != 0:
            cmd = " ".join(build)
            pytest.fail(f"C++ unit test build failed:\n{cmd}\n\n{_tail(res.stdout)}", pytrace=False)

        # Run from the build dir (ctest --test-dir needs CMake >= 3.20).
        listed = _run([ctest, "-N"], timeout=300, cwd=BUILD_DIR).stdout
        test = [ctest, "--output-on-failure", "--timeout", "300", "-j", jobs]
        res = _run(test, timeout=900, cwd=BUILD_DIR)

    # Every doctest TEST_CASE must be exactly one CTest test: a name CTest cannot carry (a ';'
    # splits it) would silently run zero assertions.
    declared = sorted(
        name
        for src in (ROOT / "cpp" / "tests").glob("*.cpp")
        for name in re.findall(r'^TEST_CASE\("((?:[^"\\]|\\.)*)"', src.read_text(), re.M)
    )
    discovered = sorted(re.findall(r"^\s*Test\s+#\d+: (.*?)\s*$", listed, re.M))
    assert declared == discovered, (
        "doctest cases vs CTest tests differ: "
        f"only declared {sorted(set(declared) - set(discovered))}, "
        f"only discovered {sorted(set(discovered) - set(declared))}"
    )

    output = res.stdout
    assert res.returncode == 0, (
        f"C++ unit tests failed (ctest exit code {res.returncode}):\n\n{_tail(output, 400)}"
    )
    assert "tests passed" in output, f"ctest ran no tests?\n\n{_tail(output)}"
