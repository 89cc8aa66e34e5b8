"""Seeded ground-truth rate profiles: true angular rates to simulate a moving gyro with.

Every profile is a plain function returning the *true* angular rate in deg/s
for ``n`` samples at ``sample_rate_hz``; feed it to
``gd.simulate(card, n, seed=..., true_rate_deg_s=profile(...))`` and compare a
filter's output with it. All random choices come from ``numpy.random.default_rng(seed)``,
so a (profile, n, rate, seed) tuple always gives the same array.

=====================  ======================================================
name                   truth
=====================  ======================================================
at_rest                0
constant               a constant rate (default 10 deg/s)
steps                  piecewise constant: 0, then levels of 2-50 deg/s
                       (random sign) held 3-8 s each
smooth                 band-limited random motion: white noise, zero-phase
                       low-passed (4th-order Butterworth, default 2 Hz),
                       scaled to a stated RMS (e.g. 20 deg/s MEMS, 5 deg/s FOG)
sine_0p2hz/1hz/5hz     sine of the stated RMS (amplitude rms * sqrt 2)
rest_manoeuvre_rest    rest, band-limited manoeuvre, rest (thirds of the
                       record; the manoeuvre fades in and out over 0.5 s)
flight_like            a real log's rate (PX4 ``px4_sample.ulg``,
                       sensor_combined gyro_rad, 250 Hz), zero-phase smoothed
                       (default 10 Hz), resampled to ``sample_rate_hz``
=====================  ======================================================

:data:`PROFILES` maps these names to callables with the common signature
``f(n, sample_rate_hz, seed=0, **kw)`` (``flight_like`` also takes ``path``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from benchmarks._data import SHARED_DATA

#: The shared real PX4 log (``../shared/data/logs``; not copied into the repository:
#: see ../shared/data/README.md).
DEFAULT_ULOG = str(SHARED_DATA / "logs" / "px4_sample.ulg")


def _check(n, sample_rate_hz):
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n!r}")
    if not (sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be > 0, got {sample_rate_hz!r}")
    return n, float(sample_rate_hz)


def _zero_phase_lowpass(x, sample_rate_hz, cutoff_hz, order=4):
    """Zero-phase Butterworth low-pass (scipy ``sosfiltfilt``)."""
    from scipy.signal import butter, sosfiltfilt
    fc = min(float(cutoff_hz), 0.45 * sample_rate_hz)
    sos = butter(order, fc, btype="low", fs=sample_rate_hz, output="sos")
    return sosfiltfilt(sos, x)


def at_rest(n, sample_rate_hz, seed=0):
    """True rate 0 deg/s."""
    n, _ = _check(n, sample_rate_hz)
    return np.zeros(n)


def constant(n, sample_rate_hz, seed=0, rate_deg_s=10.0):
    """A constant true rate, deg/s (default 10)."""
    n, _ = _check(n, sample_rate_hz)
    return np.full(n, float(rate_deg_s))


def steps(n, sample_rate_hz, seed=0, min_deg_s=2.0, max_deg_s=50.0, hold_min_s=3.0,
          hold_max_s=8.0, first_hold_s=4.0):
    """Piecewise-constant rate: 0 for ``first_hold_s``, then levels drawn
    uniformly in [min_deg_s, max_deg_s] with a random sign, each held for a
    uniform [hold_min_s, hold_max_s] seconds. Instantaneous steps."""
    n, fs = _check(n, sample_rate_hz)
    rng = np.random.default_rng(seed)
    out = np.zeros(n)
    i = int(round(first_hold_s * fs))
    while i < n:
        level = rng.uniform(min_deg_s, max_deg_s) * rng.choice((-1.0, 1.0))
        hold = int(round(rng.uniform(hold_min_s, hold_max_s) * fs))
        out[i:i + hold] = level
        i += hold
    return out


def smooth(n, sample_rate_hz, seed=0, rms_deg_s=20.0, bandwidth_hz=2.0):
    """Band-limited random motion: white noise zero-phase low-passed at
    ``bandwidth_hz`` (4th-order Butterworth), scaled to ``rms_deg_s``."""
    n, fs = _check(n, sample_rate_hz)
    rng = np.random.default_rng(seed)
    pad = int(2.0 * fs / bandwidth_hz) + 16     # filtfilt edge effects stay outside
    x = _zero_phase_lowpass(rng.standard_normal(n + 2 * pad), fs, bandwidth_hz)[pad:pad + n]
    return x * (rms_deg_s / max(float(np.sqrt(np.mean(x * x))), 1e-300))


def sine(n, sample_rate_hz, seed=0, frequency_hz=1.0, rms_deg_s=20.0):
    """A sine of ``frequency_hz`` with RMS ``rms_deg_s`` (random phase from seed)."""
    n, fs = _check(n, sample_rate_hz)
    phase = np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi)
    t = np.arange(n) / fs
    return rms_deg_s * math.sqrt(2.0) * np.sin(2.0 * math.pi * frequency_hz * t + phase)


def sine_0p2hz(n, sample_rate_hz, seed=0, rms_deg_s=20.0):
    """0.2 Hz sine of RMS ``rms_deg_s``."""
    return sine(n, sample_rate_hz, seed, 0.2, rms_deg_s)


def sine_1hz(n, sample_rate_hz, seed=0, rms_deg_s=20.0):
    """1 Hz sine of RMS ``rms_deg_s``."""
    return sine(n, sample_rate_hz, seed, 1.0, rms_deg_s)


def sine_5hz(n, sample_rate_hz, seed=0, rms_deg_s=20.0):
    """5 Hz sine of RMS ``rms_deg_s``."""
    return sine(n, sample_rate_hz, seed, 5.0, rms_deg_s)


def rest_manoeuvre_rest(n, sample_rate_hz, seed=0, rms_deg_s=20.0, bandwidth_hz=2.0,
                        fade_s=0.5):
    """At rest for the first third, a :func:`smooth` manoeuvre (RMS
    ``rms_deg_s`` over its own span) in the middle third, at rest again for the
    last third. The manoeuvre is faded in and out with raised-cosine ramps of
    ``fade_s`` so the rate itself is continuous."""
    n, fs = _check(n, sample_rate_hz)
    a, b = n // 3, 2 * n // 3
    out = np.zeros(n)
    m = b - a
    if m < 1:
        return out
    w = np.ones(m)
    nf = min(int(round(fade_s * fs)), m // 2)
    if nf > 0:
        ramp = 0.5 - 0.5 * np.cos(np.pi * (np.arange(nf) + 0.5) / nf)
        w[:nf] = ramp
        w[m - nf:] = ramp[::-1]
    out[a:b] = smooth(m, fs, seed, rms_deg_s, bandwidth_hz) * w
    return out


def load_ulog_gyro_deg_s(path=DEFAULT_ULOG):
    """(time_s from the first sample, rate_deg_s[N, 3]) of ``sensor_combined.gyro_rad`` in a
    PX4 ULog, read by the package's reader (:func:`gyrodenoise.flightlog.ulog.read`).

    The log stores whole microseconds and float32 rad/s: the time is taken in whole
    microseconds from the first sample and the rate converted in the log's own precision.
    Raises FileNotFoundError if the file is absent, ValueError if it has no
    ``sensor_combined`` gyro, and gyrodenoise's InputError if it cannot be read."""
    from gyrodenoise.flightlog import ulog
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"flight_like needs the PX4 log {p} (sensor_combined.gyro_rad); "
                                f"not found")
    _, streams, _ = ulog.read(p)
    gyro = next((s for s in streams if s.message == "sensor_combined"), None)
    if gyro is None:
        raise ValueError(f"{p}: no sensor_combined.gyro_rad in the log")
    time_us = np.rint(gyro.time_s * 1e6)
    return (time_us - time_us[0]) * 1e-6, np.degrees(gyro.raw.astype(gyro.field_dtype))


def flight_like(n, sample_rate_hz, seed=0, path=DEFAULT_ULOG, axis=0, smooth_hz=10.0,
                start_s=0.0):
    """A real flight's rate as the truth: axis ``axis`` (0 roll, 1 pitch, 2 yaw)
    of the PX4 log's ``sensor_combined.gyro_rad`` (rad/s -> deg/s, ~250 Hz),
    zero-phase low-passed at ``smooth_hz`` (removes the sensor noise and
    vibration of the log), linearly resampled to ``sample_rate_hz`` from
    ``start_s``. ``seed`` is accepted for the common signature (the profile is
    deterministic). Raises ValueError if the log is shorter than asked."""
    n, fs = _check(n, sample_rate_hz)
    t, g = load_ulog_gyro_deg_s(path)
    fs_log = 1.0 / float(np.median(np.diff(t)))
    # a uniform grid at the log's own rate first (the log has small jitter)
    tu = np.arange(0.0, t[-1], 1.0 / fs_log)
    x = np.interp(tu, t, g[:, int(axis)])
    x = _zero_phase_lowpass(x, fs_log, smooth_hz)
    tq = start_s + np.arange(n) / fs
    if tq[-1] > tu[-1]:
        raise ValueError(f"flight_like: {n} samples at {fs:g} Hz from {start_s:g} s need "
                         f"{tq[-1]:.1f} s of log, the log has {tu[-1]:.1f} s")
    return np.interp(tq, tu, x)


PROFILES = {
    "at_rest": at_rest,
    "constant": constant,
    "steps": steps,
    "smooth": smooth,
    "sine_0p2hz": sine_0p2hz,
    "sine_1hz": sine_1hz,
    "sine_5hz": sine_5hz,
    "rest_manoeuvre_rest": rest_manoeuvre_rest,
    "flight_like": flight_like,
}
