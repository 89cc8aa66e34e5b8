"""Noise measured in flight, for the estimator: per IMU, the gyro and accelerometer
noise density over flying time against the same IMU at rest (the disarmed
``ground`` segments), their ratio -- the "inflate by how much" of a Kalibr or
allan_variance_ros calibration done on the bench -- and the figures as the
autopilot's EKF noise parameters and a Kalibr ``imu.yaml`` for the flying condition.

The density (a white-noise density, unit/sqrt(Hz), Kalibr's ``*_noise_density``):
from the one-sided Welch PSD S(f) (:func:`gyrodenoise.analysis.spectrum.welch_psd`,
segments of :data:`SEGMENT_S` within the runs of kept samples) averaged over
:data:`BAND_LO_HZ` (5 Hz, above the vehicle's motion) to :data:`BAND_HI_SHARE` of the
Nyquist frequency (below the logger's roll-off): ``N = sqrt(mean S / 2)`` (white noise
of standard deviation sigma at rate fs has S = 2 sigma**2 / fs and N = sigma /
sqrt(fs)). The mean, not the median: the vibration the EKF must absorb counts; the
median (the floor between the vibration lines) is given beside it.

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
    """{x, y, z, mean, floor_mean, n_samples, seconds} of the noise density (unit/sqrt(Hz))
    of ``x`` (n, 3) at ``rate_hz`` over the samples ``keep``; None when too few or the
    band is empty."""
    keep = np.asarray(keep, dtype=bool) & np.isfinite(x).all(axis=1)
    hi = BAND_HI_SHARE * 0.5 * rate_hz
    if keep.sum() < MIN_SAMPLES or hi <= BAND_LO_HZ:
        return None
    nper = 2 ** int(round(math.log2(max(32.0, SEGMENT_S * rate_hz))))
    while nper > 32 and nper * 2 > keep.sum():
        nper //= 2
    xs = np.where(keep[:, None], x, np.nan)
    out, floor = {}, []
    for k, a in enumerate(AXES):
        f, p, nseg = spectrum.welch_psd(xs[:, k], rate_hz, nper)
        if p is None:
            return None
        band = (f >= BAND_LO_HZ) & (f <= hi)
        if band.sum() < 2:
            return None
        out[a] = float(np.sqrt(np.mean(p[band]) / 2.0))
        floor.append(float(np.sqrt(np.median(p[band]) / 2.0)))
    out["mean"] = float(np.mean([out[a] for a in AXES]))
    out["floor_mean"] = float(np.mean(floor))
    out["n_samples"] = int(keep.sum())
    out["seconds"] = round(float(keep.sum() / rate_hz), 2)
    return out


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


def sensor_figures(kind, name, stage, t, x, unit, flying, rest):
    """One IMU's figures: ``{"sensor", "stream", "stage", "unit", "rate_hz", "flying",
    "rest", "ratio", "bias_walk_rest"}`` (``ratio``: flying / rest mean density)."""
    rate = _series_rate(t)
    fly = density(x, rate, flying) if rate else None
    at_rest = density(x, rate, rest) if rate else None
    ratio = round(fly["mean"] / at_rest["mean"], 3) if fly and at_rest and at_rest["mean"] > 0 else None
    return {"sensor": kind, "stream": name, "stage": stage, "unit": unit, "rate_hz": round(rate, 2),
            "flying": _rounded(fly), "rest": _rounded(at_rest), "ratio": ratio,
            "bias_walk_rest": _rounded(bias_walk(x, rate, rest)) if rate else None,
            "bias_walk_unit": unit.replace("/sqrt(Hz)", "/s/sqrt(Hz)")}


def inflight_noise(log, segments, autopilot, params):
    """(figures or None, note) of a log: per gyro stream (rad/s) and accelerometer
    (m/s/s, the strategy's ``accel_series``) the density flying and at rest, their
    ratio, the bias walk at rest; ``ekf_parameters`` (the strategy's
    ``ekf_noise_params``) and ``kalibr_flight`` (the figures of a Kalibr imu.yaml
    for flight, :func:`kalibr_yaml` writes it)."""
    if not any(s.kind == "flying" for s in segments or []):
        return None, "no flying segment: no in-flight noise"
    gyros, accels = [], []
    for s in log.gyro:
        if not s.to_deg_s or s.n < MIN_SAMPLES:
            continue
        t = np.asarray(s.time_s, dtype=np.float64)
        fm, rm = _masks(log, t, getattr(s, "records", None), segments)
        x = np.radians(np.asarray(s.raw, dtype=np.float64) * s.to_deg_s)
        gyros.append(sensor_figures("gyro", s.name, s.stage, t, x, "rad/s/sqrt(Hz)", fm, rm))
    for name, t, xyz in autopilot.accel_series(log):
        t = np.asarray(t, dtype=np.float64)
        fm, rm = _masks(log, t, None, segments)
        accels.append(sensor_figures("accel", name, "unknown", t, np.asarray(xyz, dtype=np.float64),
                                     "m/s/s/sqrt(Hz)", fm, rm))
    gyros = [g for g in gyros if g["flying"]]
    accels = [a for a in accels if a["flying"]]
    if not gyros and not accels:
        return None, (f"no stream with {MIN_SAMPLES} flying samples and a band above {BAND_LO_HZ:g} Hz "
                      "(the rate must exceed about 11 Hz)")
    g0 = _for_ekf(gyros)
    a0 = accels[0] if accels else None
    gd = g0["flying"]["mean"] if g0 else None
    ad = a0["flying"]["mean"] if a0 else None
    out = {"band": f"{BAND_LO_HZ:g} Hz..{BAND_HI_SHARE:g} x Nyquist of each stream",
           "metric": "noise density N = sqrt(mean one-sided PSD over the band / 2) per axis; mean over the axes; "
                     "floor_mean: the same from the median PSD; ratio = flying / rest",
           "gyro": gyros, "accel": accels,
           "ekf_parameters": autopilot.ekf_noise_params(gd, ad, params),
           "ekf_from": {"gyro": g0["stream"] if g0 else None, "gyro_stage": g0["stage"] if g0 else None,
                        "accel": a0["stream"] if a0 else None},
           "kalibr_flight": kalibr_figures(g0, a0)}
    return out, ""


def _for_ekf(gyros):
    """The gyro the EKF figures come from: the first pre-filter one, else the first."""
    pre = [g for g in gyros if g["stage"] == "pre-filter"]
    return (pre or gyros or [None])[0]


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
    ekf = ", ".join(f"{k} {v['value']:g}" for k, v in nz["ekf_parameters"].items())
    return ["in-flight noise: " + "; ".join(parts) + (f"; EKF: {ekf}" if ekf else "")]
