"""The stamp at the top of every benchmark report: the commit and the command that produced it.

    from benchmarks.provenance import stamp
    lines = ["# Title", "", stamp(argv), ""]

``stamp`` reads the commit with ``git rev-parse --short HEAD`` and adds "+ uncommitted changes"
when a tracked file differs from it (the reports under ``docs/reports`` left out: a previous
run rewrites them); the command is ``python`` and the script's path relative to the repository
root, then the arguments as given.
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

from benchmarks._data import REPO


def _git(*args):
    try:
        r = subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return r.stdout.strip() if r.returncode == 0 else None


def commit():
    """``abc1234``, ``abc1234 + uncommitted changes``, or ``unknown commit`` outside a git checkout."""
    head = _git("rev-parse", "--short", "HEAD")
    if head is None:
        return "unknown commit"
    dirty = _git("status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)docs/reports")
    return head + (" + uncommitted changes" if dirty else "")


def command(argv=None):
    """``python benchmarks/NAME.py ARG...``: the running script and ``argv`` (default ``sys.argv[1:]``)."""
    script = Path(sys.argv[0]).resolve()
    try:
        script = script.relative_to(REPO)
    except ValueError:
        pass
    args = sys.argv[1:] if argv is None else [str(a) for a in argv]
    return shlex.join(["python", script.as_posix(), *args])


def stamp(argv=None):
    """One Markdown line: the commit and the command."""
    return f"Commit `{commit()}`; command `{command(argv)}`."
