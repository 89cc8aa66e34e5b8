"""Progress and notes for a person: one line on stderr, flushed at once.

stdout is kept for results (``--json`` prints exactly one object there); everything a
person reads while a command runs goes through `log`.
"""

from __future__ import annotations

import sys


def log(msg: object, *, quiet: bool = False, prefix: str = "") -> None:
    """Print ``prefix + msg`` as one line on stderr (nothing when ``quiet``)."""
    if not quiet:
        print(f"{prefix}{msg}", file=sys.stderr, flush=True)
