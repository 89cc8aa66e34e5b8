"""The step response of the rate loop, per axis, from the rate setpoint and the measured
rate the vehicle logged (what PID tuning tools show: PX4 Flight Review, ArduPilot's PID
Review, PID-Analyzer).

The method (:func:`step_response`): the flight's setpoint and rate on a uniform time grid
(at least :data:`MIN_GRID_HZ`) are cut into windows of :data:`WINDOWS_S` (the longest
that gives :data:`MIN_WINDOWS`; half overlapping, Hann-tapered); in each window
with enough setpoint excitation (its standard deviation at least
:data:`MIN_EXCITATION_DPS`), the loop's transfer function from setpoint to rate is
estimated by Wiener deconvolution, ``H = Y X* / (|X|^2 + lambda)`` with ``lambda``
:data:`WIENER_REGULARISATION` times the mean of ``|X|^2`` (where the setpoint holds
little power the estimate is pulled to 0 instead of dividing noise by almost nothing);
the impulse response is ``H``'s inverse FFT and the step response its running sum over
the first :data:`RESPONSE_S`. The windows' step responses are averaged. From the
average: ``final`` (the mean over its last 40 %), the rise time (10 % to 90 % of
``final``), the delay (to 50 %), the overshoot (the peak above ``final``, in % of it; ``peak``
itself is the response's maximum to a unit step, as PID tools plot it);
given only where ``final`` lies within :data:`FINAL_RANGE` (else the setpoint did not
explain the rate: a note says so).

The setpoint and the rate come from the log's adapter (:meth:`LogFormat.rate_setpoint`):
ArduPilot ``RATE`` (``RDes``/``R``, ``PDes``/``P``, ``YDes``/``Y``), PX4
``vehicle_rates_setpoint`` held over ``vehicle_angular_velocity``, Betaflight
``setpoint[0..2]`` against ``gyroADC[0..2]``; over the ``flying`` segments (never after
an impact).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the deconvolution windows (s), half overlapping: the longest of these that gives
#: :data:`MIN_WINDOWS` (a long window biases the response least: the taper cuts less of it)
WINDOWS_S = (4.0, 2.0, 1.0)
WINDOW_S = WINDOWS_S[0]
#: below this grid rate (Hz) a rate loop's rise (20-100 ms) spans under 2 samples: not estimated
MIN_GRID_HZ = 40.0
#: an axis' figures are given only when its response settles within this range of 1
#: (outside, setpoint and rate do not explain each other: too little excitation)
FINAL_RANGE = (0.5, 1.5)
#: the step response's length (s)
RESPONSE_S = 0.5
#: a window counts when its setpoint's standard deviation reaches this (deg/s)
MIN_EXCITATION_DPS = 5.0
#: the Wiener regularisation, a share of the mean setpoint power per window
WIENER_REGULARISATION = 1e-3
#: fewest windows for a step response
MIN_WINDOWS = 3
#: the uniform grid runs at the rate stream's median rate, at most this (Hz)
MAX_GRID_HZ = 1000.0
AXES = ("roll", "pitch", "yaw")
#: the report keeps the averaged step response at most this many points (for its plot)
CURVE_POINTS = 250


@dataclass
class StepResponse:
    """One axis' averaged step response: ``time_s`` and ``response`` (to a unit step of
    the setpoint), the ``windows`` averaged, and its figures (None where the response
    never reaches them)."""
    time_s: np.ndarray
    response: np.ndarray
    windows: int
    sample_rate_hz: float
    final: float
    rise_time_s: float | None
    delay_s: float | None
    overshoot_pct: float | None
    window_s: float = WINDOW_S

    @property
    def settles(self):
        """The response settles near 1 (:data:`FINAL_RANGE`): its figures mean something."""
        return FINAL_RANGE[0] <= self.final <= FINAL_RANGE[1]

    def to_fields(self):
        def r(x, nd=4):
            return None if x is None or not self.settles else round(float(x), nd)
        out = {"windows": self.windows, "window_s": self.window_s, "sample_rate_hz": round(self.sample_rate_hz, 2),
               "final": round(float(self.final), 4), "rise_time_s": r(self.rise_time_s), "delay_s": r(self.delay_s),
               "overshoot_pct": r(self.overshoot_pct, 2), "peak": r(float(self.response.max()), 3)}
        k = max(1, int(np.ceil(len(self.time_s) / CURVE_POINTS)))
        out["curve"] = {"time_s": [round(float(x), 5) for x in self.time_s[::k]],
                        "response": [round(float(x), 4) for x in self.response[::k]]}
        if not self.settles:
            out["note"] = (f"the averaged response settles at {self.final:.2f}, not within {FINAL_RANGE[0]:g}-"
                           f"{FINAL_RANGE[1]:g} of the setpoint: setpoint and rate do not explain each other "
                           f"(too little excitation); no figures")
        return out


def step_response(setpoint, rate, fs, valid=None, window_s=None) -> StepResponse | None:
    """The :class:`StepResponse` of ``rate`` to ``setpoint`` (1-D, on one uniform grid of
    ``fs`` Hz; ``valid``: bool per sample, a window must be valid throughout) over
    windows of ``window_s`` (default :data:`WINDOW_S`), or None with fewer than
    :data:`MIN_WINDOWS` excited windows (the module doc)."""
    sp = np.asarray(setpoint, np.float64)
    gy = np.asarray(rate, np.float64)
    window_s = WINDOW_S if window_s is None else window_s
    n = int(round(window_s * fs))
    m = int(round(RESPONSE_S * fs))
    if n < 8 or len(sp) < n:
        return None
    ok = np.isfinite(sp) & np.isfinite(gy) if valid is None else np.asarray(valid) & np.isfinite(sp) & np.isfinite(gy)
    bad = np.concatenate([[0], np.cumsum(~ok)])
    win = np.hanning(n)
    steps = []
    for a in range(0, len(sp) - n + 1, n // 2):
        if bad[a + n] != bad[a]:
            continue
        s, g = sp[a:a + n], gy[a:a + n]
        if np.std(s) < MIN_EXCITATION_DPS:
            continue
        x = np.fft.rfft(s * win)
        y = np.fft.rfft(g * win)
        px = np.abs(x) ** 2
        h = y * np.conj(x) / (px + WIENER_REGULARISATION * px.mean())
        steps.append(np.cumsum(np.fft.irfft(h, n)[:m]))
    if len(steps) < MIN_WINDOWS:
        return None
    resp = np.mean(steps, axis=0)
    t = np.arange(m) / fs
    final = float(resp[int(0.6 * m):].mean())
    return StepResponse(t, resp, len(steps), float(fs), final, *_figures(t, resp, final), window_s=window_s)


def _crossing(t, y, level):
    """The first time ``y`` reaches ``level`` (linearly interpolated), or None."""
    above = np.flatnonzero(y >= level)
    if not len(above):
        return None
    i = above[0]
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - y[i - 1]) / (y[i] - y[i - 1]) * (t[i] - t[i - 1]))


def _figures(t, y, final):
    """(rise time 10-90 %, delay to 50 %, overshoot %) of a step response settling at ``final``."""
    if not final > 0:
        return None, None, None
    t10, t50, t90 = (_crossing(t, y, k * final) for k in (0.1, 0.5, 0.9))
    rise = t90 - t10 if t10 is not None and t90 is not None else None
    return rise, t50, max(0.0, float(y.max() / final - 1.0) * 100.0)


def uniform(time_s, setpoint, rate, spans):
    """(grid, setpoint, rate, valid, fs): the (n, 3) ``setpoint`` and ``rate`` on
    ``time_s`` interpolated onto a uniform grid at their median rate (at most
    :data:`MAX_GRID_HZ`) over each of ``spans`` [(start, end)], the spans' grids joined
    with invalid samples between them; a grid sample is invalid where no logged sample
    lies within 2 grid steps (a gap). None when too few samples."""
    t = np.asarray(time_s, np.float64)
    ok = np.isfinite(t) & np.isfinite(setpoint).all(axis=1) & np.isfinite(rate).all(axis=1)
    t, sp, gy = t[ok], np.asarray(setpoint, np.float64)[ok], np.asarray(rate, np.float64)[ok]
    order = np.argsort(t, kind="stable")
    t, sp, gy = t[order], sp[order], gy[order]
    if len(t) < 16:
        return None
    dt = np.diff(t)
    dt = np.median(dt[dt > 0]) if (dt > 0).any() else 0.0
    if not dt > 0:
        return None
    fs = min(1.0 / dt, MAX_GRID_HZ)
    parts = []
    for a, b in spans:
        g = np.arange(a, b, 1.0 / fs)
        if len(g) < 2:
            continue
        k = np.clip(np.searchsorted(t, g), 1, len(t) - 1)
        near = np.minimum(np.abs(t[k] - g), np.abs(t[k - 1] - g)) <= 2.0 / fs
        valid = near & (g >= t[0]) & (g <= t[-1])
        valid[-1] = False                         # windows never straddle two spans
        parts.append((g, np.column_stack([np.interp(g, t, sp[:, j]) for j in range(3)]),
                      np.column_stack([np.interp(g, t, gy[:, j]) for j in range(3)]), valid))
    if not parts:
        return None
    return (np.concatenate([p[0] for p in parts]), np.vstack([p[1] for p in parts]),
            np.vstack([p[2] for p in parts]), np.concatenate([p[3] for p in parts]), fs)


def step_response_review(log, segments):
    """(result, note, curves): the step response per axis from the log's setpoint sources
    (:meth:`LogFormat.rate_setpoint`) over the ``flying`` segments of ``segments``;
    ``result``: ``{"source", "boot", "over", "method", "axes": {axis: fields or None}}``
    of the first source (boot) that gives one, or None with a note saying why;
    ``curves``: ``{axis: StepResponse}`` for the plot."""
    sources = log.format.rate_setpoint(log)
    if not sources:
        return None, f"no rate setpoint in the log (looked for {log.format.setpoint_looked_for or 'nothing'})", {}
    notes = []
    for src in sources:
        boot = src.get("boot", 0)
        spans = [(s.start_s, s.end_s) for s in segments if s.kind == "flying" and (s.session or 0) == boot]
        if not spans:
            notes.append(f"{src['source']}: no flying segment")
            continue
        grid = uniform(src["time_s"], src["setpoint"], src["rate"], spans)
        if grid is None:
            notes.append(f"{src['source']}: too few samples in flight")
            continue
        _, sp, gy, valid, fs = grid
        if fs < MIN_GRID_HZ:
            notes.append(f"{src['source']} logged at {fs:.0f} Hz: under {MIN_GRID_HZ:g} Hz a rate loop's rise "
                         f"(20-100 ms) spans under 2 samples, not estimated")
            continue
        axes, curves = {}, {}
        for j, axis in enumerate(AXES):
            got = None
            for w in WINDOWS_S:
                got = step_response(sp[:, j], gy[:, j], fs, valid, window_s=w)
                if got is not None:
                    break
            axes[axis] = got.to_fields() if got is not None else None
            if got is not None:
                curves[axis] = got
        if not curves:
            notes.append(f"{src['source']}: fewer than {MIN_WINDOWS} windows of {WINDOWS_S[-1]:g} s with the "
                         f"setpoint moving (std >= {MIN_EXCITATION_DPS:g} deg/s) in flight")
            continue
        result = {"source": src["source"], "boot": boot, "over": "flying", "axes": axes,
                  "method": (f"Wiener deconvolution of rate by setpoint over Hann windows of "
                             f"{'/'.join(f'{w:g}' for w in WINDOWS_S)} s (the longest giving {MIN_WINDOWS}; "
                             f"half overlapping, setpoint std >= {MIN_EXCITATION_DPS:g} deg/s), step responses "
                             f"of {RESPONSE_S:g} s averaged; rise time 10-90 % of the final value")}
        return result, "; ".join(notes + [f"{src['source']} at {fs:.0f} Hz over the flying segments"]), curves
    return None, "; ".join(notes), {}


# ------------------------------------------------------------------ setpoints, per format
def dataflash_rate_setpoint(log, streams):
    """ArduPilot ``RATE``: ``RDes``/``PDes``/``YDes`` against ``R``/``P``/``Y`` (deg/s;
    centidegrees/s in ArduCopter 3.x, told by
    :func:`gyrodenoise.flightlog.vehicle_rate.rate_scale`), one entry per boot."""
    from gyrodenoise.flightlog.vehicle_rate import rate_scale
    out = []
    for boot in range(max(1, len(log.boots))):
        m = log.boot_messages("RATE", boot)
        cols = ("RDes", "PDes", "YDes", "R", "P", "Y")
        if m is None or not all(c in m for c in cols) or len(m["time_s"]) < 16:
            continue
        t = np.asarray(m["time_s"], np.float64)
        sp = np.column_stack([np.asarray(m[c], np.float64) for c in cols[:3]])
        gy = np.column_stack([np.asarray(m[c], np.float64) for c in cols[3:]])
        scale = rate_scale(t, gy, streams)
        out.append({"boot": boot, "source": "RATE (RDes/R, PDes/P, YDes/Y)" + (" in cdeg/s" if scale != 1 else ""),
                    "time_s": t, "setpoint": sp * scale, "rate": gy * scale})
    return out


def ulog_rate_setpoint(log):
    """PX4 ``vehicle_rates_setpoint`` (roll/pitch/yaw, rad/s), held over the times of
    ``vehicle_angular_velocity.xyz[0..2]``."""
    sp = log.messages("vehicle_rates_setpoint")
    av = log.messages("vehicle_angular_velocity")
    scols, acols = ("roll", "pitch", "yaw"), ("xyz[0]", "xyz[1]", "xyz[2]")
    if sp is None or av is None or not all(c in sp for c in scols) or not all(c in av for c in acols):
        return []
    ts, ta = np.asarray(sp["time_s"], np.float64), np.asarray(av["time_s"], np.float64)
    if len(ts) < 2 or len(ta) < 16:
        return []
    o = np.argsort(ts, kind="stable")
    k = np.clip(np.searchsorted(ts[o], ta, side="right") - 1, 0, len(ts) - 1)   # the setpoint held
    held = np.column_stack([np.asarray(sp[c], np.float64)[o][k] for c in scols])
    held[ta < ts[o][0]] = np.nan
    rate = np.column_stack([np.asarray(av[c], np.float64) for c in acols])
    return [{"boot": 0, "source": "vehicle_rates_setpoint / vehicle_angular_velocity", "time_s": ta,
             "setpoint": np.degrees(held), "rate": np.degrees(rate)}]


def blackbox_rate_setpoint(log):
    """Betaflight ``setpoint[0..2]`` against ``gyroADC[0..2]`` (deg/s), one entry per log
    in the file."""
    out = []
    for k, b in enumerate(log.payload):
        sp = b.setpoint
        if not len(b.main) or sp is None or sp.shape[1] < 3:
            continue
        try:
            gy = b.gyro_dps
        except Exception:  # noqa: BLE001 - a log without gyroADC: no step response for it
            continue
        out.append({"boot": k, "source": "setpoint[0..2] / gyroADC[0..2]", "time_s": b.time_s,
                    "setpoint": sp[:, :3].astype(np.float64), "rate": np.asarray(gy, np.float64)})
    return out
