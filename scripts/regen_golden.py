"""Rewrite the golden JSON files (tests/golden/*.json) from the tests that compare with them
(marked ``golden``), then show what changed: review it as a diff before committing.

    python scripts/regen_golden.py            # every golden file
    python scripts/regen_golden.py -k moving  # those of the tests matching -k (pytest's)

The tests write their outputs, normalised (tests/helpers.py normalise_json: times and
versions replaced by "<volatile>", this run's folders by "<tmp>"), instead of comparing
them, with GYRODENOISE_REGEN_GOLDEN set; nothing else changes.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    env = dict(os.environ, GYRODENOISE_REGEN_GOLDEN="1")
    rc = subprocess.call([sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                          "-m", "golden", *argv], cwd=ROOT, env=env)
    if rc != 0:
        print(f"regen_golden: the golden tests failed (exit {rc}): files may be partly rewritten",
              file=sys.stderr)
        return rc
    subprocess.call(["git", "status", "--short", "--", "tests/golden"], cwd=ROOT)
    subprocess.call(["git", "--no-pager", "diff", "--stat", "--", "tests/golden"], cwd=ROOT)
    print("review: git diff tests/golden", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
