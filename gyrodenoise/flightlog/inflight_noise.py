"""Noise measured in flight, for the estimator: per IMU, the gyro and accelerometer
noise density over flying time against the same IMU at rest (the disarmed
``ground`` segments), their ratio -- the "inflate by how much" of a Kalibr or
allan_variance_ros calibration done on the bench -- and the figures as the
autopilot's EKF noise parameters and a Kalibr ``imu.yaml`` for the flying condition.

The density (a white-noise density, unit/sqrt(Hz), Kalibr's ``*_noise_density``) is
measured only where the stream holds the sensor's noise, with an estimator that the
vehicle's motion does not lift: the core's own white-noise estimate
(:func:`gyrodenoise.analysis.motion_metrics.white_noise_std`: the smallest over lags 1..6
of the mean |4th difference|, which cancels any cubic and so takes motion below a few Hz
at (2 sin(pi f L / fs))**8 of its power, or the spectral floor where that is lower), over
each finite run of the kept samples, per axis: ``N = sigma / sqrt(fs)`` (white noise of
standard deviation sigma at rate fs has one-sided PSD 2 sigma**2 / fs). Beside it, the
Welch band figures of the earlier estimate, which motion does lift: ``band_mean`` (from
the mean one-sided PSD S over :data:`BAND_LO_HZ` to :data:`BAND_HI_SHARE` of the Nyquist
frequency, ``sqrt(mean S / 2)``: vibration counts there) and ``floor_mean`` (the median).

A stream cannot separate noise from motion when the vehicle's filters shaped it before it
was logged: a post-filter gyro whose low-pass cutoff is below twice its Nyquist frequency
(the band is filtered: 4th differences read the filter, not the sensor) or which is logged
below the rate the filters run at (point samples: what lies between its Nyquist frequency
and the cutoff folds in). There the density is None with ``refused`` saying why (ArduPilot
``IMU`` at 50 Hz after ``INS_GYRO_FILTER`` 20 Hz is one). The EKF figures come from the
pre-filter gyro where logged (the EKF integrates the unfiltered delta angles), else the
fastest stream measured; none where every stream is refused.

The bias walk (Kalibr's ``*_random_walk``, unit/s/sqrt(Hz)): at rest only (in flight
the motion hides it), where a run of rest lasts :data:`MIN_WALK_S`; from the
Allan deviation of the rest run at ``tau`` = a tenth of it, ``K = sigma(tau) sqrt(3 /
tau)`` -- the rate random walk's line through that point, an upper bound (white noise
and bias instability lift sigma there too).

The EKF parameters: the autopilot strategy's ``ekf_noise_params`` (ArduPilot
``EK3_GYRO_P_NSE`` / ``EK3_ACC_P_NSE``, PX4 ``EKF2_GYR_NOISE`` / ``EKF2_ACC_NOISE``)
from the flying density of the first IMU (the pre-filter gyro where logged: the EKF
integrates the unfiltered delta angles; a post-filter gyro reads low above the
vehicle's low-pass, and the figure says which it is).
"""

from __future__ import annotations

import math

import numpy as np

from gyrodenoise.analysis import spectrum
from gyrodenoise.flightlog.segments import segment_mask

#: the density band starts here (Hz): above the vehicle's own motion
BAND_LO_HZ = 5.0
#: ... and ends at this share of the Nyquist frequency
BAND_HI_SHARE = 0.9
#: Welch segments of about this length (s)
SEGMENT_S = 2.0
#: fewer kept samples than this: no figure
MIN_SAMPLES = 256
#: a rest run this long (s) gives a bias walk
MIN_WALK_S = 60.0
AXES = ("x", "y", "z")


def density(x, rate_hz, keep):
    """{x, y, z, mean, band_mean, floor_mean, n_samples, seconds} of the white-noise density
    (unit/sqrt(Hz)) of ``x`` (n, 3) at ``rate_hz`` over the samples ``keep``: x..mean the
    motion-robust estimate (:func:`white_density`), band_mean and floor_mean the Welch
    band's mean and median; None when too few or the band is empty."""
    keep = np.asarray(keep, dtype=bool) & np.isfinite(x).all(axis=1)
    hi = BAND_HI_SHARE * 0.5 * rate_hz
    if keep.sum() < MIN_SAMPLES or hi <= BAND_LO_HZ:
        return None
    nper = 2 ** int(round(math.log2(max(32.0, SEGMENT_S * rate_hz))))
    while nper > 32 and nper * 2 > keep.sum():
        nper //= 2
    xs = np.where(keep[:, None], x, np.nan)
    out, band, floor = {}, [], []
    for k, a in enumerate(AXES):
        f, p, nseg = spectrum.welch_psd(xs[:, k], rate_hz, nper)
        if p is None:
            return None
        sel = (f >= BAND_LO_HZ) & (f <= hi)
        if sel.sum() < 2:
            return None
        w = white_density(xs[:, k], rate_hz)
        if w is None:
            return None
        out[a] = w
        band.append(float(np.sqrt(np.mean(p[sel]) / 2.0)))
        floor.append(float(np.sqrt(np.median(p[sel]) / 2.0)))
    out["mean"] = float(np.mean([out[a] for a in AXES]))
    out["band_mean"] = float(np.mean(band))
    out["floor_mean"] = float(np.mean(floor))
    out["n_samples"] = int(keep.sum())
    out["seconds"] = round(float(keep.sum() / rate_hz), 2)
    return out


def white_density(x, rate_hz):
    """The white-noise density (unit/sqrt(Hz)) of a 1-D record (NaN outside the samples
    kept): ``white_noise_std / sqrt(rate)`` over its finite runs; None where none is long
    enough."""
    from gyrodenoise.analysis.motion_metrics import white_noise_std
    sd = white_noise_std(np.asarray(x, dtype=np.float64), rate_hz)
    return None if sd is None else float(sd) / math.sqrt(rate_hz)


def refusal(stage, rate_hz, cutoff_hz, filter_rate_hz, cutoff_name="the low-pass"):
    """Why a stream cannot give the sensor's noise density, or None when it can: a
    post-filter stream whose low-pass cutoff is unknown or below twice its Nyquist
    frequency (its band is filtered), or logged below the rate the filters run at (its
    samples hold what folded down from between its Nyquist frequency and the cutoff)."""
    if stage != "post-filter":
        return None
    nyq = 0.5 * rate_hz
    if not cutoff_hz:
        return (f"a post-filter stream at {rate_hz:.0f} Hz and {cutoff_name}'s cutoff not logged: its band may be "
                "the vehicle's filter, not the sensor's noise")
    if cutoff_hz < 2.0 * nyq:
        return (f"a post-filter stream: {cutoff_name} at {cutoff_hz:g} Hz filters its band (Nyquist {nyq:.0f} Hz), "
                "so what is left there is the filter's roll-off and the vehicle's motion, not the sensor's noise")
    if filter_rate_hz and rate_hz < 0.9 * filter_rate_hz:
        return (f"a post-filter stream logged at {rate_hz:.0f} Hz, below the {filter_rate_hz:.0f} Hz the filters run "
                f"at: noise up to {cutoff_name}'s {cutoff_hz:g} Hz folds into it")
    return None


def _longest_run(keep):
    """(start, stop) of the longest run of True in ``keep``."""
    k = np.r_[False, np.asarray(keep, dtype=bool), False].astype(np.int8)
    d = np.diff(k)
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    if not len(starts):
        return 0, 0
    j = int(np.argmax(stops - starts))
    return int(starts[j]), int(stops[j])


def bias_walk(x, rate_hz, keep):
    """{x, y, z, mean, tau_s, seconds} of the rate random walk (unit/s/sqrt(Hz), an upper
    bound) from the longest run of ``keep`` lasting :data:`MIN_WALK_S`; None otherwise."""
    a, b = _longest_run(keep)
    if (b - a) / rate_hz < MIN_WALK_S:
        return None
    seg = np.asarray(x[a:b], dtype=np.float64)
    m = max(1, int((b - a) / 10))                   # tau = a tenth of the run
    tau = m / rate_hz
    out = {}
    for k, ax in enumerate(AXES):
        v = seg[:, k]
        n = len(v) // m
        means = v[: n * m].reshape(n, m).mean(axis=1)
        adev = math.sqrt(0.5 * np.mean(np.diff(means) ** 2)) if n > 1 else float("nan")
        out[ax] = adev * math.sqrt(3.0 / tau)
    out["mean"] = float(np.mean([out[ax] for ax in AXES]))
    out["tau_s"] = round(tau, 3)
    out["seconds"] = round((b - a) / rate_hz, 2)
    return out


def _rounded(d, nd=6):
    return None if d is None else {k: (float(f"{v:.{nd}g}") if isinstance(v, float) else v) for k, v in d.items()}


def _masks(log, t, records, segments):
    sess = log.boot_of(records) if records is not None and len(getattr(log, "boots", [])) > 1 else None
    return segment_mask(t, segments, "flying", sess), segment_mask(t, segments, "ground", sess)


def _series_rate(t):
    dt = np.diff(np.asarray(t, dtype=np.float64))
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if len(dt) else 0.0


def sensor_figures(kind, name, stage, t, x, unit, flying, rest, refused=None):
    """One IMU's figures: ``{"sensor", "stream", "stage", "unit", "rate_hz", "flying",
    "rest", "ratio", "bias_walk_rest"}`` (``ratio``: flying / rest mean density);
    ``refused`` (:func:`refusal`): the densities None, with it as ``refused``."""
    rate = _series_rate(t)
    ok = rate and refused is None
    fly = density(x, rate, flying) if ok else None
    at_rest = density(x, rate, rest) if ok else None
    ratio = round(fly["mean"] / at_rest["mean"], 3) if fly and at_rest and at_rest["mean"] > 0 else None
    out = {"sensor": kind, "stream": name, "stage": stage, "unit": unit, "rate_hz": round(rate, 2),
           "flying": _rounded(fly), "rest": _rounded(at_rest), "ratio": ratio,
           "bias_walk_rest": _rounded(bias_walk(x, rate, rest)) if ok else None,
           "bias_walk_unit": unit.replace("/sqrt(Hz)", "/s/sqrt(Hz)")}
    if refused is not None:
        out["refused"] = refused
    elif fly and fly["band_mean"] > 2.0 * fly["mean"]:
        out["band_note"] = (f"flying, the Welch band {BAND_LO_HZ:g} Hz..{BAND_HI_SHARE:g} x Nyquist reads "
                            f"{fly['band_mean'] / fly['mean']:.1f}x the white-noise density: motion or vibration "
                            "in the band")
    return out


def inflight_noise(log, segments, autopilot, params, filters=None):
    """(figures or None, note) of a log: per gyro stream (rad/s) and accelerometer
    (m/s/s, the strategy's ``accel_series``) the density flying and at rest, their
    ratio, the bias walk at rest; ``refused``: the streams that cannot separate the
    sensor's noise from the vehicle's filters and motion, each with why (:func:`refusal`; the stages
    and cutoffs from the strategy: ``stream_stage``, ``lowpass_param``,
    ``accel_filtering``); ``ekf_parameters`` (the strategy's ``ekf_noise_params``, of
    the streams measured; a parameter left out, with ``ekf_note``, where none is) and
    ``kalibr_flight`` (the figures of a Kalibr imu.yaml for flight, :func:`kalibr_yaml`
    writes it). ``filters``: the vehicle's filters
    (:func:`~gyrodenoise.flightlog.vehicle_filters.vehicle_filters`; read from
    ``params`` when None)."""
    from gyrodenoise.flightlog import vehicle_filters as vf
    if not any(s.kind == "flying" for s in segments or []):
        return None, "no flying segment: no in-flight noise"
    filters = filters if filters is not None else vf.vehicle_filters(autopilot, params)
    filter_rate = filters.get("filter_rate_hz") if isinstance(filters, dict) else None
    lp = autopilot.lowpass_param(params)
    gyro_cut = _number(params.get(lp)) if lp else None
    gyros, accels = [], []
    for s in log.gyro:
        if not s.to_deg_s or s.n < MIN_SAMPLES:
            continue
        t = np.asarray(s.time_s, dtype=np.float64)
        fm, rm = _masks(log, t, getattr(s, "records", None), segments)
        x = np.radians(np.asarray(s.raw, dtype=np.float64) * s.to_deg_s)
        stage = autopilot.stream_stage(params, s)
        why = refusal(stage, _series_rate(t), gyro_cut, filter_rate, lp or "the low-pass")
        gyros.append(sensor_figures("gyro", s.name, stage, t, x, "rad/s/sqrt(Hz)", fm, rm, why))
    a_stage, a_lp = autopilot.accel_filtering(params)
    acc_cut = _number(params.get(a_lp)) if a_lp else None
    for name, t, xyz in autopilot.accel_series(log):
        t = np.asarray(t, dtype=np.float64)
        fm, rm = _masks(log, t, None, segments)
        why = refusal(a_stage, _series_rate(t), acc_cut, filter_rate, a_lp or "the low-pass")
        accels.append(sensor_figures("accel", name, a_stage, t, np.asarray(xyz, dtype=np.float64),
                                     "m/s/s/sqrt(Hz)", fm, rm, why))
    refused = [{k: f[k] for k in ("sensor", "stream", "stage", "rate_hz", "refused")}
               for f in gyros + accels if f.get("refused")]
    gyros = [g for g in gyros if g["flying"]]
    accels = [a for a in accels if a["flying"]]
    if not gyros and not accels and not refused:
        return None, (f"no stream with {MIN_SAMPLES} flying samples and a band above {BAND_LO_HZ:g} Hz "
                      "(the rate must exceed about 11 Hz)")
    g0 = _for_ekf(gyros)
    a0 = _for_ekf(accels)
    gd = g0["flying"]["mean"] if g0 else None
    ad = a0["flying"]["mean"] if a0 else None
    out = {"band": f"{BAND_LO_HZ:g} Hz..{BAND_HI_SHARE:g} x Nyquist of each stream (band_mean, floor_mean)",
           "metric": "white-noise density N = sigma / sqrt(fs) per axis, sigma the core's motion-robust white-noise "
                     "estimate (4th differences, lags 1..6; motion_metrics.white_noise_std); mean over the axes; "
                     "band_mean / floor_mean: sqrt(mean / median one-sided Welch PSD over the band / 2); "
                     "ratio = flying / rest; refused: the stream cannot separate noise from the filters and motion",
           "gyro": gyros, "accel": accels, "refused": refused,
           "ekf_parameters": autopilot.ekf_noise_params(gd, ad, params),
           "ekf_from": {"gyro": g0["stream"] if g0 else None, "gyro_stage": g0["stage"] if g0 else None,
                        "accel": a0["stream"] if a0 else None},
           "kalibr_flight": kalibr_figures(g0, a0)}
    missing = [k for k, v in (("gyro", g0), ("accelerometer", a0)) if v is None]
    if missing:
        out["ekf_note"] = (f"no {' or '.join(missing)} noise measured: every stream refused or too short "
                           "(see refused); the EKF parameter is left as it is")
    return out, ""


def _number(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if v > 0 else None


def _for_ekf(figures):
    """The stream the EKF figures come from, among those measured flying: the fastest
    pre-filter one, else the fastest; None when none is measured."""
    got = [f for f in figures if f["flying"]]
    pre = [f for f in got if f["stage"] == "pre-filter"]
    return max(pre or got, key=lambda f: f["rate_hz"], default=None)


def kalibr_figures(gyro, accel):
    """The four numbers of a Kalibr imu.yaml for the flying condition (None where not measured)."""
    def walk(f):
        return f["bias_walk_rest"]["mean"] if f and f.get("bias_walk_rest") else None
    return {"gyroscope_noise_density": gyro["flying"]["mean"] if gyro else None,
            "gyroscope_random_walk": walk(gyro),
            "accelerometer_noise_density": accel["flying"]["mean"] if accel else None,
            "accelerometer_random_walk": walk(accel),
            "update_rate": gyro["rate_hz"] if gyro else (accel["rate_hz"] if accel else None)}


def kalibr_yaml(figures, rostopic="/imu0"):
    """A Kalibr imu.yaml (text) of ``kalibr_flight``; a number not measured is written as
    ``.nan`` with a comment (Kalibr needs all four: fill them from a bench calibration)."""
    lines = ["# gyrodenoise: noise measured in flight (flying segments); random walks from rest",
             f"rostopic: {rostopic}"]
    for key in ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                "gyroscope_random_walk", "update_rate"):
        v = figures.get(key)
        lines.append(f"{key}: {v:.6g}" if v is not None else f"{key}: .nan  # not measured in this log")
    return "\n".join(lines) + "\n"


def noise_lines(rep):
    """Text summary lines of a log's ``inflight_noise``."""
    nz = rep.get("inflight_noise")
    if not nz:
        return [f"in-flight noise: none ({rep.get('inflight_noise_note', '')})"]
    parts = []
    for f in nz["gyro"] + nz["accel"]:
        r = f" (x{f['ratio']:.2f} the rest's)" if f["ratio"] else ""
        parts.append(f"{f['sensor']} {f['stream']} {f['flying']['mean']:.3g} {f['unit']}{r}")
    parts += [f"{f['sensor']} {f['stream']} not measured ({f['stage']})" for f in nz.get("refused", [])]
    ekf = ", ".join(f"{k} {v['value']:g}" for k, v in nz["ekf_parameters"].items())
    return ["in-flight noise: " + "; ".join(parts) + (f"; EKF: {ekf}" if ekf else "")]
