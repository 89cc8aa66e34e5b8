"""Where the benchmarks find this checkout and the third-party data: ``../shared/data`` beside
the repository, or the folder named by the environment variable GYRODENOISE_SHARED_DATA
(tests/conftest.py reads the same variable)."""

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("GYRODENOISE_SHARED_DATA") or REPO.parent / "shared" / "data")
