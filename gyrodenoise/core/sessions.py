"""A record cut at its restarts: the one place that turns a restart mask into runs.

A gyro restart (power cycle, reboot, a gap in a log) starts a new *session*: the
filters start over there, and every figure measured over a record (a spectrum, the
motion kept, a reference filter's run) is measured inside sessions, never across one.
"""

from __future__ import annotations

import numpy as np


def sessions(n, restarts=None, skip_samples=0, finite=None, min_len=1):
    """[(start, stop)] of the usable runs of a record of ``n`` samples.

    Cut at each restart (``restarts[i]`` True: sample i starts a session; sample 0
    always does) and, when ``finite`` is given, at every sample where it is False
    (those samples are left out); the first ``skip_samples`` of each session are left
    out (a filter's warm-up). Runs shorter than ``min_len`` samples are dropped.
    """
    starts = [0] + ([] if restarts is None else
                    [int(i) for i in np.flatnonzero(np.asarray(restarts, dtype=bool)) if i > 0])
    bounds = starts + [int(n)]
    bad = None if finite is None else ~np.asarray(finite, dtype=bool)
    runs = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        a = min(b, a + int(skip_samples))
        if bad is None or not bad[a:b].any():
            runs.append((a, b))
            continue
        cut = np.flatnonzero(bad[a:b]) + a
        edges = [a - 1] + cut.tolist() + [b]
        runs += [(lo + 1, hi) for lo, hi in zip(edges[:-1], edges[1:]) if hi > lo + 1]
    return [(a, b) for a, b in runs if b - a >= max(1, int(min_len))]
