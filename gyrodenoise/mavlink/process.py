"""One log end to end (read, find restarts, denoise, write), and many logs in a pool.

Outputs of a log ``NAME.ext`` in the output folder:

* ``NAME.filtered.ext`` -- the log with the gyro fields of the IMU messages
  replaced by the filtered values (same messages, same order; only those
  fields, and for MAVLink the CRC, differ);
* ``NAME.STREAM.csv`` -- ``time,raw_x,filtered_x,raw_y,filtered_y,raw_z,filtered_z,restart``
  per stream (deg/s; ``*_counts`` columns when the unit is unknown);
* ``NAME.STREAM.png`` -- raw and filtered per axis, restarts marked;
* ``NAME.spectrum.png`` -- per stream raw and filtered PSD per axis, vibration
  peaks named; the filter's gain and lag; a spectrogram for a long record
  (:mod:`gyrodenoise.mavlink.spectra`).
"""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

import numpy as np

from gyrodenoise.errors import InputError, Terminated

from gyrodenoise.mavlink import dataflash
from gyrodenoise.core.kernels import DEFAULT_METHOD

from gyrodenoise.mavlink.stopping import as_child, atomic_path, signals_blocked, stop_processes
from gyrodenoise.mavlink.spectra import SPECTRUM_METRIC
from gyrodenoise.mavlink.streams import NOISE_METRIC, detect_restarts, field_misfit, noise_per_axis

MOTION_METRIC = ("per axis, over each session after the filter's warm-up: the 0-5 Hz content of "
                 "raw and filtered (zero-phase Butterworth order 4, session mean removed); corr = "
                 "their correlation, amplitude_ratio = std filtered / std raw, lag_s = delay of "
                 "the filtered one at the peak of their cross-correlation (within 0.5 s); "
                 "gyrodenoise.analysis.motion_metrics")

LOG_SUFFIXES = {".tlog": "tlog", ".mavlink": "tlog", ".bin": "dataflash", ".ulg": "ulog"}
GYRO_LOOKED_FOR = {
    "tlog": "RAW_IMU, SCALED_IMU, SCALED_IMU2, SCALED_IMU3, HIGHRES_IMU",
    "dataflash": "IMU, IMU2, IMU3 with GyrX/GyrY/GyrZ, ISBH/ISBD gyro bursts",
    "ulog": "sensor_combined.gyro_rad, sensor_gyro",
}


def log_kind(path):
    """'tlog', 'dataflash' or 'ulog' from the suffix, else from the first bytes."""
    p = Path(path)
    kind = LOG_SUFFIXES.get(p.suffix.lower())
    if kind:
        return kind
    try:
        with open(p, "rb") as fh:
            head = fh.read(600)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if head[:2] == b"\xa3\x95":
        return "dataflash"
    if head[:7] == b"ULog\x01\x12\x35":
        return "ulog"
    from gyrodenoise.mavlink import tlog
    if tlog.looks_like_tlog(head):
        return "tlog"
    raise InputError(f"{path}: unknown file type (expected a MAVLink telemetry log .tlog, "
                     f"an ArduPilot DataFlash log .bin or a PX4 log .ulg)")


def safe_name(s):
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


def _envelope(t, y, nbins=2000):
    """Min/max per bin of a long line (what a raster plot shows anyway)."""
    n = len(y)
    if n <= 2 * nbins:
        return t, y
    edges = np.linspace(0, n, nbins + 1).astype(np.int64)[:-1]
    lo = np.minimum.reduceat(y, edges)
    hi = np.maximum.reduceat(y, edges)
    return np.repeat(t[edges], 2), np.column_stack([lo, hi]).ravel()


def plot_time(time_s, restarts):
    """(time axis of a stream's plot, x-axis label). The log's boot time, as in the
    summary and the CSV (gaps shown as gaps), when it never goes backwards; else
    (a reboot, a concatenated log) the sessions laid end to end from the first
    sample's boot time (:func:`joined_time`), each restart line labelled with its
    boot time."""
    t = np.asarray(time_s, dtype=np.float64)
    if len(t) < 2 or np.all(np.diff(t) >= 0):
        return t, "boot time [s] (as in the summary and the CSV)"
    return (t[0] + joined_time(t, restarts),
            "time [s]: sessions joined end to end (boot time went backwards); restarts labelled with boot time")


def plot_stream(path, title, t, x, f, restarts, unit, axes=("x", "y", "z")):
    """PNG of raw and filtered per axis (``t``: the samples' boot times, s),
    restarts as dashed red lines."""
    _draw(path, title, _plot_data(t, x, f, restarts), unit, axes)


def _plot_data(t, x, f, restarts):
    """What the plot needs: per axis the min/max envelopes, the restart times, their
    boot times (labels when the plot's time is not the boot time) and the x label."""
    pt, xlabel = plot_time(t, restarts)
    labels = None if pt is t or np.array_equal(pt, t) else np.asarray(t, dtype=np.float64)[restarts]
    rt = pt[restarts]
    cut = np.flatnonzero(restarts)          # no line drawn across a restart (a gap, a reboot)
    if len(cut):
        pt, x, f = (np.insert(pt, cut, np.nan), np.insert(x, cut, np.nan, axis=0),
                    np.insert(f, cut, np.nan, axis=0))
    lines = [(_envelope(pt, x[:, k]), _envelope(pt, f[:, k])) for k in range(x.shape[1])]
    return lines, rt, labels, xlabel


def _draw(path, title, pdata, unit, axes, spectrum=None):
    if spectrum is not None:                     # (path, title, [(stream, plot data)]) of gyrodenoise.mavlink.spectra
        from gyrodenoise.mavlink.spectra import draw_log_spectrum
        draw_log_spectrum(*spectrum)
    if pdata is None:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(len(axes), 1, figsize=(9, 6.5), sharex=True)
    fig.subplots_adjust(left=0.1, right=0.98, top=0.94, bottom=0.08, hspace=0.12)
    lines, rt, rlabels, xlabel = pdata
    for k, ax in enumerate(np.atleast_1d(axs)):
        ax.plot(*lines[k][0], lw=0.6, color="0.6", label="raw")
        ax.plot(*lines[k][1], lw=0.9, color="C0", label="filtered")
        if len(rt):
            ax.vlines(rt, 0, 1, transform=ax.get_xaxis_transform(), colors="C3", lw=0.8,
                      linestyles="--", label="restart")
        if k == 0 and rlabels is not None and len(rt) <= 20:
            for x0, tb in zip(rt, rlabels):
                ax.text(x0, 0.02, f" t={tb:.1f} s", transform=ax.get_xaxis_transform(), fontsize=7,
                        color="C3", va="bottom")
        ax.set_ylabel(f"{axes[k]} [{unit}]")
        ax.grid(True, lw=0.3)
    axs[0].legend(loc="upper right", fontsize=8, ncol=3)
    axs[0].set_title(title, fontsize=10)
    axs[-1].set_xlabel(xlabel)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=90, pil_kwargs={"compress_level": 1})
    plt.close(fig)


def _plot_loop(conn):
    """Child process: import matplotlib while the parent filters, then plot jobs.
    Ends with its parent (:func:`gyrodenoise.mavlink.stopping.as_child`)."""
    as_child()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401
    while True:
        job = conn.recv()
        if job is None:
            break
        try:
            _draw(*job)
            conn.send(None)
        except Exception as exc:  # noqa: BLE001 - reported by the parent
            conn.send(f"{job[0]}: plot failed: {type(exc).__name__}: {exc}")
    conn.close()


class Plotter:
    """Plots inline, or in a forked helper process that overlaps the parent's work."""

    def __init__(self, background=False, helpers=1):
        self.procs, self.conns, self.threads, self.queues = [], [], [], []
        self.pending = []
        self.next = 0
        if background and sys.platform.startswith("linux"):
            import multiprocessing as mp
            import queue
            import threading
            ctx = mp.get_context("fork")
            for _ in range(max(1, int(helpers))):
                conn, child = ctx.Pipe()
                proc = ctx.Process(target=_plot_loop, args=(child,), daemon=True)
                with signals_blocked():           # until the helper ignores SIGINT itself
                    proc.start()
                child.close()
                # a thread does the sending: a send blocks while the helper is still importing
                q = queue.Queue()
                th = threading.Thread(target=self._sender, args=(conn, q), daemon=True)
                th.start()
                self.procs.append(proc)
                self.conns.append(conn)
                self.queues.append(q)
                self.threads.append(th)
                self.pending.append(0)

    @staticmethod
    def _sender(conn, q):
        while True:
            job = q.get()
            try:
                conn.send(job)
            except (OSError, ValueError):      # the helper was stopped (an interrupt): nothing to send to
                break
            if job is None:
                break

    def plot(self, path, title, t, x, f, restarts, unit, axes):
        self._submit((path, title, _plot_data(t, x, f, restarts), unit, axes))

    def plot_spectrum(self, path, title, items):
        """The spectrum PNG of a log: [(stream name, plot data)] (:mod:`gyrodenoise.mavlink.spectra`)."""
        self._submit((path, None, None, None, None, (path, title, items)))

    def _submit(self, job):
        if not self.procs:
            _draw(*job)
        else:
            i = self.next % len(self.procs)
            self.next += 1
            self.queues[i].put(job)
            self.pending[i] += 1

    def close(self):
        """Wait for the helpers; raise RuntimeError with the first failure. An
        interrupt while waiting stops them at once (:meth:`abort`)."""
        errors = []
        try:
            for proc, conn, q, th, n in zip(self.procs, self.conns, self.queues, self.threads, self.pending):
                try:
                    for _ in range(n):
                        r = conn.recv()
                        if r:
                            errors.append(r)
                except EOFError:
                    errors.append("plot helper process ended unexpectedly")
                q.put(None)
                th.join(timeout=30)
                proc.join(timeout=30)
                if proc.is_alive():
                    proc.terminate()
        except BaseException:
            self.abort()
            raise
        self.procs = []
        if errors:
            raise RuntimeError(errors[0])

    def abort(self):
        """Stop the helpers at once (the run was interrupted or failed): no waiting
        for plots; their partial files are deleted by the caller."""
        stop_processes(self.procs)
        for q in self.queues:
            q.put(None)
        for conn in self.conns:
            conn.close()
        self.procs = []


#: |sample| beyond this in work units (deg/s, or raw counts when the unit is unknown)
#: is a corrupted record, not a reading (int16 counts stay below 32768)
ABSURD_WORK = 1.0e6


def _sub_restarts(restarts, keep):
    """Restart flags of the kept samples: a restart on a dropped sample moves to the next kept one."""
    idx = np.nonzero(keep)[0]
    cr = np.concatenate([[0], np.cumsum(restarts, dtype=np.int64)])
    prev = np.concatenate([[0], idx[:-1] + 1])
    return (cr[idx + 1] - cr[prev]) > 0


def _filter_streams(streams, engine, gap_factor, sample_rate=None):
    """Restarts, then each axis of each stream through its own denoiser. Unusable
    samples -- NaN/inf in float fields, or beyond :data:`ABSURD_WORK` in work
    units (a corrupted record: DataFlash has no checksum, so a damaged record can
    decode to 1e23 rad/s) -- are not fed to the filter (it would never recover):
    they are kept as they are in the output and counted in ``non_finite``.

    Then the safety net (:func:`check_filtered`): a stream whose filtered output
    is not finite, leaves the raw range of a session, or does not fit the log's
    field type is written RAW (``s.left_raw`` says why).

    A stream sampled too slowly to denoise
    (:func:`gyrodenoise.analysis.motion_metrics.too_slow_to_denoise`) is not filtered: it
    goes out raw, bit for bit. A stream the filter never changed gets the reason
    in ``s.not_filtered`` (:func:`not_filtered_reason`)."""
    from gyrodenoise.analysis.motion_metrics import too_slow_to_denoise
    for s in streams:
        detect_restarts(s, gap_factor)
        rate = sample_rate or s.rate_hz or 1.0
        x, back, unit = s.work_units()
        f = x.copy()
        s.non_finite = [0] * x.shape[1]
        s.not_filtered = None
        s.warmup_samples = engine.warmup_samples(rate)
        s.cutoff_hz = engine.cutoff_hz(rate) if hasattr(engine, "cutoff_hz") else None
        s._work = (x, f, unit, rate)
        usable = np.isfinite(x) & (np.abs(x) <= ABSURD_WORK)
        if too_slow_to_denoise(s.rate_hz):
            s.filtered = s.raw.astype(np.float64)          # out raw, bit for bit
            s.left_raw = None
            continue
        try:
            engine.check_rate(rate)
        except ValueError as exc:               # e.g. --cutoff-hz not below this stream's Nyquist
            s.filtered = s.raw.astype(np.float64)
            s.left_raw = None
            s.not_filtered = f"the filter cannot run at {rate:g} Hz: {exc}; written raw"
            s.rate_refused = rate
            continue
        for k in range(x.shape[1]):
            fin = usable[:, k]
            if fin.all():
                f[:, k] = engine.filter(x[:, k], s.restarts, rate)
            elif fin.any():
                s.non_finite[k] = int((~fin).sum())
                f[fin, k] = engine.filter(x[fin, k], _sub_restarts(s.restarts, fin), rate)
            else:
                s.non_finite[k] = len(fin)
        s.filtered = f * back
        s.left_raw = check_filtered(s, x, f, usable, causal=getattr(engine, "causal", True))
        if s.left_raw:
            f = x.copy()
            s.filtered = s.raw.astype(np.float64)          # the raw values, bit for bit
        elif usable.any() and np.array_equal(f[usable], x[usable]):
            s.not_filtered = not_filtered_reason(s, engine.method, s.warmup_samples, rate, sample_rate)
            s.filtered = s.raw.astype(np.float64)
        s._work = (x, f, unit, rate)


def not_filtered_reason(s, method, warmup_samples, rate, sample_rate=None):
    """Why the filter's output of stream ``s`` equals its input on every sample."""
    if method == "none":
        return "--method none: output = input"
    starts = np.flatnonzero(np.r_[True, np.asarray(s.restarts, dtype=bool)[1:]])
    longest = int(np.max(np.diff(np.r_[starts, s.n])))
    if method != "lowpass" and longest <= warmup_samples:
        sessions = "its one session is" if len(starts) == 1 else f"each of its {len(starts)} sessions is at most"
        return (f"{sessions} {longest} samples, not longer than the filter's warm-up of {warmup_samples} samples "
                f"at {rate:.4g} Hz{' (--sample-rate)' if sample_rate else ''}, during which the raw samples "
                f"pass through: the stream is written raw (a shorter --warmup-s, e.g. 0.1, filters it)")
    return "the filter's output equals the raw input on every sample: the stream is written raw"


def check_filtered(s, x, f, usable, causal=True):
    """None, or one line saying why stream ``s`` must not be written filtered:
    an axis whose output (work units ``f``) is not finite or leaves the raw
    envelope of its session (:func:`gyrodenoise.analysis.motion_metrics.envelope_violation`,
    over the samples fed to the filter; the whole session's range for a zero-phase
    filter, ``causal=False``), or a value that does not fit the log's
    field type (:func:`gyrodenoise.mavlink.streams.field_misfit`)."""
    from gyrodenoise.analysis.motion_metrics import envelope_violation
    problems = []
    for k, a in enumerate(s.axes):
        fin = usable[:, k]
        if not fin.any():
            continue
        v = envelope_violation(x[fin, k], f[fin, k], _sub_restarts(s.restarts, fin), causal=causal)
        if v is not None:
            i = int(np.flatnonzero(fin)[v["sample"]])
            problems.append(f"{a}: filtered value {v['value']:.6g} at sample {i} (t={s.time_s[i]:.3f} s) "
                            f"{v['reason']} [{v['low']:.6g}, {v['high']:.6g}]")
    if not problems:
        bad = field_misfit(s, s.filtered) & usable
        for k, a in enumerate(s.axes):
            if bad[:, k].any():
                i = int(np.flatnonzero(bad[:, k])[0])
                problems.append(f"{a}: filtered value {s.filtered[i, k]:.6g} {s.unit} at sample {i} "
                                f"does not fit the field type {np.dtype(s.field_dtype).name}")
    return "; ".join(problems) or None


def stream_report(s, csv_path=None, png_path=None, band_hz=None):
    """The report of one stream: counts, noise figures and, beside them, how much
    of the low-band motion the filter kept and the lag it added
    (:mod:`gyrodenoise.analysis.motion_metrics`); a stream sampled too slowly to denoise
    gets a note instead of an improvement figure."""
    from gyrodenoise.analysis import motion_metrics as mm
    band_hz = mm.LOWBAND_HZ if band_hz is None else band_hz
    x, f, unit, rate = s._work
    if np.any(np.abs(x) > ABSURD_WORK):      # corrupted samples stay out of the figures
        bad = np.abs(x) > ABSURD_WORK
        x, f = np.where(bad, np.nan, x), np.where(bad, np.nan, f)
    dr = noise_per_axis(x, s.restarts)       # first differences: noise + motion + vibration
    df = noise_per_axis(f, s.restarts)
    nr = [mm.white_noise_std(x[:, k], rate, s.restarts) for k in range(x.shape[1])]
    slow = mm.too_slow_to_denoise(s.rate_hz, band_hz)
    unfiltered = getattr(s, "not_filtered", None)
    written_raw = slow or unfiltered or getattr(s, "left_raw", None)
    # an output written raw has the raw figures (no second run of the estimator)
    nf = nr if written_raw else [mm.white_noise_std(f[:, k], rate, s.restarts) for k in range(x.shape[1])]
    noise, motion, warnings = {}, {}, []
    skip = int(getattr(s, "warmup_samples", 0) or 0)
    for k, a in enumerate(s.axes):
        ratio = (nf[k] / nr[k]) if (nr[k] and nf[k] is not None and not slow and not unfiltered) else None
        noise[a] = {"raw": nr[k], "filtered": nf[k], "ratio": ratio,
                    "first_diff_raw": dr[k], "first_diff_filtered": df[k]}
        if slow or unfiltered or getattr(s, "left_raw", None):
            motion[a] = None
            continue
        kept = mm.lowband_kept(x[:, k], f[:, k], s.rate_hz, band_hz, s.restarts, skip)
        kept["lag_s"] = mm.lag_s(x[:, k], f[:, k], s.rate_hz, band_hz, s.restarts, skip)
        kept["motion_above_noise"] = mm.motion_above_noise(kept, nr[k], s.rate_hz, band_hz)
        motion[a] = kept
        why = mm.motion_loss(kept, nr[k], s.rate_hz, band_hz)
        if why:
            warnings.append(f"{s.name}.{a}: the filter removed most of the real motion: {why}")
    dur = float(np.sum(np.diff(joined_time(s.time_s, s.restarts)))) if s.n > 1 else 0.0
    rep = {
        "name": s.name, "message": s.message, "field_unit": s.unit,
        "to_deg_s": s.to_deg_s, "unit_known": s.to_deg_s is not None,
        "samples": int(s.n), "rate_hz": s.rate_hz, "filter_rate_hz": rate,
        "duration_s": dur, "restarts": len(s.restart_events),
        "repeated_timestamps": int(s.repeated_timestamps),
        "non_finite_samples": dict(zip(s.axes, getattr(s, "non_finite", [0] * len(s.axes)))),
        "all_zero": bool(s.n and not np.any(s.raw)),
        "noise_unit": unit, "noise": noise,
        "motion_band_hz": band_hz, "warmup_samples": skip, "motion": motion,
        "too_slow_to_denoise": bool(slow),
        "left_raw": getattr(s, "left_raw", None),
        "not_filtered": unfiltered,
        "cutoff_hz": getattr(s, "cutoff_hz", None),
        "warnings": warnings,
        "saturation": saturation(s, x, unit),
    }
    if slow:
        rep["slow_note"] = (f"sampled at {_hz(s.rate_hz)} Hz, below {mm.MIN_DENOISE_RATE_HZ:g} Hz: too "
                            f"slowly to denoise (what a filter removes is motion as much as noise): "
                            f"written raw (unfiltered), no improvement figure")
    if s.note:
        rep["note"] = s.note
    if csv_path:
        rep["csv"] = str(csv_path)
    if png_path:
        rep["plot"] = str(png_path)
    return rep


#: full scales (deg/s) of the gyros in autopilot logs: ArduPilot and PX4 set their IMUs
#: to +-2000 deg/s (a few newer ones to +-4000); a field in raw int16 counts ends at 32767
SATURATION_FULL_SCALES_DEG_S = (2000.0, 4000.0)
INT16_FULL_SCALE = 32767.0
#: a sample at or beyond this share of a full scale counts as at the full scale (a
#: calibrated reading sits a few % off the ADC's end: log171's IMU peaks at 2022.7)
SATURATION_FRACTION = 0.97
SATURATION_RULE = (f"|rate| >= {100 * SATURATION_FRACTION:g} % of a gyro full scale: "
                   f"{', '.join(f'{v:g}' for v in SATURATION_FULL_SCALES_DEG_S)} deg/s (the ranges "
                   f"ArduPilot and PX4 set), or {INT16_FULL_SCALE:g} in raw int16 counts when the unit "
                   f"is unknown; the largest full scale reached is named")


def saturation(s, x, unit):
    """None, or what says stream ``s`` (work values ``x``, (n, 3) in ``unit``) sits at
    a plausible full scale (:data:`SATURATION_RULE`): there the sensor clipped,
    the true rate may have been larger and no filter can restore it."""
    scales = SATURATION_FULL_SCALES_DEG_S if unit == "deg/s" else (
        (INT16_FULL_SCALE,) if np.dtype(s.field_dtype).kind in "iu" and s.to_deg_s is None else ())
    with np.errstate(invalid="ignore"):
        a = np.where(np.isfinite(x) & (np.abs(x) <= ABSURD_WORK), np.abs(x), 0.0)
    reached = [fs for fs in scales if a.max(initial=0.0) >= SATURATION_FRACTION * fs]
    if not reached:
        return None
    fs = reached[-1]
    hit = a >= SATURATION_FRACTION * fs
    i = int(np.flatnonzero(hit.any(axis=1))[0])
    k, j = np.unravel_index(int(np.argmax(a)), a.shape)[::-1]
    return {"full_scale": fs, "unit": unit, "threshold": SATURATION_FRACTION * fs,
            "samples": {ax: int(hit[:, m].sum()) for m, ax in enumerate(s.axes)},
            "first_time_s": float(s.time_s[i]), "peak": float(x[j, k]), "peak_axis": s.axes[k],
            "peak_time_s": float(s.time_s[j]), "rule": SATURATION_RULE}


def saturation_note(sat):
    """One line of the summary for a :func:`saturation` result."""
    n = ", ".join(f"{a} {v}" for a, v in sat["samples"].items() if v)
    return (f"at the gyro's full scale: {n} sample(s) at or beyond {SATURATION_FRACTION * 100:g} % of "
            f"+-{sat['full_scale']:g} {sat['unit']} (first at t={sat['first_time_s']:.2f} s; peak "
            f"{sat['peak']:.5g} on {sat['peak_axis']} at t={sat['peak_time_s']:.2f} s): likely saturated, the "
            f"true rate may have been larger there and no filter restores it")


def _hz(v):
    return "unknown" if v is None else f"{v:.3g}"


def process_log(path, out_dir, *, engine="native", method=DEFAULT_METHOD, ar_order=3, gap_factor=5.0,
                plots=True, csv=True, raw_imu_unit="auto", raw_imu_scale=None, fmu_path=None,
                sample_rate=None, out_stem=None, log=None, background_plots=False,
                plot_helpers=1, warmup_s=None, filter_kw=None, zero_phase=False, causal=False):
    """Process one log file; return its report (a JSON-able dict).

    The form of the filter (``rep["form"]``): a whole log is filtered offline by
    default where the engine and method have an offline form (the native engine
    with ``method="motion"``: forwards and backwards per session, no lag;
    ``zero_phase`` for the low-pass); ``causal=True`` gives the causal filter
    (``Denoiser``, as a live link, ``Denoiser.step`` and the FMUs run it). The FMU
    engine is always causal.

    Raises InputError (one line naming the file) for a file that cannot be
    used: unknown type, unreadable, or without a gyro stream.
    ``background_plots`` draws the PNGs in a forked helper process (Linux),
    which overlaps matplotlib's import and drawing with the filtering.
    """
    from gyrodenoise.mavlink.engines import make_engine
    t0 = time.perf_counter()
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    kind = log_kind(path)
    rep = {"file": str(path), "format": kind}
    plotter = Plotter(background_plots, helpers=plot_helpers) if plots else None
    done = False
    try:
        ctx = {}
        if kind == "dataflash":
            ctx["data"], ctx["sc"], streams = dataflash.read(path)
            sc = ctx["sc"]
            rep.update(messages=sc.n_messages, unreadable_records=len(sc.bad_regions),
                       unreadable_bytes=sc.bad_bytes, truncated=sc.truncated_bytes > 0,
                       truncated_bytes=sc.truncated_bytes,
                       truncation="message cut by the end of the file" if sc.truncated_bytes else None)
        elif kind == "tlog":
            from gyrodenoise.mavlink import tlog
            ctx["data"], ctx["fr"], streams = tlog.read(path, raw_imu_unit, raw_imu_scale)
            fr = ctx["fr"]
            rep.update(messages=int(fr.ok.sum()), unreadable_records=fr.n_unreadable,
                       unreadable_bytes=int(fr.length[~fr.ok].sum()) + sum(e - s for s, e in fr.bad_regions),
                       truncated=fr.truncated_bytes > 0, truncated_bytes=fr.truncated_bytes,
                       truncation=("zero-filled tail" if fr.zero_tail else
                                   "record cut by the end of the file" if fr.truncated_bytes else None))
        else:
            from gyrodenoise.mavlink import ulog
            ctx["u"], streams, ctx["refs"] = ulog.read(path)
            u = ctx["u"]
            cut = ulog.truncated_bytes(path)
            rep.update(messages=sum(len(d.data["timestamp"]) for d in u.data_list),
                       unreadable_records=None,
                       data_corruption=bool(getattr(u, "file_corruption", False)),
                       truncated=cut > 0, truncated_bytes=max(cut, 0),
                       truncation="message cut by the end of the file" if cut > 0 else None)
        if not streams:
            raise InputError(f"{path}: no gyro stream (looked for {GYRO_LOOKED_FOR[kind]})")
        offline = engine == "native" and method == "motion" and not causal
        eng = make_engine(engine, method, ar_order, fmu_path, warmup_s, filter_kw, zero_phase, offline)
        rep.update(filter_form(eng, engine))
        try:
            _filter_streams(streams, eng, gap_factor, sample_rate)
        finally:
            eng.close()
        _check_some_stream_filterable(path, streams, filter_kw)
        rep.update(_write_outputs(path, kind, out_dir, out_stem, streams, plotter, csv,
                                  engine, method, ar_order, log, filter_kw=filter_kw, form=rep["form"], **ctx))
        done = True
    finally:
        if plotter is not None:
            # an interrupt or a failure: stop the helpers now, without waiting for their plots
            plotter.close() if done else plotter.abort()
    options = dict(filter_kw or {})
    if method == "lowpass":
        options.setdefault("cutoff_hz", None)          # None: the default, min(20 Hz, rate / 4)
        options.setdefault("order", 2)
        options["zero_phase"] = bool(zero_phase)
    rep.update(engine=engine, method=method, ar_order=int(ar_order), gap_factor=gap_factor,
               warmup_s=warmup_s, filter_options=options,
               seconds=round(time.perf_counter() - t0, 3))
    return rep


def _check_some_stream_filterable(path, streams, filter_kw):
    """InputError (one line, nothing written) when a --cutoff-hz was given and every
    stream that would be filtered (not too slow to denoise) refused it: at or above
    its Nyquist frequency. A log where some stream takes it goes on: the others
    are written raw, each with its reason."""
    cutoff = (filter_kw or {}).get("cutoff_hz")
    tried = [s for s in streams if not _too_slow(s.rate_hz)]      # the slow ones never reach the filter
    if cutoff is None or not tried or not all(getattr(s, "rate_refused", None) is not None for s in tried):
        return
    rates = sorted({s.rate_refused for s in tried})
    exc = InputError(f"{path}: --cutoff-hz {cutoff:g} is at or above the Nyquist frequency of every gyro "
                     f"stream (sampled at {', '.join(f'{r:.4g}' for r in rates)} Hz: Nyquist "
                     f"{', '.join(f'{r / 2:.4g}' for r in rates)} Hz); nothing to filter")
    exc.option, exc.rates_hz = "--cutoff-hz", rates
    raise exc


def _too_slow(rate_hz):
    from gyrodenoise.analysis.motion_metrics import too_slow_to_denoise
    return too_slow_to_denoise(rate_hz)


def filter_form(eng, engine):
    """{"form": "offline" | "causal", "form_note": what it means} of an engine."""
    if not eng.causal:
        how = ("forwards then backwards, each session on its own (zero phase)" if getattr(eng, "zero_phase", False)
               else "forward and backward runs blended, each session on its own (no lag)")
        return {"form": "offline", "form_note": f"whole record: {how}"}
    if engine == "fmu":
        return {"form": "causal", "form_note": "the FMU filters one sample per step (causal only)"}
    return {"form": "causal", "form_note": "each output from the samples up to it (as live links, "
                                           "Denoiser.step and the FMUs)"}


def _write_outputs(path, kind, out_dir, out_stem, streams, plotter, csv, engine, method,
                   ar_order, log, data=None, sc=None, fr=None, u=None, refs=None, filter_kw=None, form=None):
    from gyrodenoise.mavlink.spectra import stream_spectrum
    rep = {}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = out_stem or path.stem
    out_log = out_dir / f"{stem}.filtered{path.suffix or '.' + kind}"
    label = f"{method}, AR({ar_order})" if method in ("shakf", "kf", "sh_classic") else method
    if form:                                    # the plots name the form, as the summary does
        label += f", {form}"
    spec_items = []
    spec_png = out_dir / f"{stem}.spectrum.png"
    for s in streams:
        x, f, unit, rate = s._work
        jt = joined_time(s.time_s, s.restarts)
        if plotter is not None:                  # queued first: the helper draws while we go on
            s._png = out_dir / f"{stem}.{safe_name(s.name)}.png"
            plot_label = label
            if getattr(s, "cutoff_hz", None):
                plot_label += f" {s.cutoff_hz:.4g} Hz"
            plotter.plot(s._png, f"{path.name}: {s.name} ({engine} {plot_label}{_plot_note(s)})",
                         s.time_s, x, f, s.restarts, unit, s.axes)
        usable = (np.isfinite(x) & np.isfinite(f) & (np.abs(x) <= ABSURD_WORK)).all(axis=1)
        s._spectrum, spec_plot = stream_spectrum(s, x, f, unit, rate, method, filter_kw,
                                                 getattr(s, "warmup_samples", 0), jt, usable)
        if spec_plot is not None:
            spec_items.append((s.name, spec_plot))
            s._spectrum_png = spec_png if plotter is not None else None
    if plotter is not None and spec_items:
        plotter.plot_spectrum(spec_png, f"{path.name}: spectrum ({engine} {label})", spec_items)
    with atomic_path(out_log) as tmp:
        if kind == "dataflash":
            tmp.write_bytes(dataflash.patch(data, sc, streams))
        elif kind == "tlog":
            from gyrodenoise.mavlink import tlog
            rep["signatures_dropped"] = tlog.write_filtered(data, fr, streams, tmp)
        else:
            from gyrodenoise.mavlink import ulog
            ulog.write_filtered(u, streams, refs, tmp)
    rep["output_log"] = str(out_log)

    srep = []
    restarts = []
    for s in streams:
        x, f, unit, _ = s._work
        csv_path = png_path = None
        if csv:
            csv_path = out_dir / f"{stem}.{safe_name(s.name)}.csv"
            write_csv(csv_path, s, x, f, unit)
        if plotter is not None:
            png_path = s._png
        srep.append(stream_report(s, csv_path, png_path))
        srep[-1]["spectrum"] = s._spectrum
        if getattr(s, "_spectrum_png", None) is not None:
            srep[-1]["spectrum_plot"] = str(s._spectrum_png)
        restarts += s.restart_events
        if s.to_deg_s is None and log:
            log(f"{path}: {s.name}: unit unknown, filtered in {s.unit} ({s.note})")
    rep.update(streams=srep, restarts=restarts)
    if log:
        log_problems(dict(rep, file=str(path)), log)
    return rep


def _plot_note(s):
    """What a plot's title says of a stream written unfiltered."""
    from gyrodenoise.analysis.motion_metrics import too_slow_to_denoise
    if too_slow_to_denoise(s.rate_hz):
        return "; too slow to denoise: written raw"
    if getattr(s, "not_filtered", None) or getattr(s, "left_raw", None):
        return "; NOT FILTERED: written raw"
    return ""


def log_problems(rep, log):
    """One stderr line per stream left raw, and per motion-loss warning."""
    for s in rep["streams"]:
        if s.get("left_raw"):
            log(f"{rep['file']}: {s['name']}: NOT FILTERED: {s['left_raw']}; the stream's samples "
                f"are written RAW (unfiltered) into {rep.get('output_log')}")
        for w in s.get("warnings", []):
            log(f"{rep['file']}: warning: {w}")


# ------------------------------------------------------------------ many logs
def expand_inputs(items):
    """Files and folders -> (list of log files, list of ignored files)."""
    files, ignored = [], []
    for it in items:
        p = Path(it)
        if p.is_dir():
            for q in sorted(p.rglob("*")):
                if q.is_file():
                    (files if q.suffix.lower() in LOG_SUFFIXES else ignored).append(q)
        else:
            files.append(p)
    return files, ignored


def _unique_stems(files):
    seen = {}
    stems = []
    for f in files:
        st = Path(str(f).split("://", 1)[-1]).stem
        k = seen.get(st, 0)
        seen[st] = k + 1
        stems.append(st if k == 0 else f"{st}-{k + 1}")
    return stems


def _worker(args):
    path, out_dir, kw = args
    try:
        return {"ok": True, "report": process_log(path, out_dir, **kw)}
    except InputError as exc:
        res = {"ok": False, "file": str(path), "error": str(exc)}
        if getattr(exc, "option", None):            # the option the log refused (e.g. --cutoff-hz)
            res["option"] = exc.option
            res["rates_hz"] = list(getattr(exc, "rates_hz", []))
        return res
    except Exception as exc:  # noqa: BLE001 - one bad log must not stop the others
        return {"ok": False, "file": str(path), "error": f"{path}: {type(exc).__name__}: {exc}"}


def process_many(items, out_dir, jobs=1, log=None, scheduler=None, progress=False, on_interrupt=None, **kw):
    """Process files and folders; one summary dict. A failing log is listed
    under ``failed`` and does not stop the others (nor does a crashed worker).

    ``jobs`` > 1 runs a local process pool; ``scheduler`` (``tcp://HOST:PORT``
    or a ``distributed.Client``) runs each log as one task on a Dask cluster
    (:mod:`gyrodenoise.mavlink.cluster`). Items and ``out_dir`` may be fsspec URLs.
    ``progress`` shows logs done / failed / remaining and samples per second
    on stderr. Outputs are byte-identical whichever way the logs are run.

    Interrupted (KeyboardInterrupt, :class:`gyrodenoise.errors.Terminated`): the
    workers are stopped, then ``on_interrupt(summary)`` is called with the
    summary of the logs that completed (:func:`interrupted_summary`: which logs
    completed, which did not) before the interrupt goes on up; a text it
    returns is set as the exception's ``stop_note`` (the CLI's stop line).
    """
    from gyrodenoise.mavlink.cluster import Progress, expand_url_inputs, is_url, largest_first, run_on_cluster, run_task
    local = [it for it in items if not is_url(it)]
    files, ignored = expand_inputs(local)
    urls = [it for it in items if is_url(it)]
    if urls:
        found, missing = expand_url_inputs(urls)
        files += found
        ignored += missing
    stems = _unique_stems(files)
    tasks = [(f, out_dir, dict(kw, out_stem=st, log=None)) for f, st in zip(files, stems)]
    t0 = time.perf_counter()
    where = "Dask cluster" if scheduler is not None else f"{jobs} processes" if jobs > 1 else "local"
    bar = Progress(len(tasks), where) if progress and tasks else None
    results = [None] * len(tasks)           # filled as the logs end (read by an interrupt)
    try:
        if scheduler is not None:
            run_on_cluster(tasks, scheduler, bar, into=results)
        elif jobs > 1 and len(tasks) > 1:
            import concurrent.futures as cf
            import multiprocessing as mp
            ctx = mp.get_context("fork") if sys.platform.startswith("linux") else None
            # the workers end with this process, and on an interrupt they are stopped
            # at once (the pool's own shutdown would wait for the logs under way)
            ex = cf.ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), mp_context=ctx, initializer=as_child)
            try:
                with signals_blocked():           # the workers are forked by the first submit
                    futures = {ex.submit(run_task, tasks[i]): i for i in largest_first(tasks)}
                for fut in cf.as_completed(futures):
                    t = tasks[futures[fut]]
                    try:
                        res = fut.result()
                    except Exception as exc:  # noqa: BLE001 - e.g. a worker killed by a crash
                        res = {"ok": False, "file": str(t[0]),
                               "error": f"{t[0]}: worker failed: {type(exc).__name__}: {exc}"}
                    results[futures[fut]] = res
                    if bar:
                        bar(res)
            except BaseException:
                stop_processes(list((getattr(ex, "_processes", None) or {}).values()))
                ex.shutdown(wait=False, cancel_futures=True)
                raise
            ex.shutdown(wait=True)
        else:
            for i, t in enumerate(tasks):
                results[i] = run_task(t)
                if bar:
                    bar(results[i])
    except (KeyboardInterrupt, Terminated) as exc:
        if on_interrupt is not None:
            note = on_interrupt(interrupted_summary(files, stems, results, ignored, exc,
                                                    time.perf_counter() - t0, jobs, scheduler))
            if note:
                exc.stop_note = note            # the CLI's one line says it
        raise
    finally:
        if bar:
            bar.close()
    logs = [r["report"] for r in results if r["ok"]]
    failed = _failed_entries(results)
    if log:
        for r in logs:
            for s in r["streams"]:
                if not s["unit_known"]:
                    log(f"{r['file']}: {s['name']}: unit unknown, filtered in {s['field_unit']}")
            log_problems(r, log)
    return {
        "logs": logs, "failed": failed, "ignored_files": [str(p) for p in ignored],
        "n_logs": len(files), "n_ok": len(logs), "n_failed": len(failed),
        "jobs": None if scheduler is not None else int(jobs),     # the cluster decides its parallelism
        "scheduler": None if scheduler is None else str(scheduler),
        "seconds": round(time.perf_counter() - t0, 3),
        "noise_metric": NOISE_METRIC, "motion_metric": MOTION_METRIC, "spectrum_metric": SPECTRUM_METRIC,
        "streams_left_raw": streams_left_raw(logs),
    }


def _failed_entries(results):
    """The ``failed`` list of a summary: file, error and, when a log refused an option, which."""
    return [{k: r[k] for k in ("file", "error", "option", "rates_hz") if k in r} for r in results if not r["ok"]]


def interrupted_summary(files, stems, results, ignored, exc, seconds, jobs=1, scheduler=None):
    """The summary of an interrupted run: the completed logs' reports (``logs``,
    ``failed``) as in a full summary, ``"interrupted": true``, the signal, and
    ``completed`` / ``unfinished`` (file and output stem): an unfinished log's
    outputs (``STEM.*``) may be absent or only some of them present, each file
    whole (written under a partial name, renamed when complete)."""
    done = [r for r in results if r is not None]
    logs = [r["report"] for r in done if r["ok"]]
    failed = _failed_entries(done)
    sig = "SIGINT" if isinstance(exc, KeyboardInterrupt) else "SIGTERM"
    return {
        "interrupted": True, "signal": sig, "exit_status": 130 if sig == "SIGINT" else 143,
        "completed": [str(f) for f, r in zip(files, results) if r is not None],
        "unfinished": [{"file": str(f), "out_stem": st,
                        "note": f"not completed: its outputs {st}.* in this folder, if any, are not all there"}
                       for f, st, r in zip(files, stems, results) if r is None],
        "logs": logs, "failed": failed, "ignored_files": [str(p) for p in ignored],
        "n_logs": len(files), "n_ok": len(logs), "n_failed": len(failed),
        "n_unfinished": sum(r is None for r in results),
        "jobs": None if scheduler is not None else int(jobs),
        "scheduler": None if scheduler is None else str(scheduler),
        "seconds": round(seconds, 3),
        "noise_metric": NOISE_METRIC, "motion_metric": MOTION_METRIC, "spectrum_metric": SPECTRUM_METRIC,
        "streams_left_raw": streams_left_raw(logs),
    }


def streams_left_raw(logs):
    """[{"file", "stream", "reason"}] of the streams written raw by the safety net."""
    return [{"file": r["file"], "stream": s["name"], "reason": s["left_raw"]}
            for r in logs for s in r["streams"] if s.get("left_raw")]
