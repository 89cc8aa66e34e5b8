"""The vehicle's own body-rate estimate, for the HTML report's time plots: one reader per
format (the format adapters' ``vehicle_rate``; :func:`gyrodenoise.flightlog.log_review.vehicle_rate_series`
asks the log's adapter)."""

from __future__ import annotations

import numpy as np


#: RATE / gyro magnitude ratios read as centidegrees per second (older ArduCopter, e.g. 3.3)
CDEG_RATIO_RANGE = (30.0, 300.0)


def rate_scale(time_s, rate, streams):
    """1.0, or 0.01 where ``rate`` (m, 3) reads about 100x the first gyro stream in deg/s
    over the same times (ArduCopter 3.x logs ``RATE`` in centidegrees per second, 4.x in
    degrees per second; the log's FMT does not say): the median of |rate| over the median
    of |gyro| at the same times, within :data:`CDEG_RATIO_RANGE`."""
    g = next((st for st in streams if st.to_deg_s and st.n > 10), None)
    if g is None:
        return 1.0
    t = np.asarray(g.time_s, dtype=np.float64)
    order = np.argsort(t, kind="stable")
    gyro = np.abs(np.asarray(g.raw, dtype=np.float64)[order] * g.to_deg_s)
    t = t[order]
    inside = (time_s >= t[0]) & (time_s <= t[-1])
    if inside.sum() < 10:
        return 1.0
    gi = np.column_stack([np.interp(time_s[inside], t, gyro[:, k]) for k in range(min(3, gyro.shape[1]))])
    num, den = np.nanmedian(np.abs(rate[inside][:, :gi.shape[1]])), np.nanmedian(gi)
    if not (den > 0 and np.isfinite(num)):
        return 1.0
    return 0.01 if CDEG_RATIO_RANGE[0] < num / den < CDEG_RATIO_RANGE[1] else 1.0


def dataflash_rate_series(log, streams):
    """ArduPilot ``RATE`` (``R``, ``P``, ``Y``: the rate controller's measured
    roll/pitch/yaw rates, deg/s in ArduCopter 4.x, centidegrees/s in 3.x, told by
    :func:`rate_scale` against the gyro ``streams``; ``RDes``/``PDes``/``YDes`` its
    targets, a second entry)."""
    out = []
    m = log.messages("RATE")
    scale = None
    for name, cols in (("RATE (R, P, Y)", ("R", "P", "Y")), ("RATE desired (RDes, PDes, YDes)",
                                                            ("RDes", "PDes", "YDes"))):
        if m is not None and all(c in m for c in cols) and len(m["time_s"]):
            t = np.asarray(m["time_s"], dtype=np.float64)
            rate = np.column_stack([np.asarray(m[c], dtype=np.float64) for c in cols])
            if scale is None:                 # from the measured rates, for both entries
                scale = rate_scale(t, rate, streams)
            if scale != 1.0:
                name += ", logged in cdeg/s"
            out.append({"name": name, "time_s": t, "rate": rate * scale, "unit": "deg/s"})
    return out


def ulog_rate_series(log):
    """PX4 ``vehicle_angular_velocity.xyz[0..2]`` (rad/s, converted to deg/s)."""
    m = log.messages("vehicle_angular_velocity")
    cols = ("xyz[0]", "xyz[1]", "xyz[2]")
    if m is None or not all(c in m for c in cols) or not len(m["time_s"]):
        return []
    return [{"name": "vehicle_angular_velocity", "time_s": np.asarray(m["time_s"], dtype=np.float64),
             "rate": np.degrees(np.column_stack([np.asarray(m[c], dtype=np.float64) for c in cols])),
             "unit": "deg/s"}]
