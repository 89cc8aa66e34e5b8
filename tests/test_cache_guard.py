"""The numba cache guard: compiled loops inline kernels.py, which numba's cache
key does not cover, so their cache files are dropped when kernels.py changes."""
import hashlib
from pathlib import Path

import gyrodenoise.batch as batch


def test_stale_cache_files_are_dropped_and_fresh_ones_kept():
    cache = Path(batch.__file__).resolve().parent / "__pycache__"
    cache.mkdir(exist_ok=True)
    owner, pattern = "gdtest_guard", "gdtest_guard.*.nb[ic]"
    stamp = cache / f"{owner}.kernels.sha256"
    fake = cache / "gdtest_guard.run-1.py311.nbi"
    try:
        stamp.write_text("a hash of an older kernels.py")
        fake.write_bytes(b"x")
        batch.invalidate_stale_cache(owner, (pattern,))
        assert not fake.exists()
        digest = hashlib.sha256((cache.parent / "kernels.py").read_bytes()).hexdigest()
        assert stamp.read_text() == digest
        fake.write_bytes(b"x")                        # written after the stamp: current
        batch.invalidate_stale_cache(owner, (pattern,))
        assert fake.exists()
    finally:
        fake.unlink(missing_ok=True)
        stamp.unlink(missing_ok=True)
