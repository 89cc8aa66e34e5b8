"""Shared test helpers: where the third-party data lives, and skipping without it."""
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


def shared_file(*parts):
    """Path of a file in ../shared/data, or skip the test with a reason."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"third-party data not present: {p} (licence forbids copying it into the repo)")
    return p
