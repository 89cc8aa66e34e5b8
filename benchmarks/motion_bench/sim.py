"""An independent gyro simulator for the motion benchmark.

Written directly with numpy (it does not use :mod:`gyrodenoise.simulator` or
the model cards), seeded by ``numpy.random.default_rng(seed)``.

A record is ``z = ref + noise`` where

* ``truth``  -- the true angular rate, deg/s (the profile; the drone sensor's
  frame vibration is real motion and is part of it);
* ``bias``   -- the sensor's slow errors, deg/s: turn-on bias, Gauss-Markov bias
  instability, rate random walk and a temperature warm-up ramp;
* ``ref = truth + bias`` -- what a filter should output: no filter can tell a
  slow bias from slow motion, so the filters are judged against ``ref``;
* ``noise``  -- angle random walk (white rate noise) and quantisation (of the
  rate for the MEMS, of the integrated angle for the FOG).

Units: rates deg/s, ARW deg/sqrt(h), bias instability deg/h, rate random walk
deg/h/sqrt(h), sample rates Hz.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Sensor:
    key: str
    label: str
    sample_rate_hz: float
    arw_deg_rt_h: float            # angle random walk N
    bias_inst_deg_h: float         # Gauss-Markov bias instability (its std), deg/h
    bias_corr_s: float             # Gauss-Markov correlation time, s
    rrw_deg_h_rt_h: float          # rate random walk K
    turn_on_deg_s: float           # std of the turn-on bias
    temp_slope_deg_s_per_s: float  # initial slope of the warm-up ramp of the bias
    temp_tau_s: float              # time constant of the warm-up
    quant_rate_deg_s: float = 0.0  # rate LSB (MEMS), 0 = none
    quant_angle_deg: float = 0.0   # angle-increment quantum (FOG), 0 = none
    vibration_deg_s: float = 0.0   # frame vibration amplitude (real motion, part of the truth)
    vibration_hz: float = 0.0

    @property
    def white_std_deg_s(self):
        """Per-sample std of the ARW term: N / 60 * sqrt(fs)."""
        return self.arw_deg_rt_h / 60.0 * math.sqrt(self.sample_rate_hz)

    @property
    def quant_std_deg_s(self):
        """Per-sample std of the quantisation error of the rate."""
        if self.quant_angle_deg > 0:   # difference of two independent uniform angle errors
            return self.quant_angle_deg * self.sample_rate_hz * math.sqrt(2.0 / 12.0)
        return self.quant_rate_deg_s / math.sqrt(12.0)

    @property
    def noise_std_deg_s(self):
        """Per-sample std of the wideband noise (ARW + quantisation)."""
        return math.hypot(self.white_std_deg_s, self.quant_std_deg_s)


SENSORS = {
    # LN-200 class FOG: ARW 0.07 deg/sqrt(h), bias instability 0.5 deg/h, angle output
    # quantised at 1.1e-4 deg (about 2 micro-rad, a 20-bit increment)
    "fog": Sensor("fog", "navigation FOG 200 Hz (LN-200 class)", 200.0,
                  arw_deg_rt_h=0.07, bias_inst_deg_h=0.5, bias_corr_s=100.0,
                  rrw_deg_h_rt_h=0.02, turn_on_deg_s=1.0 / 3600.0,
                  temp_slope_deg_s_per_s=0.5 / 3600.0 / 60.0, temp_tau_s=600.0,
                  quant_angle_deg=1.1e-4),
    # ADIS16448 class: 0.66 deg/sqrt(h), 14.5 deg/h, 0.04 deg/s LSB
    "tactical": Sensor("tactical", "tactical MEMS 1 kHz (ADIS16448 class)", 1000.0,
                       arw_deg_rt_h=0.66, bias_inst_deg_h=14.5, bias_corr_s=60.0,
                       rrw_deg_h_rt_h=3.0, turn_on_deg_s=0.2,
                       temp_slope_deg_s_per_s=0.05 / 60.0, temp_tau_s=600.0,
                       quant_rate_deg_s=0.04),
    # ICM-20602 class drone MEMS: 0.004 deg/s/sqrt(Hz) = 0.24 deg/sqrt(h), LSB 1/16.4 deg/s,
    # with the frame's 80 Hz vibration (3 deg/s) in the true rate
    "drone": Sensor("drone", "drone MEMS 400 Hz (ICM-20602 class, 80 Hz frame vibration)", 400.0,
                    arw_deg_rt_h=0.24, bias_inst_deg_h=10.0, bias_corr_s=30.0,
                    rrw_deg_h_rt_h=10.0, turn_on_deg_s=1.0,
                    temp_slope_deg_s_per_s=0.03 / 60.0, temp_tau_s=300.0,
                    quant_rate_deg_s=1.0 / 16.4, vibration_deg_s=3.0, vibration_hz=80.0),
}


# ------------------------------------------------------------------ sensor errors
def gauss_markov(n, fs, std, corr_s, rng):
    """First-order Gauss-Markov sequence of stationary std ``std``, correlation time ``corr_s``."""
    a = math.exp(-1.0 / (fs * corr_s))
    w = rng.standard_normal(n) * std * math.sqrt(1.0 - a * a)
    w[0] = rng.standard_normal() * std
    from scipy.signal import lfilter
    return lfilter([1.0], [1.0, -a], w)


def bias_terms(sensor, n, rng, ramp_gain=1.0):
    """Slow errors (deg/s), summed: turn-on, Gauss-Markov, rate random walk, warm-up ramp."""
    fs = sensor.sample_rate_hz
    t = np.arange(n) / fs
    turn_on = rng.standard_normal() * sensor.turn_on_deg_s
    gm = gauss_markov(n, fs, sensor.bias_inst_deg_h / 3600.0, sensor.bias_corr_s, rng)
    # K deg/h/sqrt(h) -> deg/s/sqrt(s): K / 3600 / 60
    rrw = np.cumsum(rng.standard_normal(n)) * (sensor.rrw_deg_h_rt_h / 3600.0 / 60.0) / math.sqrt(fs)
    ramp = ramp_gain * sensor.temp_slope_deg_s_per_s * sensor.temp_tau_s * (1.0 - np.exp(-t / sensor.temp_tau_s))
    return turn_on + gm + rrw + ramp


def measure(sensor, ref, rng):
    """Add the wideband noise (ARW, quantisation) to ``ref`` (deg/s) -> the gyro's output."""
    fs = sensor.sample_rate_hz
    z = ref + rng.standard_normal(ref.size) * sensor.white_std_deg_s
    if sensor.quant_angle_deg > 0:
        # the FOG counts angle increments: quantise the integrated angle (the
        # remainder carries over, so the integral of the output stays exact)
        q = sensor.quant_angle_deg
        angle = np.cumsum(z) / fs + rng.uniform(0.0, q)
        counts = np.floor(angle / q)
        z = np.diff(counts, prepend=math.floor(rng.uniform(0.0, q) / q)) * q * fs
    elif sensor.quant_rate_deg_s > 0:
        z = np.round(z / sensor.quant_rate_deg_s) * sensor.quant_rate_deg_s
    return z


# ------------------------------------------------------------------ motion profiles
def _band_noise(n, fs, rng, lo_hz, hi_hz, rms):
    """Gaussian noise band-limited to [lo_hz, hi_hz] (FFT mask), scaled to ``rms``."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / fs)
    spec[(f < lo_hz) | (f > hi_hz)] = 0.0
    spec[0] = 0.0                      # zero mean
    x = np.fft.irfft(spec, n)
    s = x.std()
    return x * (rms / s) if s > 1e-9 else np.zeros(n)   # a band narrower than the record's resolution


def _tone(n, fs, rng, f0_hz, amp, wander_hz=0.0, am=0.0):
    """A tone of slowly wandering frequency and amplitude (motor/frame vibration)."""
    f = f0_hz + wander_hz * _band_noise(n, fs, rng, 0.0, 0.2, 1.0)
    phase = 2 * np.pi * np.cumsum(f) / fs + rng.uniform(0, 2 * np.pi)
    a = amp * (1.0 + am * _band_noise(n, fs, rng, 0.0, 0.5, 1.0))
    return a * np.sin(phase)


def _vibration(n, fs, rng, tones):
    """Sum of tones (f0, amp, wander), dropping those above 0.45 fs (the sensor's
    anti-alias filter removes them)."""
    out = np.zeros(n)
    for f0, amp, wander in tones:
        if f0 + 3 * wander <= 0.45 * fs:
            out += _tone(n, fs, rng, f0, amp, wander, am=0.2)
    return out


def _second_order(x, fs, f_hz, zeta):
    """Unit-DC-gain 2nd-order low-pass response (bilinear)."""
    from scipy.signal import bilinear, lfilter
    w = 2 * np.pi * f_hz
    b, a = bilinear([w * w], [1.0, 2 * zeta * w, w * w], fs)
    return lfilter(b, a, x)


def trapezoid(n, fs, rng):
    """Rate-table trapezoids: rest, ramp at 10-50 deg/s^2 to +-5..60 deg/s, hold, ramp back."""
    out = np.zeros(n)
    i = int(rng.uniform(1.0, 3.0) * fs)
    while i < n:
        peak = rng.uniform(5.0, 60.0) * rng.choice([-1.0, 1.0])
        acc = rng.uniform(10.0, 50.0)
        ramp = max(1, int(abs(peak) / acc * fs))
        hold = int(rng.uniform(2.0, 6.0) * fs)
        seg = np.r_[np.linspace(0, peak, ramp, endpoint=False), np.full(hold, peak),
                    np.linspace(peak, 0, ramp, endpoint=False)]
        m = min(seg.size, n - i)
        out[i:i + m] = seg[:m]
        i += seg.size + int(rng.uniform(2.0, 5.0) * fs)
    return out


def car(n, fs, rng):
    """Car yaw: corners (half-cosine pulses of 5-25 deg/s over 2-6 s), lane keeping
    (0-0.5 Hz, 0.5 deg/s RMS) and body/road vibration (8-20 Hz, 0.3 deg/s RMS)."""
    out = _band_noise(n, fs, rng, 0.0, 0.5, 0.5)
    i = int(rng.uniform(1.0, 4.0) * fs)
    while i < n:
        dur = int(rng.uniform(2.0, 6.0) * fs)
        amp = rng.uniform(5.0, 25.0) * rng.choice([-1.0, 1.0])
        pulse = amp * 0.5 * (1 - np.cos(2 * np.pi * np.arange(dur) / dur))
        m = min(dur, n - i)
        out[i:i + m] += pulse[:m]
        i += dur + int(rng.uniform(2.0, 8.0) * fs)
    return out + _band_noise(n, fs, rng, 8.0, min(20.0, 0.45 * fs), 0.3)


def multirotor(n, fs, rng, parts=None):
    """Multirotor: rate commands every 0.3-1.5 s (up to +-90 deg/s) through a 4 Hz,
    zeta 0.7 rate loop, turbulence (0-5 Hz, 5 deg/s RMS) and frame vibration
    80-200 Hz (motor tone near 90 Hz + harmonic; tones above 0.45 fs dropped).
    ``parts`` (a dict), when given, receives the frame vibration as "vibration"."""
    cmd = np.zeros(n)
    i = 0
    while i < n:
        dur = int(rng.uniform(0.3, 1.5) * fs)
        cmd[i:i + dur] = rng.uniform(-90.0, 90.0) * (rng.uniform() < 0.7)
        i += dur
    out = _second_order(cmd, fs, 4.0, 0.7) + _band_noise(n, fs, rng, 0.0, 5.0, 5.0)
    f0 = min(rng.uniform(80.0, 100.0), 0.45 * fs - 5.0)  # below the FOG's 90 Hz limit
    vib = _vibration(n, fs, rng, [(f0, 2.0, 1.5), (2 * f0, 1.0, 3.0), (130.0, 0.7, 5.0)])
    if parts is not None:
        parts["vibration"] = vib
    return out + vib


def ship(n, fs, rng):
    """Ship roll: narrow-band around 0.08-0.12 Hz (resonant, zeta 0.05), 3 deg/s RMS,
    plus slow yaw (0-0.05 Hz, 0.3 deg/s RMS)."""
    f0 = rng.uniform(0.08, 0.12)
    w = _band_noise(n, fs, rng, 0.0, 2.0, 1.0)
    from scipy.signal import bilinear, lfilter
    wn = 2 * np.pi * f0
    b, a = bilinear([2 * 0.05 * wn, 0.0], [1.0, 2 * 0.05 * wn, wn * wn], fs)
    roll = lfilter(b, a, w)
    roll *= 3.0 / max(roll[n // 10:].std(), 1e-12)
    return roll + _band_noise(n, fs, rng, 0.0, 0.05, 0.3)


def pendulum(n, fs, rng):
    """Pendulum: damped 0.5-1 Hz swing, 40-80 deg/s at release, decay 20 s, re-released every 20-30 s."""
    t = np.arange(n) / fs
    out = np.zeros(n)
    f = rng.uniform(0.5, 1.0)
    start = rng.uniform(0.5, 2.0)
    while start < t[-1]:
        m = t >= start
        tt = t[m] - start
        out[m] = rng.uniform(40.0, 80.0) * np.exp(-tt / 20.0) * np.sin(2 * np.pi * f * tt)
        start += rng.uniform(20.0, 30.0)
    return out


def static(n, fs, rng):
    """At rest (the bias ramp is made 5x stronger by :func:`record` for this profile)."""
    return np.zeros(n)


def chirp(n, fs, rng):
    """Logarithmic chirp 0.1 -> 20 Hz (capped at 0.45 fs) over the record, 10 deg/s."""
    t = np.arange(n) / fs
    f1 = min(20.0, 0.45 * fs)
    T = t[-1] if n > 1 else 1.0
    k = math.log(f1 / 0.1) / T
    phase = 2 * np.pi * 0.1 * (np.exp(k * t) - 1.0) / k
    return 10.0 * np.sin(phase + rng.uniform(0, 2 * np.pi))


PROFILES = {"trapezoid": trapezoid, "car": car, "multirotor": multirotor, "ship": ship,
            "pendulum": pendulum, "static_ramp": static, "chirp": chirp}
MOVING = tuple(p for p in PROFILES if p != "static_ramp")
RAMP_GAIN = {"static_ramp": 5.0}
WITH_PARTS = ("multirotor",)   # profiles that hand their frame vibration back (``parts``)


@dataclass
class Record:
    sensor: Sensor
    profile: str
    seed: int
    z: np.ndarray       # gyro output, deg/s
    truth: np.ndarray   # true rate, deg/s
    ref: np.ndarray     # truth + slow sensor errors, deg/s (what a filter should output)
    vibration: np.ndarray = None   # the frame vibration inside truth, deg/s (zeros if none)

    @property
    def sample_rate_hz(self):
        return self.sensor.sample_rate_hz


def record(sensor_key, profile, seed, duration_s, truth=None):
    """Simulate one record. ``truth`` (deg/s) overrides the profile (the gain test)."""
    sensor = SENSORS[sensor_key]
    fs = sensor.sample_rate_hz
    n = int(round(duration_s * fs))
    # one stream per (sensor, profile, seed): independent of evaluation order
    key = [seed, list(SENSORS).index(sensor_key), zlib.crc32(profile.encode())]
    rng = np.random.default_rng(key)
    vib = np.zeros(n)
    if truth is None:
        parts = {}
        truth = (PROFILES[profile](n, fs, rng, parts) if profile in WITH_PARTS
                 else PROFILES[profile](n, fs, rng))
        vib = parts.get("vibration", vib)
        if sensor.vibration_deg_s > 0 and profile in MOVING:   # at rest the motors are off
            tone = _tone(n, fs, rng, sensor.vibration_hz, sensor.vibration_deg_s, 1.0, am=0.3)
            truth = truth + tone
            vib = vib + tone
    truth = np.asarray(truth, dtype=float)
    ref = truth + bias_terms(sensor, n, rng, RAMP_GAIN.get(profile, 1.0))
    z = measure(sensor, ref, rng)
    return Record(sensor, profile, seed, z, truth, ref, vib)
