"""Fixtures shared by the tests of every area: the session's FMU build (pythonfmu and native
FMUs, built once, started in the background as soon as the tests to run are known). Plain
helpers are in tests/helpers.py."""
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

NATIVE_REPORT_PREFIX = "gyrodenoise: native "      # the stderr lines of `fmu build` (gyrodenoise/cli/fmu.py)
#: fixtures whose setup builds FMUs (tens of seconds): a test that uses one is in the slow tier
FMU_BUILD_FIXTURES = frozenset({"fmu_build", "native_build"})
#: a cold zig cache (a fresh CI machine) builds each target's C library first: measured on 2
#: shared cores, 229 s for linux64 + win64 + darwin64 and 44 s more for the two aarch64 targets
BUILD_TIMEOUT_S = 480


class FmuBuild:
    """`gyrodenoise fmu build --out DIR` started in a subprocess; :meth:`result` waits for it.
    stdout and stderr go to files in DIR's parent (a pipe nobody reads could stall the build)."""

    def __init__(self, out):
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self._stdout = open(self.out.parent / "fmu_build.stdout", "w+")
        self._stderr = open(self.out.parent / "fmu_build.stderr", "w+")
        self.args = [sys.executable, "-m", "gyrodenoise.cli", "fmu", "build", "--out", str(self.out)]
        self.proc = subprocess.Popen(self.args, stdout=self._stdout, stderr=self._stderr, text=True)
        self._result = None

    def result(self):
        """(folder, CompletedProcess) once the build has exited (killed after BUILD_TIMEOUT_S)."""
        if self._result is None:
            try:
                self.proc.wait(timeout=BUILD_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                raise
            self._stdout.seek(0)
            self._stderr.seek(0)
            self._result = (self.out, subprocess.CompletedProcess(self.args, self.proc.returncode,
                                                                   self._stdout.read(), self._stderr.read()))
        return self._result

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self._stdout.close()
        self._stderr.close()


BACKGROUND_BUILD = pytest.StashKey[FmuBuild]()


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark ``slow`` every test that needs the session's FMU build, so that the quick tier
    (``pytest -m "not slow"``) never builds an FMU (tryfirst: before -m deselects)."""
    for item in items:
        if FMU_BUILD_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


def pytest_collection_finish(session):
    """When a test to run needs the FMU build, start it now: it then runs beside the tests
    that come before its first user (the build is mostly compilers, ~35 s)."""
    if session.config.option.collectonly or os.environ.get("PYTEST_XDIST_WORKER"):
        return          # under pytest-xdist every worker collects every test: the fixture builds, when needed
    if any(FMU_BUILD_FIXTURES & set(getattr(item, "fixturenames", ())) for item in session.items):
        folder = Path(tempfile.mkdtemp(prefix="gyrodenoise-fmu-build-"))
        session.config.stash[BACKGROUND_BUILD] = FmuBuild(folder / "fmus")


def pytest_sessionfinish(session):
    build = session.config.stash.get(BACKGROUND_BUILD, None)
    if build is not None:
        build.close()
        shutil.rmtree(build.out.parent, ignore_errors=True)


@pytest.fixture(scope="session")
def fmu_build(request, tmp_path_factory):
    """`gyrodenoise fmu build --out DIR` run once per session in a subprocess: the pythonfmu
    FMUs (FogDenoiser, SimulatedFog) and the native ones (FogDenoiserNative, SimulatedFogNative,
    every platform a compiler is found for); (folder, CompletedProcess). Each user checks the
    exit status its own way (tests/fmu/test_build_and_run.py asserts it, tests/mavlink/test_fmu_engine.py
    skips).
    One build serves every test that needs a built FMU: it is the suite's costliest setup
    (~35 s with a warm zig cache, five native platforms x two models), started when the session's tests are known
    (pytest_collection_finish), or here."""
    build = request.config.stash.get(BACKGROUND_BUILD, None)
    if build is None:
        build = FmuBuild(tmp_path_factory.mktemp("fmu_build") / "fmus")
        request.addfinalizer(build.close)
    return build.result()


@pytest.fixture(scope="session")
def native_build(fmu_build, tmp_path_factory):
    """The native FMUs (FogDenoiserNative, SimulatedFogNative and the FMI 3.0 ones) for every
    platform a compiler is found for; (folder, {platform: compiler or skip reason}). Taken from the session's
    `fmu build` (its stderr report is build_native_fmus' report, one line a platform); if that
    build failed, built alone here (gyrodenoise.fmu.native3.build_native_fmus), or skipped."""
    out, proc = fmu_build
    if proc.returncode == 0:
        report = {}
        for line in proc.stderr.splitlines():
            if line.startswith(NATIVE_REPORT_PREFIX):
                plat, _, what = line[len(NATIVE_REPORT_PREFIX):].partition(": ")
                report[plat] = what
        if report and all((out / f"{n}.fmu").is_file() for n in ("FogDenoiserNative", "SimulatedFogNative")):
            return out, report
    from gyrodenoise.errors import InputError
    from gyrodenoise.fmu import native3
    out = tmp_path_factory.mktemp("native_fmus")
    report = {}
    try:
        native3.build_native_fmus(out, report=report)    # FMI 2.0 and 3.0
    except InputError as exc:
        pytest.skip(f"native FMU not buildable here: {exc}")
    return out, report
