"""Fixtures shared by the tests of every area: the session's FMU build (pythonfmu and native
FMUs, built once). Plain helpers are in tests/helpers.py."""
import subprocess
import sys

import pytest

NATIVE_REPORT_PREFIX = "gyrodenoise: native "      # the stderr lines of `fmu build` (gyrodenoise/cli/fmu.py)


@pytest.fixture(scope="session")
def fmu_build(tmp_path_factory):
    """`gyrodenoise fmu build --out DIR` run once per session in a subprocess: the pythonfmu
    FMUs (FogDenoiser, SimulatedFog) and the native ones (FogDenoiserNative, SimulatedFogNative,
    every platform a compiler is found for); (folder, CompletedProcess). Each user checks the
    exit status its own way (tests/fmu/test_build_and_run.py asserts it, tests/mavlink/test_fmu_engine.py
    skips).
    One build serves every test that needs a built FMU: it is the suite's costliest setup
    (~35 s, three native platforms x two models)."""
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


#: fixtures whose setup builds FMUs (tens of seconds): a test that uses one is in the slow tier
FMU_BUILD_FIXTURES = frozenset({"fmu_build", "native_build"})


def pytest_collection_modifyitems(config, items):
    """Mark ``slow`` every test that needs the session's FMU build, so that the quick tier
    (``pytest -m "not slow"``) never builds an FMU."""
    for item in items:
        if FMU_BUILD_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
