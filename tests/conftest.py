"""Shared test helpers: where the third-party data lives, and skipping without it."""
import os
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


@pytest.fixture(scope="session")
def native_build(tmp_path_factory):
    """The native FMUs (FogDenoiserNative, SimulatedFogNative), compiled once per session for every
    platform a compiler is found for (gyrodenoise.fmu.native.build_native_fmus); (folder,
    {platform: compiler or skip reason})."""
    from gyrodenoise.errors import InputError
    from gyrodenoise.fmu import native
    out = tmp_path_factory.mktemp("native_fmus")
    report = {}
    try:
        native.build_native_fmus(out, report=report)
    except InputError as exc:
        pytest.skip(f"native FMU not buildable here: {exc}")
    return out, report
