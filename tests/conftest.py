"""Fixtures shared by the tests of every area: the session's FMU build (pythonfmu and native
FMUs, built once, started in the background as soon as the tests to run are known). Plain
helpers are in tests/helpers.py."""
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import pytest

NATIVE_REPORT_PREFIX = "gyrodenoise: native "      # the stderr lines of `fmu build` (gyrodenoise/cli/fmu.py)
#: fixtures whose setup is the session's FMU build (tens of seconds), started in the background
FMU_BUILD_FIXTURES = frozenset({"fmu_build", "native_build"})
#: a test that uses one of these is in the slow tier: the session's build, or ``builds_fmus``,
#: which a fixture that builds FMUs of its own (pythonfmu, gcc) requests (tests/test_quick_tier.py
#: checks that every such fixture does)
SLOW_FIXTURES = FMU_BUILD_FIXTURES | {"builds_fmus"}
#: a cold zig cache (a fresh CI machine) builds each target's C library first: measured on 2
#: shared cores, 229 s for linux64 + win64 + darwin64 and 44 s more for the two aarch64 targets
BUILD_TIMEOUT_S = 480
#: the FMI 3.0 FMUs are built for this machine's platform only in the tests: each denoiser compile
#: takes ~8 s (the core's unrolled AR loops), and the FMI 3.0 cross builds are inspected nowhere
#: that the FMI 2.0 ones are not (same sources, same compiler flags)
FMI3_TEST_PLATFORM = "linux64"


def _build_command(out):
    """The shell command of the session's build: every FMI 2.0 FMU (pythonfmu and native, every
    platform a compiler is found for), then the native FMI 3.0 ones for :data:`FMI3_TEST_PLATFORM`;
    its exit status is written to ``rc`` beside ``out`` when it ends (others may wait on it)."""
    cli = [sys.executable, "-m", "gyrodenoise.cli", "fmu", "build", "--out", str(out)]
    q = " ".join
    first = q(shlex.quote(a) for a in cli + ["--fmi-versions", "2"])
    second = q(shlex.quote(a) for a in cli + ["--fmi-versions", "3", "--platforms", FMI3_TEST_PLATFORM])
    rc = shlex.quote(str(out.parent / "rc"))
    return f"{first} && {second}; echo $? > {rc}.tmp && mv {rc}.tmp {rc}"


class FmuBuild:
    """The session's FMU build (:func:`_build_command`) in a subprocess; :meth:`result` waits for it.
    stdout and stderr go to files in DIR's parent (a pipe nobody reads could stall the build).

    Under pytest-xdist the workers share one build: the first to create the folder (named by
    the test run's id, the same in every worker) starts it, the others wait for its ``rc``
    file; the controller removes the folder at the end of the run. Alone (``-n 0``) the folder
    is this session's own."""

    def __init__(self, folder):
        self.folder = Path(folder)
        self.out = self.folder / "fmus"
        self.proc = None
        try:
            self.folder.mkdir(parents=True)
        except FileExistsError:
            return                                   # another worker builds
        self.out.mkdir()
        with open(self.folder / "stdout", "w") as fo, open(self.folder / "stderr", "w") as fe:
            self.proc = subprocess.Popen(["sh", "-c", _build_command(self.out)], stdout=fo, stderr=fe,
                                         start_new_session=True)
        self._result = None

    def result(self):
        """(folder, CompletedProcess) once the build has exited (TimeoutError after BUILD_TIMEOUT_S)."""
        rc_file = self.folder / "rc"
        deadline = time.monotonic() + BUILD_TIMEOUT_S
        while not rc_file.is_file():
            if time.monotonic() > deadline:
                raise TimeoutError(f"the session's FMU build did not end in {BUILD_TIMEOUT_S} s ({self.folder})")
            time.sleep(0.2)
        rc = int(rc_file.read_text().strip() or 1)
        return self.out, subprocess.CompletedProcess(_build_command(self.out), rc,
                                                     (self.folder / "stdout").read_text(),
                                                     (self.folder / "stderr").read_text())

    def close(self, wait_s=0.0):
        """Stop the build if it still runs (alone: at the end of the session; a worker leaves a
        shared build running, others may wait on it)."""
        if self.proc is not None and self.proc.poll() is None:
            try:
                self.proc.wait(timeout=wait_s)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()


BACKGROUND_BUILD = pytest.StashKey[FmuBuild]()
SHARED_PREFIX = "gyrodenoise-fmu-build-"


def _shared_folder():
    """The build folder every xdist worker of this run names alike, or None outside xdist."""
    uid = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    return Path(tempfile.gettempdir()) / f"{SHARED_PREFIX}{uid}" if uid else None


REPO = Path(__file__).resolve().parents[1]


def _checkout_first_on_pythonpath():
    """The programs the tests start (``python -m gyrodenoise.cli``, the console script, the
    session's ``fmu build``) import this checkout's package, as the tests themselves do
    (pyproject's ``pythonpath = ["."]``), not an installed copy of another checkout (an
    editable install made from a sibling worktree). Tests that check an installed copy set
    their own PYTHONPATH."""
    parts = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    if str(REPO) not in parts:
        os.environ["PYTHONPATH"] = os.pathsep.join([str(REPO)] + parts)


def pytest_configure(config):
    """Subprocesses import this checkout (:func:`_checkout_first_on_pythonpath`). The
    controller fixes the test run's id (xdist passes it to the workers), so that it
    can remove the workers' shared build folder at the end."""
    _checkout_first_on_pythonpath()
    if not os.environ.get("PYTEST_XDIST_WORKER") and hasattr(config.option, "testrunuid") \
            and config.option.testrunuid is None:
        config.option.testrunuid = uuid.uuid4().hex


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark ``slow`` every test that needs an FMU built (SLOW_FIXTURES), so that the quick
    tier (``pytest -m "not slow"``) never builds one (tryfirst: before -m deselects)."""
    for item in items:
        if SLOW_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


def pytest_collection_finish(session):
    """When a test to run needs the FMU build, start it now: it then runs beside the tests
    that come before its first user (the build is mostly compilers). Under xdist every worker
    collects every test; the first to get here starts the one shared build."""
    if session.config.option.collectonly:
        return
    if any(FMU_BUILD_FIXTURES & set(getattr(item, "fixturenames", ())) for item in session.items):
        session.config.stash[BACKGROUND_BUILD] = _start_build()


def _start_build():
    shared = _shared_folder()
    return FmuBuild(shared if shared is not None else Path(tempfile.mkdtemp(prefix=SHARED_PREFIX)) / "own")


def pytest_sessionfinish(session):
    build = session.config.stash.get(BACKGROUND_BUILD, None)
    if build is not None and _shared_folder() is None:
        build.close()
        shutil.rmtree(build.folder.parent, ignore_errors=True)
    uid = getattr(session.config.option, "testrunuid", None)
    if uid and not os.environ.get("PYTEST_XDIST_WORKER"):
        # the controller, after every worker has ended: the shared build's folder (its build
        # process, if no test waited for it to end, is stopped first)
        folder = Path(tempfile.gettempdir()) / f"{SHARED_PREFIX}{uid}"
        _stop_left_build(folder)
        shutil.rmtree(folder, ignore_errors=True)


def _stop_left_build(folder):
    """Wait up to BUILD_TIMEOUT_S for a shared build nobody waited on (its ``rc`` file), so that
    its compilers do not write into a removed folder."""
    if not folder.is_dir():
        return
    deadline = time.monotonic() + BUILD_TIMEOUT_S
    while not (folder / "rc").is_file() and time.monotonic() < deadline:
        time.sleep(0.2)


@pytest.fixture(scope="session")
def builds_fmus():
    """Nothing to set up: requested by a fixture that builds FMUs itself, it puts the tests
    using that fixture in the slow tier (:func:`pytest_collection_modifyitems`)."""


@pytest.fixture(scope="session")
def fmu_build(request, tmp_path_factory):
    """`gyrodenoise fmu build --out DIR` run once per session in a subprocess: the pythonfmu
    FMUs (FogDenoiser, SimulatedFog) and the native ones (FogDenoiserNative, SimulatedFogNative,
    every platform a compiler is found for); (folder, CompletedProcess). Each user checks the
    exit status its own way (tests/fmu/test_build_and_run.py asserts it, tests/flightlog/test_fmu_engine.py
    skips).
    One build serves every test that needs a built FMU: it is the suite's costliest setup
    (~35 s with a warm zig cache, five native platforms x two models), started when the session's tests are known
    (pytest_collection_finish), or here."""
    build = request.config.stash.get(BACKGROUND_BUILD, None)
    if build is None:
        build = request.config.stash[BACKGROUND_BUILD] = _start_build()
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
