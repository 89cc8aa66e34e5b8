"""A commit of this repository checked out beside it, for the before/after benchmarks
(bench_vs_commit.py, bench_bridge.py --against)."""

from __future__ import annotations

import contextlib
import shutil
import subprocess
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def checkout(rev, with_this_core=False):
    """Yield the root of ``rev`` in a temporary git worktree, removed afterwards.

    ``with_this_core``: copy this tree's compiled extensions into it (the comparison is
    then of the Python around the C core; ``rev`` must have the same core)."""
    with tempfile.TemporaryDirectory(prefix="gd_rev_") as tmp:
        root = Path(tmp) / "tree"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(root), rev], check=True)
        try:
            if with_this_core:
                for so in REPO.joinpath("gyrodenoise").rglob("*.so"):
                    shutil.copy2(so, root / so.relative_to(REPO))
            yield root
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(root)], check=False)
