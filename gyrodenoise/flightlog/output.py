"""The per-stream files of a processed log: their names, the CSV, and the time
axis that lays a stream's sessions end to end.
"""

from __future__ import annotations

import re

import numpy as np

from gyrodenoise.flightlog.stopping import atomic_path


def safe_name(s):
    """``s`` with every run of characters unsafe in a file name replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", s).strip("_")


def joined_time(t, restarts):
    """A monotonic time axis for plots: sessions laid end to end."""
    t = np.asarray(t, dtype=np.float64)
    if len(t) < 2:
        return t - (t[0] if len(t) else 0)
    dt = np.diff(t)
    pos = dt[(dt > 0) & ~restarts[1:]]
    period = float(np.median(pos)) if len(pos) else 1.0
    step = np.where((dt > 0) & ~restarts[1:], dt, period)
    return np.concatenate([[0.0], np.cumsum(step)])


def write_csv(path, s, x_work, f_work, unit):
    """``time,raw_x,filtered_x,raw_y,filtered_y,raw_z,filtered_z,restart``; time in s
    (the log's boot time), values in deg/s (or ``*_<unit>`` columns when the unit
    is unknown), 9 significant digits; restart is 1 on the first sample after a restart."""
    suffix = "" if unit == "deg/s" else "_" + safe_name(unit)
    cols = ["time"]
    parts = [map("{:.6f}".format, np.asarray(s.time_s, dtype=np.float64).tolist())]
    for k, a in enumerate(s.axes):
        cols += [f"raw_{a}{suffix}", f"filtered_{a}{suffix}"]
        parts += [map("{:.9g}".format, x_work[:, k].tolist()), map("{:.9g}".format, f_work[:, k].tolist())]
    cols.append("restart")
    parts.append(map(str, s.restarts.astype(np.int8).tolist()))
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        fh.write(",".join(cols) + "\n")
        if len(s.time_s):
            fh.write("\n".join(map(",".join, zip(*parts))))
            fh.write("\n")
