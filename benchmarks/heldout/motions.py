"""Motion profiles: the true angular rate about the gyro's axis, deg/s, drawn per run.

Every profile is a function ``(rng, t, fs) -> rate``; its amplitudes, frequencies and timings
are drawn inside it from the ranges written there (sources in README.md). Vibration of a frame
(the multirotor's motors, the car's engine and road) is *real motion*: it is part of the truth
a filter should keep.
"""

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.signal import butter, chirp, sosfilt

from benchmarks.heldout.ranges import Range

G = 9.80665
EARTH_RATE_DPS = 15.041 / 3600.0


def _smooth_step(u: np.ndarray) -> np.ndarray:
    """0 before 0, 1 after 1, a raised cosine between."""
    u = np.clip(u, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * u)


def _band_limited(rng, n: int, fs: float, lo_hz: float | None, hi_hz: float, rms: float) -> np.ndarray:
    """Gaussian noise band-limited by a Butterworth (low-pass, or band-pass when ``lo_hz``), of ``rms``."""
    hi_hz = min(hi_hz, 0.45 * fs)
    if lo_hz is None:
        sos = butter(2, hi_hz, btype="low", fs=fs, output="sos")
    else:
        sos = butter(2, [lo_hz, hi_hz], btype="band", fs=fs, output="sos")
    warm = int(min(n, 20 * fs / (lo_hz or hi_hz)))  # let the filter settle before the record starts
    x = sosfilt(sos, rng.normal(size=n + warm))[warm:]
    return x * (rms / max(np.sqrt(np.mean(x * x)), 1e-300))


def rest(rng, t, fs):
    return np.zeros_like(t)


def steps(rng, t, fs):
    T = t[-1]
    n_steps = int(rng.integers(2, 8))
    amp = Range(1.0, 200.0, log=True).draw(rng)
    rise = Range(0.002, 0.05, log=True).draw(rng)  # a rate step through a real rig's torque limit
    times = np.sort(rng.uniform(0.05 * T, 0.95 * T, n_steps))
    levels = rng.uniform(-amp, amp, n_steps)
    rate = np.zeros_like(t)
    previous = 0.0
    for ti, level in zip(times, levels):
        rate += (level - previous) * _smooth_step((t - ti) / rise)
        previous = level
    return rate


def ramps(rng, t, fs):
    T = t[-1]
    n_knots = int(rng.integers(3, 9))
    amp = Range(1.0, 150.0, log=True).draw(rng)
    knots_t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, T, 2 * n_knots)), [T]])
    values = np.zeros(len(knots_t))
    for k in range(1, len(knots_t) - 1, 2):  # a ramp to a new level, then a hold there
        values[k] = values[k - 1]
        values[k + 1] = rng.uniform(-amp, amp)
    values[-1] = values[-2]
    return np.interp(t, knots_t, values)


def sines(rng, t, fs):
    rate = np.zeros_like(t)
    for _ in range(int(rng.integers(1, 4))):
        f = Range(0.05, min(10.0, 0.1 * fs), log=True).draw(rng)
        a = Range(0.5, 100.0, log=True).draw(rng)
        rate += a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    return rate


def chirps(rng, t, fs):
    f0 = Range(0.05, 0.5, log=True).draw(rng)
    f1 = Range(2.0, min(30.0, 0.1 * fs), log=True).draw(rng)
    a = Range(1.0, 50.0, log=True).draw(rng)
    method = "linear" if rng.random() < 0.5 else "logarithmic"
    return a * chirp(t, f0=f0, t1=t[-1], f1=f1, method=method, phi=rng.uniform(0, 360))


def pendulum(rng, t, fs):
    """A damped pendulum released at rest from theta0 after a still start (small-angle law)."""
    length = Range(0.2, 5.0, log=True).draw(rng)
    theta0 = Range(5.0, 60.0).draw(rng)
    zeta = Range(1e-3, 5e-2, log=True).draw(rng)
    release = Range(0.0, 5.0).draw(rng)
    w = np.sqrt(G / length)
    wd = w * np.sqrt(1 - zeta ** 2)
    s = np.maximum(t - release, 0.0)
    # d/dt of theta0 e^{-zeta w s} (cos wd s + zeta w / wd sin wd s): starts at rate 0
    rate = -theta0 * np.exp(-zeta * w * s) * (w * w / wd) * np.sin(wd * s)
    return np.where(t >= release, rate, 0.0)


def ship(rng, t, fs):
    """Roll of a ship in a seaway: a narrow band around the roll period, plus slow yaw."""
    period = Range(5.0, 20.0).draw(rng)
    roll_rms_deg = Range(0.5, 10.0, log=True).draw(rng)
    fr = 1.0 / period
    freqs = fr * rng.uniform(0.8, 1.2, 30)
    amps = rng.rayleigh(1.0, 30)
    rate = (amps[:, None] * np.cos(2 * np.pi * freqs[:, None] * t + rng.uniform(0, 2 * np.pi, 30)[:, None])).sum(0)
    rate *= 2 * np.pi * fr * roll_rms_deg / np.sqrt(np.mean(rate ** 2))
    yaw = Range(0.05, 1.0, log=True).draw(rng) * np.sin(2 * np.pi * t / Range(30.0, 120.0).draw(rng))
    return rate + yaw


def car(rng, t, fs):
    """Yaw of a car: turns (bell-shaped yaw rate), the road's rumble and the engine's vibration."""
    T = t[-1]
    rate = np.zeros_like(t)
    start = Range(0.0, 5.0).draw(rng)
    while start < T:
        duration = Range(2.0, 8.0).draw(rng)
        peak = Range(5.0, 40.0).draw_signed(rng)
        u = (t - start) / duration
        rate += np.where((u >= 0) & (u <= 1), peak * np.sin(np.pi * np.clip(u, 0, 1)) ** 2, 0.0)
        start += duration + Range(1.0, 8.0).draw(rng)
    rate += _band_limited(rng, len(t), fs, 1.0, 15.0, Range(0.05, 1.0, log=True).draw(rng))
    engine_hz = Range(20.0, 100.0).draw(rng)
    if engine_hz < 0.4 * fs:
        rate += Range(0.02, 0.5, log=True).draw(rng) * np.sin(2 * np.pi * engine_hz * t + rng.uniform(0, 2 * np.pi))
    return rate


def multirotor(rng, t, fs):
    """Attitude control of a multirotor, and its frame's vibration at the motors' rotation rate."""
    rate = _band_limited(rng, len(t), fs, None, Range(1.0, 5.0).draw(rng), Range(2.0, 50.0, log=True).draw(rng))
    fv = Range(60.0, 200.0).draw(rng)
    wobble = 1.0 + 0.1 * np.sin(2 * np.pi * t / Range(2.0, 10.0).draw(rng))  # throttle changes
    phase = 2 * np.pi * np.cumsum(fv * wobble) / fs
    amp = Range(0.5, 10.0, log=True).draw(rng)
    rate += amp * np.sin(phase)
    if 2 * fv * 1.1 < 0.45 * fs:
        rate += amp * Range(0.1, 0.5).draw(rng) * np.sin(2 * phase + rng.uniform(0, 2 * np.pi))
    return rate


def manoeuvres(rng, t, fs):
    """Random manoeuvres: band-limited Gaussian rate with a random corner, plus a few steps."""
    corner = Range(0.1, 5.0, log=True).draw(rng)
    rate = _band_limited(rng, len(t), fs, None, corner, Range(1.0, 100.0, log=True).draw(rng))
    return rate + steps(rng, t, fs) * float(rng.random() < 0.5)


@dataclass(frozen=True)
class Profile:
    name: str
    rate: Callable[[np.random.Generator, np.ndarray, float], np.ndarray]
    min_rate_hz: float = 0.0  # the lowest sample rate this motion is sampled at (its vibration)
    weight: float = 1.0  # how often it is drawn, relative to the others
    at_rest: bool = False


PROFILES = (
    Profile("rest", rest, weight=2.0, at_rest=True),
    Profile("steps", steps),
    Profile("ramps", ramps),
    Profile("sines", sines),
    Profile("chirp", chirps),
    Profile("pendulum", pendulum),
    Profile("ship", ship),
    Profile("car", car),
    Profile("multirotor", multirotor, min_rate_hz=1000.0),
    Profile("manoeuvres", manoeuvres),
)
PROFILE_BY_NAME = {p.name: p for p in PROFILES}


def draw_profile(rng: np.random.Generator) -> Profile:
    w = np.array([p.weight for p in PROFILES])
    return PROFILES[int(rng.choice(len(PROFILES), p=w / w.sum()))]


def draw_earth_rate(rng: np.random.Generator) -> float:
    """Earth's rotation on the axis: 15.04 deg/h times the cosine of a uniformly drawn direction."""
    return EARTH_RATE_DPS * rng.uniform(-1.0, 1.0)
