"""Shared test helpers: where the third-party data lives, and skipping without it; the
session's FMU build; running a program under wine; the CLI in this process."""
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# ../shared/data beside the repository, or the folder named by GYRODENOISE_SHARED_DATA
SHARED_DATA = Path(os.environ.get("GYRODENOISE_SHARED_DATA") or REPO.parent / "shared" / "data")


def shared_file(*parts):
    """Path of a file in the shared data (SHARED_DATA), or skip the test with a reason."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"third-party data not present: {p} (licence forbids copying it into the repo)")
    return p


NATIVE_REPORT_PREFIX = "gyrodenoise: native "      # the stderr lines of `fmu build` (fmu/cli.py _cmd_build)


@pytest.fixture(scope="session")
def fmu_build(tmp_path_factory):
    """`gyrodenoise fmu build --out DIR` run once per session in a subprocess: the pythonfmu
    FMUs (FogDenoiser, SimulatedFog) and the native ones (FogDenoiserNative, SimulatedFogNative,
    every platform a compiler is found for); (folder, CompletedProcess). Each user checks the
    exit status its own way (tests/test_fmu.py asserts it, tests/test_bridge_fmu.py skips).
    One build serves every test that needs a built FMU: it is the suite's costliest setup
    (~35 s, three native platforms x two models) and was run three times."""
    out = tmp_path_factory.mktemp("fmus")
    proc = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "fmu", "build", "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    return out, proc


@pytest.fixture(scope="session")
def native_build(fmu_build, tmp_path_factory):
    """The native FMUs (FogDenoiserNative, SimulatedFogNative) for every platform a compiler is
    found for; (folder, {platform: compiler or skip reason}). Taken from the session's
    `fmu build` (its stderr report is build_native_fmus' report, one line a platform); if that
    build failed, built alone here (gyrodenoise.fmu.native.build_native_fmus), or skipped."""
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
    from gyrodenoise.fmu import native
    out = tmp_path_factory.mktemp("native_fmus")
    report = {}
    try:
        native.build_native_fmus(out, report=report)
    except InputError as exc:
        pytest.skip(f"native FMU not buildable here: {exc}")
    return out, report


def run_wine(cmd, input=None, env=None, timeout=180):
    """``subprocess.run(cmd, input=input, capture_output=True, text=True, env=env, timeout=timeout)``
    for a program run under wine, with stdout and stderr caught in temporary files instead of
    pipes. The wineserver that a wine client starts inherits the client's stdout and stderr and
    stays ~3 s after the last client exits (its default persistence), so a pipe reader waits
    those 3 s for end-of-file on every run (measured: 2.9 s a run with pipes, 0.7 s with files,
    tests/chost/host.c under wine, 2400 samples); a file is read once the program has exited."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.run(cmd, input=input, stdout=out, stderr=err, text=True, env=env, timeout=timeout)
        out.seek(0)
        err.seek(0)
        return subprocess.CompletedProcess(proc.args, proc.returncode, out.read(), err.read())


#: the warnings a Python process prints with its default filters (all but these categories)
SILENT_BY_DEFAULT = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


def main_in_process(capfd, *args):
    """``gyrodenoise ARGS`` run by gyrodenoise.cli in this process: (exit status,
    stdout, stderr). Read at the file descriptors (capfd: C-level writes too); a warning that
    a process of its own would print (default filters) is a line of stderr; an exception is
    a traceback and fails the caller."""
    from gyrodenoise.cli import main
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            status = main([str(a) for a in args])
        except SystemExit as exc:           # argparse errors leave with sys.exit(2)
            status = exc.code
    out, err = capfd.readouterr()
    err += "".join(f"{w.category.__name__}: {w.message}\n" for w in caught
                   if not issubclass(w.category, SILENT_BY_DEFAULT))
    return status, out, err
