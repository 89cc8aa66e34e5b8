"""The vehicle's own gyro filters replayed sample by sample along the flight, and the
replay compared with the post-filter gyro the vehicle logged.

What no other tool publishes: how close a filter model comes to the vehicle. Where a
log holds the gyro both before and after the vehicle's filters (ArduPilot's batch
sampler with ``INS_LOG_BAT_OPT`` pre+post, PX4 ``sensor_combined`` and
``vehicle_angular_velocity``, Betaflight's debug ``GYRO_SCALED`` and ``gyroADC``), the
pre-filter gyro is run through the autopilot's chain (:mod:`vehicle_filters`,
:mod:`betaflight_filters`) with every tracking notch's centre moved along the flight
as the autopilot moves it:

* ArduPilot harmonic notch ``MODE`` 1 (throttle): ``FREQ x max(FM_RAT, sqrt(ThO / REF))``
  from ``CTUN.ThO``; ``MODE`` 3 (ESC telemetry): ``max(FREQ x FM_RAT, REF x rpm / 60)``
  from ``ESC.RPM`` (the mean over the motors, or a notch set per motor with
  ``OPTS`` bit 1); ``MODE`` 4 (FFT): ``FTN.NF1``. The centre is updated once per
  main loop (``SCHED_LOOP_RATE``, 400 Hz when not logged) and slewed by at most 5 %
  per update (``NotchFilter.cpp``: ``NOTCH_MAX_SLEW`` 0.05, the centre kept within
  [previous x 0.95, previous / 0.95]);
* PX4 ``IMU_GYRO_DNF_EN`` bit 0: a notch per ESC and harmonic at ``h x rpm / 60``
  (``esc_status``), none below ``IMU_GYRO_DNF_MIN``;
* Betaflight: the dynamic gyro low-pass follows the throttle (``setpoint[3]``), the
  RPM notches the motors' eRPM where the log holds it.

The driving value between two logged samples is interpolated linearly (the log holds
it at 10-50 Hz; the autopilot reads it every loop). The biquads run in Direct Form I,
the autopilots' form (``y = b0 x + b1 x1 + b2 x2 - a1 y1 - a2 y2``), their state
(the last two inputs and outputs) kept across a change of coefficients, as the
firmware keeps it.

The agreement: the Welch PSDs of the replayed and of the logged post-filter gyro over
the same (flying) time, compared bin by bin over :data:`BAND_LO_HZ` (30 Hz) to the
slower stream's Nyquist frequency: ``sqrt(mean((10 log10(P_replay / P_logged))**2))``
dB per axis, and over the axes the root mean square of the three. A log whose slower
stream stops below 30 Hz has no band: no figure, a note saying so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrodenoise.analysis import spectrum

#: the agreement band starts here (Hz): the band the filters are there for
BAND_LO_HZ = 30.0
#: PSD segments of about this length (s): ~4 Hz bins
SEGMENT_S = 0.25
#: fewer bins than this in the band: no figure
MIN_BAND_BINS = 4
#: ArduPilot's main loop rate when SCHED_LOOP_RATE is not logged (Copter)
AP_DEFAULT_LOOP_HZ = 400.0
AXES = ("x", "y", "z")


@dataclass(frozen=True)
class GyroSeries:
    """A gyro series in deg/s: ``xyz`` (n, 3) at ``time_s``; ``rate_hz`` its rate."""
    name: str
    time_s: np.ndarray
    xyz: np.ndarray
    rate_hz: float

    @classmethod
    def of_stream(cls, stream):
        """The series of a :class:`~gyrodenoise.flightlog.streams.GyroStream` (None when its unit is not known)."""
        if stream is None or not stream.to_deg_s:
            return None
        t = np.asarray(stream.time_s, dtype=np.float64)
        return cls(stream.name, t, np.asarray(stream.raw, dtype=np.float64) * stream.to_deg_s, series_rate(t))


def series_rate(time_s):
    """1 / the median positive time step (Hz), or 0.0."""
    dt = np.diff(np.asarray(time_s, dtype=np.float64))
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if len(dt) else 0.0


@dataclass(frozen=True)
class Track:
    """What moves a filter: ``value`` (m,) or (m, k) -- k motors -- at ``time_s``;
    ``source`` names the log's field."""
    time_s: np.ndarray
    value: np.ndarray
    source: str

    def at(self, t):
        """The value at each of ``t``, linearly interpolated (held beyond the ends): (n,) or (n, k)."""
        v = np.asarray(self.value, dtype=np.float64)
        ts = np.asarray(self.time_s, dtype=np.float64)
        if v.ndim == 1:
            return np.interp(t, ts, v)
        return np.stack([np.interp(t, ts, v[:, j]) for j in range(v.shape[1])], axis=1)


@dataclass(frozen=True)
class Production:
    """How the logged pre-filter stream was made from the gyro the vehicle's filters
    run on: that gyro at ``filter_rate_hz``, averaged over ``averaged`` consecutive
    samples (a box-car: PX4's ``sensor_combined`` is the integrated delta angle over
    its interval, ``gyro_integral_dt``, divided by that interval) and logged once per
    average. ``source`` names the log's fields that say so."""
    filter_rate_hz: float
    averaged: int
    source: str


def boxcar_gain(f_hz, rate_hz, n):
    """|A(f)| of the mean of ``n`` consecutive samples at ``rate_hz``:
    ``|sin(pi n f / fs) / (n sin(pi f / fs))|`` (1 at 0 Hz)."""
    f = np.asarray(f_hz, dtype=np.float64)
    x = np.pi * f / float(rate_hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.abs(np.sin(n * x) / (n * np.sin(x)))
    return np.where(np.abs(np.sin(x)) < 1e-12, 1.0, g)


def _finite_runs(ok):
    """[(start, stop)] of the runs of True in ``ok``."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], ok.astype(np.int8), [0]))))
    return list(zip(edges[::2], edges[1::2]))


def at_filter_rate(series, production):
    """``series`` (the logged pre-filter gyro) brought to the rate the filters run at:
    each finite run upsampled by ``round(filter_rate / rate)`` (scipy's polyphase
    resampler: band-limited to the logged Nyquist frequency) and, where the stream is
    an average of ``averaged`` samples, that box-car undone up to the logged Nyquist
    frequency (the spectrum divided by :func:`boxcar_gain`, which stays above 2 / pi
    there). What the averaging folded down from above the logged Nyquist frequency
    cannot be undone. Returns a :class:`GyroSeries`, or ``series`` itself when the
    rates already match."""
    from scipy import signal

    up = int(round(production.filter_rate_hz / series.rate_hz))
    if up < 2 and production.averaged < 2:
        return series
    up = max(up, 1)
    rate = series.rate_hz * up
    ok = np.isfinite(series.xyz).all(axis=1)
    t_out, x_out = [], []
    for a, b in _finite_runs(ok):
        if b - a < 8:
            continue
        x = signal.resample_poly(series.xyz[a:b], up, 1, axis=0) if up > 1 else series.xyz[a:b].copy()
        if production.averaged > 1:
            spec = np.fft.rfft(x, axis=0)
            f = np.fft.rfftfreq(len(x), 1.0 / rate)
            g = np.maximum(boxcar_gain(f, production.filter_rate_hz, production.averaged), 2.0 / np.pi)
            x = np.fft.irfft(spec / g[:, None], len(x), axis=0)
        t_out.append(series.time_s[a] + np.arange(len(x)) / rate)
        t_out.append(np.array([np.nan]))
        x_out.append(x)
        x_out.append(np.full((1, 3), np.nan))
    if not t_out:
        return series
    t = np.concatenate(t_out)[:-1]
    xyz = np.concatenate(x_out)[:-1]
    t = np.where(np.isfinite(t), t, np.concatenate(([t[0]], t[:-1])))   # the separators: the run's end time
    return GyroSeries(series.name, t, xyz, rate)


def sampled_at(series, time_s, max_gap_steps=1.5):
    """``series`` read at ``time_s`` (linear interpolation between its two neighbouring
    samples; NaN where those are further apart than ``max_gap_steps`` of its step, or
    either is not finite, or ``time_s`` is outside it): the replay taken where the
    vehicle logged its post-filter gyro, so that both go through the same logging."""
    t = np.asarray(time_s, dtype=np.float64)
    ts = series.time_s
    i = np.clip(np.searchsorted(ts, t), 1, len(ts) - 1)
    t0, t1 = ts[i - 1], ts[i]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(t1 > t0, (t - t0) / (t1 - t0), 0.0)
    x0, x1 = series.xyz[i - 1], series.xyz[i]
    y = x0 + (x1 - x0) * w[:, None]
    bad = (t < ts[0]) | (t > ts[-1]) | (t1 - t0 > max_gap_steps / series.rate_hz)
    y[bad] = np.nan
    return y


def lattice(time_s, tolerance=0.25, share=0.95):
    """(step s, index of each sample on the lattice ``t0 + k step``) of a stream logged
    at a fixed rate with samples dropped (PX4's logger drops topics it cannot keep up
    with: ``vehicle_angular_velocity`` at 409 Hz with every third sample missing, or at
    250 Hz with most steps 8 and 12 ms), or None when the times are not on one lattice.

    The sorted steps split into clusters where one is more than ``1 + tolerance`` times
    the one before; shortest first, each cluster holding 3 steps and 0.5 % of them is
    tried as the base step (the shortest step is not always the commonest: when most
    samples are dropped the base step may be 2 % of the steps): each sample's index the
    previous one's plus its step in base steps, rounded; the step then the least-squares
    slope of the times over the indices; the first whose lattice holds ``share`` of the
    times within ``tolerance`` of a step wins."""
    t = np.asarray(time_s, dtype=np.float64)
    steps = np.diff(t)
    if len(steps) < 8 or np.any(steps <= 0):
        return None
    srt = np.sort(steps)
    cuts = np.flatnonzero(srt[1:] > srt[:-1] * (1.0 + tolerance)) + 1
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(srt)]):
        if b - a < max(3, 0.005 * len(srt)):
            continue
        base = float(np.median(srt[a:b]))
        k = np.r_[0, np.cumsum(np.maximum(np.round(steps / base), 1))].astype(np.int64)
        base, t0 = np.polyfit(k, t, 1)
        if np.mean(np.abs(t - t0 - k * base) > tolerance * base) <= 1.0 - share:
            return float(base), k
    return None


def _fill(idx, k, v):
    """``v`` known at lattice indices ``k`` read at every index of ``idx``: a cubic spline
    through the known samples (scipy's CubicSpline, not-a-knot; its error on a tone of
    frequency f at rate fs grows as (pi f / fs)**4, linear interpolation's as
    (pi f / fs)**2: a dropped sample of a 70 Hz motor line at 400 Hz is 1.5 % off instead of
    15 %); linear with fewer than 4 samples, NaN with fewer than 2."""
    if len(k) < 2:
        return np.full(len(idx), np.nan)
    if len(k) < 4:
        return np.interp(idx, k, v)
    from scipy.interpolate import CubicSpline
    return CubicSpline(k, v)(np.clip(idx, k[0], k[-1]))


def on_lattice(series, max_fill=4):
    """(xyz on the lattice, rate) of a series with dropped samples: the missing lattice
    samples filled (:func:`_fill`, a cubic spline) where at most ``max_fill`` are missing in a
    row (NaN beyond: Welch stays within the runs); ``series`` as it is (its median
    rate) when it is not on a lattice or drops none."""
    lat = lattice(series.time_s)
    if lat is None:
        return series.xyz, series.rate_hz, False
    base, k = lat
    if k[-1] + 1 == len(k):
        return series.xyz, 1.0 / base, False
    idx = np.arange(k[-1] + 1)
    out = np.empty((len(idx), 3))
    for a in range(3):
        ok = np.isfinite(series.xyz[:, a])
        out[:, a] = _fill(idx, k[ok], series.xyz[ok, a])
    for j in np.flatnonzero(np.diff(k) - 1 > max_fill):       # gaps longer than max_fill: NaN
        out[k[j] + 1:k[j + 1]] = np.nan
    return out, 1.0 / base, True


def regular(series):
    """(series on its lattice, the number of samples filled) of a series logged with
    samples dropped (:func:`on_lattice`); (``series``, 0) when it drops none or is on no
    lattice."""
    xyz, rate, filled = on_lattice(series)
    if not filled:
        return series, 0
    t = series.time_s[0] + np.arange(len(xyz)) / rate
    return GyroSeries(series.name, t, xyz, rate), len(xyz) - len(series.xyz)


# --------------------------------------------------------------------------- running the chain

def run_biquads(x, coefs):
    """Run biquad sections in series over ``x`` (n, 3), sample by sample, Direct Form I
    with the state kept across coefficient changes. ``coefs``: (n, k, 5) -- section j's
    (b0, b1, b2, a1, a2) at sample i, the same for the three axes -- or (n, k, 3, 5)
    per axis. Returns y (n, 3). Non-finite input samples pass as NaN and leave the
    state as it was."""
    x = np.asarray(x, dtype=np.float64)
    c = np.asarray(coefs, dtype=np.float64)
    n = len(x)
    if c.ndim == 3:
        c = np.broadcast_to(c[:, :, None, :], (n, c.shape[1], 3, 5))
    k = c.shape[1]
    out = np.full_like(x, np.nan)
    for ax in range(3):
        cl = c[:, :, ax, :].tolist()
        xs = x[:, ax].tolist()
        st = [[0.0, 0.0, 0.0, 0.0] for _ in range(k)]     # x1, x2, y1, y2 of each section
        primed = False
        ys = [math.nan] * n
        for i in range(n):
            v = xs[i]
            if not math.isfinite(v):
                continue
            if not primed:                  # start at rest on the first sample (no start-up transient)
                for j in range(k):
                    b0, b1, b2, a1, a2 = cl[i][j]
                    g = (b0 + b1 + b2) / (1.0 + a1 + a2) if abs(1.0 + a1 + a2) > 1e-12 else 1.0
                    st[j] = [v, v, v * g, v * g]
                    v = v * g
                v = xs[i]
                primed = True
            row = cl[i]
            for j in range(k):
                b0, b1, b2, a1, a2 = row[j]
                s = st[j]
                y = b0 * v + b1 * s[0] + b2 * s[1] - a1 * s[2] - a2 * s[3]
                s[1] = s[0]
                s[0] = v
                s[3] = s[2]
                s[2] = y
                v = y
            ys[i] = v
        out[:, ax] = ys
    return out


# --------------------------------------------------------------------------- the comparison

def _psd(xyz, rate_hz, keep, nperseg):
    """(freq, (3, bins) PSD) of the samples ``keep`` (others NaN: Welch within the runs)."""
    x = np.where(keep[:, None], xyz, np.nan)
    out, f = [], None
    for k in range(3):
        f, p, _ = spectrum.welch_psd(x[:, k], rate_hz, nperseg)
        if p is None:
            return None
        out.append(p)
    return f, np.array(out)


def _nperseg(rate_hz, n_keep):
    n = 2 ** int(round(math.log2(max(16.0, SEGMENT_S * rate_hz))))
    while n > 16 and n * 4 > n_keep:
        n //= 2
    return n


def agreement(replayed, logged, keep_fn=None, max_hz=None):
    """The agreement of a replayed post-filter series with the logged one (both
    :class:`GyroSeries`, deg/s) over their common time (and ``keep_fn(time_s) -> bool``'s
    samples), over :data:`BAND_LO_HZ` to the slower stream's Nyquist frequency (or
    ``max_hz``, when lower): ``{"band_hz", "db_rms": {x, y, z, all}, "db_mean": {...},
    "n_bins", "resolution_hz"}``, or (None, why). A series logged with samples
    dropped is put back on its lattice first (:func:`on_lattice`)."""
    t0 = max(np.nanmin(replayed.time_s), np.nanmin(logged.time_s))
    t1 = min(np.nanmax(replayed.time_s), np.nanmax(logged.time_s))
    if not t1 > t0:
        return None, "the pre- and post-filter streams do not overlap in time"
    regular = []
    for s in (replayed, logged):
        xyz, rate, _ = on_lattice(s)
        t = s.time_s if len(xyz) == len(s.time_s) else s.time_s[0] + np.arange(len(xyz)) / rate
        regular.append((s.name, t, xyz, rate))
    slow = min(regular[0][3], regular[1][3])
    hi = 0.5 * slow if max_hz is None else min(0.5 * slow, float(max_hz))
    if hi <= BAND_LO_HZ:
        return None, (f"the slower stream ({slow:.0f} Hz) stops at "
                      f"{hi:.1f} Hz, below the {BAND_LO_HZ:g} Hz the agreement band starts at")
    specs = []
    for name, t, xyz, rate in regular:
        keep = (t >= t0) & (t <= t1) & np.isfinite(xyz).all(axis=1)
        if keep_fn is not None:
            keep &= np.asarray(keep_fn(t), dtype=bool)
        if keep.sum() < 64:
            return None, f"{name}: fewer than 64 samples over the common (flying) time"
        # the same segment length in seconds: the same bin width in both spectra
        nper = _nperseg(rate, int(keep.sum())) if not specs else \
            max(16, int(round(specs[0][2] * rate / regular[0][3])))
        got = _psd(xyz, rate, keep, nper)
        if got is None:
            return None, f"{name}: too few contiguous samples for a spectrum"
        specs.append((*got, nper))
    (f1, p1, _), (f2, p2, _) = specs
    band = (f1 >= BAND_LO_HZ) & (f1 <= hi * 0.98)
    if band.sum() < MIN_BAND_BINS:
        return None, f"fewer than {MIN_BAND_BINS} spectrum bins between {BAND_LO_HZ:g} and {hi:.0f} Hz"
    rms, mean = {}, {}
    for k, a in enumerate(AXES):
        logged_p = np.interp(f1[band], f2, p2[k])
        with np.errstate(divide="ignore", invalid="ignore"):
            d = 10.0 * np.log10(p1[k][band] / logged_p)
        d = d[np.isfinite(d)]
        rms[a] = round(float(np.sqrt(np.mean(d * d))), 3) if len(d) else None
        mean[a] = round(float(np.mean(d)), 3) if len(d) else None
    got = [v for v in rms.values() if v is not None]
    rms["all"] = round(float(np.sqrt(np.mean(np.square(got)))), 3) if got else None
    return {"band_hz": [BAND_LO_HZ, round(float(f1[band][-1]), 2)], "db_rms": rms, "db_mean": mean,
            "n_bins": int(band.sum()), "resolution_hz": round(float(f1[1] - f1[0]), 4),
            "over_s": [round(float(t0), 3), round(float(t1), 3)]}, ""


# --------------------------------------------------------------------------- a log

def replay_review(log, autopilot, params, filters, stream, keep_fn=None):
    """(replay or None, note) of a log: its pre-filter gyro run through the vehicle's
    chain (the autopilot strategy's ``replay_sections``, the centres moved by its
    ``notch_tracks``) and compared with its logged post-filter gyro
    (``logged_post_filter``). ``keep_fn(time_s) -> bool``: the samples compared
    (flying time); None: all. ``stream``: the pre-filter gyro stream (the filter
    review's :func:`~gyrodenoise.flightlog.filter_review.pick_pre_filter_stream`).

    The replay (JSON-able): ``pre`` / ``post`` (stream, rate), ``filter_rate_hz``
    (the rate the coefficients are designed at: the pre-filter stream's), ``tracks``
    (what moved each tracking stage), ``agreement`` (:func:`agreement`; None with
    ``agreement_note``), ``unfiltered_db_rms`` (the pre-filter gyro itself against the logged
    post-filter one, the same figure: what the replay has to beat), ``notes`` (what the
    replay leaves out)."""
    pre = GyroSeries.of_stream(stream)
    if pre is None:
        return None, "no pre-filter gyro stream in deg/s to replay"
    post = autopilot.logged_post_filter(log, stream)
    if post is None:
        return None, f"{pre.name} is the pre-filter gyro; the log holds no post-filter gyro to compare with"
    tracks = autopilot.notch_tracks(log, params, filters)
    production = autopilot.pre_filter_production(log, params, filters, stream)
    notes = []
    # the chain runs on consecutive samples: a pre-filter stream logged with samples dropped
    # goes back on its lattice first (the missing samples interpolated)
    pre, n_filled = regular(pre)
    if n_filled:
        notes.append(f"{pre.name}: {n_filled} samples the logger dropped filled on its "
                     f"{pre.rate_hz:.0f} Hz "
                     "lattice (a cubic spline) before the replay")
    work = pre
    if production is not None and (production.filter_rate_hz > 1.02 * pre.rate_hz or production.averaged > 1):
        work = at_filter_rate(pre, production)
        notes.append(f"{pre.name} ({pre.rate_hz:.0f} Hz) brought to the rate the filters run at, "
                     f"{work.rate_hz:.0f} Hz ({production.source})"
                     + (f", its mean over {production.averaged} samples undone up to {pre.rate_hz / 2:.0f} Hz"
                        if production.averaged > 1 else "")
                     + "; what its making folded down from above that cannot be undone")
    coefs, chain_notes = autopilot.replay_sections(params, filters, tracks, work.time_s, work.rate_hz)
    notes += list(chain_notes)
    y = run_biquads(work.xyz, coefs)
    replayed = GyroSeries(f"{pre.name} replayed", work.time_s, y, work.rate_hz)
    unfiltered = work
    # like with like: the replay read where the vehicle logged its post-filter gyro, so that
    # both go through the same logging (its rate, its dropped samples)
    at_post = sampled_at(replayed, post.time_s)
    if np.isfinite(at_post).all(axis=1).sum() >= 64:
        replayed = GyroSeries(replayed.name, post.time_s, at_post, post.rate_hz)
        unfiltered = GyroSeries(pre.name, post.time_s, sampled_at(work, post.time_s), post.rate_hz)
        notes.append(f"the replay read at {post.name}'s own sample times")
    max_hz = 0.5 * pre.rate_hz
    agree, why = agreement(replayed, post, keep_fn, max_hz)
    unfilt, _ = agreement(unfiltered, post, keep_fn, max_hz)
    out = {"pre": {"stream": pre.name, "rate_hz": round(pre.rate_hz, 2)},
           "post": {"stream": post.name, "rate_hz": round(post.rate_hz, 2)},
           "filter_rate_hz": round(work.rate_hz, 2),
           "production": None if production is None else {
               "filter_rate_hz": round(production.filter_rate_hz, 2), "averaged": production.averaged,
               "source": production.source},
           "sections": int(np.asarray(coefs).shape[1]),
           "tracks": {k: tr.source for k, tr in tracks.items()},
           "agreement": agree,
           "unfiltered_db_rms": unfilt["db_rms"]["all"] if unfilt else None,
           "agreement_metric": (
               f"sqrt(mean((10 log10(PSD_replayed / PSD_logged))**2)) over {BAND_LO_HZ:g} Hz..the slower "
               "stream's Nyquist frequency (and the pre-filter stream's), dB per axis; all: rms over the axes"),
           "notes": notes}
    if agree is None:
        out["agreement_note"] = why
    elif out["unfiltered_db_rms"] is not None and agree["db_rms"]["all"] is not None \
            and agree["db_rms"]["all"] >= out["unfiltered_db_rms"]:
        out["worse_than_unfiltered"] = True
        out["agreement_note"] = (
            f"the replay ({agree['db_rms']['all']:.2f} dB) is no closer to the logged post-filter gyro than the "
            f"unfiltered pre-filter gyro ({out['unfiltered_db_rms']:.2f} dB): the chain or the streams' making is "
            "not modelled right; not an agreement")
    return out, ""


def replay_section_html(rep, esc=None):
    """A short HTML section of a log's ``notch_replay`` (``esc``: the report's HTML escape,
    :func:`html.escape` by default)."""
    import html
    esc = esc or html.escape
    nr = rep.get("notch_replay")
    if nr is None:
        return (f"<section><h2>Filter replay</h2><p>{esc(rep.get('notch_replay_note') or 'no replay')}</p>"
                "</section>")
    ag = nr.get("agreement")
    if ag is None:
        fig = f"<p>No agreement figure: {esc(nr.get('agreement_note', ''))}</p>"
    else:
        cells = "".join(f"<td>{'' if ag['db_rms'][a] is None else format(ag['db_rms'][a], '.2f')}</td>"
                        for a in (*AXES, "all"))
        warn = (f"<p><strong>Not an agreement:</strong> {esc(nr['agreement_note'])}</p>"
                if nr.get("worse_than_unfiltered") else "")
        fig = warn + ("<table><tr><th></th><th>x</th><th>y</th><th>z</th><th>all</th></tr>"
               f"<tr><th>replay vs logged, dB rms</th>{cells}</tr>"
               f"<tr><th>unfiltered vs logged, dB rms</th><td colspan=\"3\"></td>"
               f"<td>{'' if nr.get('unfiltered_db_rms') is None else format(nr['unfiltered_db_rms'], '.2f')}</td></tr>"
               "</table>"
               f"<p>{esc(nr['agreement_metric'])}; band {ag['band_hz'][0]:g}-{ag['band_hz'][1]:g} Hz, "
               f"{ag['n_bins']} bins.</p>")
    tracks = "; ".join(f"{k}: {v}" for k, v in nr.get("tracks", {}).items()) or "none"
    notes = "".join(f"<li>{esc(n)}</li>" for n in nr.get("notes", []))
    return (f"<section><h2>Filter replay</h2><p>{esc(nr['pre']['stream'])} ({nr['pre']['rate_hz']:g} Hz) run "
            f"through the vehicle's own filters, sample by sample, against {esc(nr['post']['stream'])} "
            f"({nr['post']['rate_hz']:g} Hz). Tracking: {esc(tracks)}.</p>{fig}"
            f"{'<ul>' + notes + '</ul>' if notes else ''}</section>")


# --------------------------------------------------------------------------- tracks from message columns

def column_track(m, col, source):
    """The Track of column ``col`` of message columns ``m`` (finite rows), or None."""
    if m is None or col is None or col not in m or not len(m["time_s"]):
        return None
    t = np.asarray(m["time_s"], dtype=np.float64)
    v = np.asarray(m[col], dtype=np.float64)
    ok = np.isfinite(t) & np.isfinite(v)
    if ok.sum() < 1:
        return None
    order = np.argsort(t[ok], kind="stable")
    return Track(t[ok][order], v[ok][order], source)


def track_of(channels):
    """The (m, motors) Track of motor speeds logged as
    :class:`~gyrodenoise.flightlog.timeseries.Channels` (a column per motor, NaN in the rows of
    another motor's message): each column interpolated on its own finite rows onto the times
    of the first column's; None for None or no finite value."""
    if channels is None:
        return None
    t = np.asarray(channels.time_s, dtype=np.float64)
    cols = [np.asarray(v, dtype=np.float64) for v in channels.columns.values()]
    cols = [v for v in cols if np.isfinite(v).any()]
    if not cols:
        return None
    base = t[np.isfinite(cols[0])]
    value = np.stack([np.interp(base, t[np.isfinite(v)], v[np.isfinite(v)]) for v in cols], axis=1)
    return Track(base, value, channels.source)
