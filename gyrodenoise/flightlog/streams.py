"""Gyro streams in memory, restart detection and the noise figure.

A :class:`GyroStream` is one gyro (one message type and instance of one
vehicle) with its three axes. Readers fill ``time_s``, ``raw`` (in the unit of
the log field) and ``to_deg_s`` (the factor to deg/s, or ``None`` when the log
does not tell the unit); the processing step fills ``filtered``.

Restarts are found by :class:`RestartDetector`, the same rules for files and
live links, sample by sample:

* ``boot_time_backwards``: the vehicle's boot time went backwards (a reboot,
  or a new boot session in a concatenated log);
* ``gap``: the time step is more than ``gap_factor`` times the recent sample
  period (median of the last 16 positive steps; needs 2 of them first);
* a repeated timestamp (step 0) is counted, not a restart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrodenoise.units import RAD_TO_DEG  # noqa: F401 - the flight-log modules' name for it
from gyrodenoise.units import RATE_TO_DEG_S as UNIT_TO_DEG_S  # noqa: F401 - unit label -> factor to deg/s

NOISE_METRIC = ("per axis: raw = the sensor's white-noise standard deviation, the core's own estimate "
                "(gyrodenoise.analysis.motion_metrics.white_noise_std: the motion filter's noise level, the smallest "
                "over lags 1..6 of the mean |4th difference|, median over the record, each session on its "
                "own): slow motion does not lift it (a 4th difference cancels any cubic); it reads 2-6 % "
                "low on white noise; filtered = the same estimate on the output: the sample-to-sample "
                "scatter left, which a smoothing filter removes first (not the noise left inside the "
                "motion band: read it with the motion kept and the lag); ratio = filtered / raw; "
                "first_diff_raw/first_diff_filtered = std of first differences / sqrt(2) within sessions: "
                "noise plus motion plus vibration (mostly motion on a moving 25-50 Hz stream); deg/s "
                "(field units when the unit is unknown)")


@dataclass(slots=True)
class GyroStream:
    """One gyro stream of a log. Every attribute a step sets is declared here (slots: an
    undeclared one raises AttributeError)."""
    name: str                       # e.g. "IMU2", "IMU[1]", "RAW_IMU", "SCALED_IMU2@1.1"
    message: str                    # message type in the log
    unit: str                       # unit of the log field: rad/s, mrad/s, counts, ...
    to_deg_s: float | None          # factor from the field unit to deg/s; None: unknown
    time_s: np.ndarray              # boot time of each sample, s
    raw: np.ndarray                 # (n, 3) raw values in the field unit
    index: np.ndarray               # per sample: index of the record in its log (reader-defined)
    note: str = ""
    filtered: np.ndarray | None = None   # (n, 3) filtered values in the field unit
    restarts: np.ndarray | None = None   # bool (n,), True at the first sample after a restart
    restart_events: list = field(default_factory=list)
    repeated_timestamps: int = 0
    rate_hz: float | None = None
    axes: tuple = ("x", "y", "z")
    extra: dict = field(default_factory=dict)    # reader-specific data (e.g. ISBD multipliers)
    #: how the log stores a gyro value: numpy dtype of the field, and the factor from
    #: the field unit to the stored number (a scalar, or per sample: ISBD ``mul``)
    field_dtype: str = "<f4"
    field_scale: object = 1.0
    #: the stream's instance (IMU number, multi_id) where the log numbers them, else None
    instance: int | None = None
    #: per sample: the record it was read from, in the log's numbering (a DataFlash byte
    #: offset, a telemetry frame index), which tells its boot; None: ``index`` is it
    records: np.ndarray | None = None
    #: where it was logged in the vehicle's filter chain: "pre-filter", "post-filter", "unknown"
    stage: str = "unknown"
    # -- set by the filtering step (gyrodenoise.flightlog.filtering, .live) --
    #: per axis: samples that were not finite, and dropouts healed before filtering
    non_finite: list = field(default_factory=list)
    dropouts_healed: list = field(default_factory=list)
    #: why the stream was not filtered / was written raw (None: it was filtered and written)
    not_filtered: str | None = None
    left_raw: str | None = None
    #: the filter's warm-up (samples) and its cutoff (Hz, filters that have one)
    warmup_samples: int = 0
    cutoff_hz: float | None = None
    #: the rate (Hz) the filter refused to run at, and the option that made it refuse
    rate_refused: float | None = None
    refused_option: object = None
    #: (raw, filtered values in the working unit, the unit, the rate Hz) once filtered
    _work: tuple | None = None
    # -- set by the pipeline (gyrodenoise.flightlog.pipeline) --
    #: the samples its figures are over (flying time by default), its spectrum report
    #: and plot data, and where its plots go
    _figures_mask: np.ndarray | None = None
    _spectrum: dict | None = None
    _spectrum_plot: dict | None = None
    _png: object = None
    _spectrum_png: object = None

    @property
    def n(self):
        return len(self.time_s)

    @property
    def sample_records(self):
        """The record of each sample (``records``, else ``index``)."""
        return self.index if self.records is None else self.records

    def work_units(self):
        """(raw values in the unit the filter works in, factor back, unit label)."""
        if self.to_deg_s is None:
            return self.raw.astype(np.float64), 1.0, self.unit
        return self.raw.astype(np.float64) * self.to_deg_s, 1.0 / self.to_deg_s, "deg/s"


@dataclass
class AccelStream:
    """An accelerometer stream of a log (a FlightLog's ``accel``): ULog ``sensor_accel_fifo``,
    a ROS bag's Imu ``linear_acceleration``, a blackbox's ``accSmooth``; m/s^2."""
    name: str
    message: str
    time_s: np.ndarray               # time of each sample on the log's time axis, s
    values: np.ndarray               # (n, 3) m/s^2
    unit: str = "m/s^2"
    rate_hz: float | None = None
    note: str = ""


def field_misfit(stream, values):
    """Samples (bool (n, 3)) whose ``values`` (field unit) cannot be stored in the
    log's field as they are: beyond the integer type's range once rounded, or
    overflowing a float type (NaN in a float field is stored as NaN). Never
    clipped silently: the caller leaves such a stream raw and reports it."""
    return misfit(values, stream.field_dtype, stream.field_scale)


def require_fit(name, values, dtype, scale=1.0):
    """The writers' last guard (every format's): ValueError naming ``name`` when a value of
    ``values`` (field unit, times ``scale``) cannot be stored in ``dtype`` (:func:`misfit`;
    an integer field holds no NaN or infinity, a float field holds them as themselves).
    Callers check :func:`field_misfit` first and leave such a stream raw: never clipped."""
    v = np.asarray(values, dtype=np.float64)
    bad = misfit(v, dtype, scale)
    if np.dtype(dtype).kind not in "iu":
        bad &= np.isfinite(v)
    if np.any(bad):
        raise ValueError(f"{name}: a value does not fit {np.dtype(dtype).name} (check field_misfit first)")


def misfit(values, dtype, scale=1.0):
    """:func:`field_misfit` for a dtype and a scale (scalar, or one per row)."""
    v = np.asarray(values, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    if scale.ndim == 1 and v.ndim == 2:
        scale = scale[:, None]
    dt = np.dtype(dtype)
    with np.errstate(invalid="ignore", over="ignore"):
        stored = v * scale
        if dt.kind in "iu":
            info = np.iinfo(dt)
            r = np.rint(stored)
            return ~((r >= info.min) & (r <= info.max))
        return np.isinf(stored) | (np.abs(stored) > np.finfo(dt).max)


class RestartDetector:
    """Online restart detection on a stream's boot time (seconds)."""

    HISTORY = 16
    MIN_HISTORY = 2

    def __init__(self, gap_factor=5.0):
        if not gap_factor > 1.0:
            raise ValueError(f"gap_factor must be > 1, got {gap_factor!r}")
        self.gap_factor = float(gap_factor)
        self.prev = None
        self.dts = []
        self.repeated = 0

    def period(self):
        k = len(self.dts)
        if k < self.MIN_HISTORY:
            return None
        s = sorted(self.dts)
        return s[k // 2] if k % 2 else 0.5 * (s[k // 2 - 1] + s[k // 2])

    def update(self, t):
        """Feed one timestamp; return None or the restart reason for this sample."""
        prev, self.prev = self.prev, t
        if prev is None:
            return None
        dt = t - prev
        if dt < 0:
            return "boot_time_backwards"
        if dt == 0:
            self.repeated += 1
            return None
        p = self.period()
        self.dts.append(dt)
        if len(self.dts) > self.HISTORY:
            del self.dts[0]
        if p is not None and dt > self.gap_factor * p:
            return "gap"
        return None


def restart_flags(t, gap_factor=5.0):
    """Vectorised :class:`RestartDetector` over a whole array of times (same
    decisions, sample for sample). Returns (flags, reasons, repeated)."""
    t = np.asarray(t, dtype=np.float64)
    n = len(t)
    flags = np.zeros(n, dtype=bool)
    reasons = np.full(n, "", dtype=object)
    if n < 2:
        return flags, reasons, 0
    dt = np.diff(t)
    back = np.nonzero(dt < 0)[0] + 1
    flags[back] = True
    reasons[back] = "boot_time_backwards"
    repeated = int(np.count_nonzero(dt == 0))
    pos_idx = np.nonzero(dt > 0)[0]               # dt index of each positive step
    pdt = dt[pos_idx]
    H, M = RestartDetector.HISTORY, RestartDetector.MIN_HISTORY
    m = len(pdt)
    if m > M:
        period = np.full(m, np.nan)
        for j in range(M, min(H, m)):             # growing window at the start
            period[j] = np.median(pdt[:j])
        if m > H:
            from numpy.lib.stride_tricks import sliding_window_view
            period[H:] = np.median(sliding_window_view(pdt, H)[:m - H], axis=1)
        gap = np.nonzero(pdt > gap_factor * period)[0]    # nan compares False
        g = pos_idx[gap] + 1
        flags[g] = True
        reasons[g] = "gap"
    return flags, reasons, repeated


def detect_restarts(stream: GyroStream, gap_factor=5.0):
    """Fill ``stream.restarts``, ``restart_events``, ``repeated_timestamps`` and
    ``rate_hz`` (1 / median positive step within sessions)."""
    t = stream.time_s
    r, reasons, repeated = restart_flags(t, gap_factor)
    stream.restarts = r
    stream.restart_events = [
        {"stream": stream.name, "sample": int(i), "time_s": float(t[i]),
         "previous_time_s": float(t[i - 1]), "reason": reasons[i]} for i in np.nonzero(r)[0]]
    stream.repeated_timestamps = repeated
    stream.rate_hz = measured_rate_hz(t, r)
    return r


def measured_rate_hz(time_s, restarts):
    """Sample rate from the median positive time step within sessions (Hz), or None."""
    dt = np.diff(np.asarray(time_s, dtype=np.float64))
    ok = (dt > 0) & ~np.asarray(restarts, dtype=bool)[1:]
    return float(1.0 / np.median(dt[ok])) if ok.any() else None


def noise_per_axis(values, restarts):
    """Std of first differences / sqrt(2) of each column of ``values``, pairs
    inside one session (``first_diff_*`` of :data:`NOISE_METRIC`): the white
    noise's sigma on a still record, lifted by motion and vibration."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 1:
        v = v[:, None]
    if len(v) < 3:
        return [None] * v.shape[1]
    keep = np.ones(len(v) - 1, dtype=bool)
    if restarts is not None:
        keep &= ~np.asarray(restarts, dtype=bool)[1:]
    out = []
    for k in range(v.shape[1]):
        d = np.diff(v[:, k])[keep]
        d = d[np.isfinite(d)]                  # pairs with a NaN/inf sample do not count
        out.append(float(d.std(ddof=1) / math.sqrt(2.0)) if len(d) >= 2 else None)
    return out


def kept_restarts(restarts, keep):
    """Restart flags of the samples kept by the bool mask ``keep``: a restart on a
    dropped sample moves to the next kept one (a filter fed only the kept samples
    starts over there)."""
    idx = np.nonzero(keep)[0]
    cr = np.concatenate([[0], np.cumsum(restarts, dtype=np.int64)])
    prev = np.concatenate([[0], idx[:-1] + 1])
    return (cr[idx + 1] - cr[prev]) > 0
