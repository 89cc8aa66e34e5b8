"""Gyro grades with their published ranges, one sensor drawn per run, and its error simulated.

Units: rates in deg/s; angle random walk (ARW) in deg/sqrt(h); bias instability (BI) in
deg/h; rate random walk (RRW) in deg/h/sqrt(h). The sources of every range are in README.md.

The error of a drawn sensor is, in this order:

* white rate noise of density ARW (the angle random walk);
* three first-order Gauss-Markov biases with correlation times 1, 10 and 100 s, whose
  standard deviations are the bias instability times a factor drawn in 0.5..1.5 each (a sum of
  Gauss-Markov processes standing in for the flicker floor of the Allan deviation);
* a rate random walk;
* a residual turn-on bias (constant over the run);
* a warm-up ramp b_w (1 - exp(-t / tau_w)), most of it within the first minute;

then the sum of the true rate and the error saturates at the full scale and is quantised to
the least significant bit (LSB).
"""

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from benchmarks.heldout.ranges import Range

GM_TAUS_S = (1.0, 10.0, 100.0)
GM_FACTOR = Range(0.5, 1.5, log=True)
WARMUP_TAU_S = Range(8.0, 25.0)


@dataclass(frozen=True)
class Grade:
    """A class of gyro and the ranges its parameters are drawn from."""

    name: str
    arw_deg_rt_h: Range
    bi_deg_h: Range
    rrw_deg_h_rt_h: Range
    lsb_dps: Range
    full_scale_dps: Range
    turn_on_bias_dps: Range  # magnitude of the residual after the start-up calibration
    warmup_dps: Range  # magnitude of the warm-up ramp's end value
    sample_rate_hz: Range


GRADES = (
    Grade("consumer_mems",
          arw_deg_rt_h=Range(0.17, 0.9, log=True),       # 0.0028..0.015 deg/s/sqrt(Hz)
          bi_deg_h=Range(2.0, 30.0, log=True),
          rrw_deg_h_rt_h=Range(2.0, 40.0, log=True),
          lsb_dps=Range(250 / 32768, 2000 / 32768, log=True),  # 16 bit at +-250..+-2000 deg/s
          full_scale_dps=Range(250.0, 2000.0, log=True),
          turn_on_bias_dps=Range(0.0, 0.05),
          warmup_dps=Range(0.005, 0.06, log=True),
          sample_rate_hz=Range(100.0, 8000.0, log=True)),
    Grade("tactical_mems",
          arw_deg_rt_h=Range(0.09, 0.34, log=True),
          bi_deg_h=Range(0.3, 8.0, log=True),
          rrw_deg_h_rt_h=Range(0.3, 10.0, log=True),
          lsb_dps=Range(5e-5, 0.01, log=True),
          full_scale_dps=Range(400.0, 2000.0, log=True),
          turn_on_bias_dps=Range(0.0, 0.01),
          warmup_dps=Range(0.002, 0.02, log=True),
          sample_rate_hz=Range(100.0, 4000.0, log=True)),
    Grade("tactical_fog",
          arw_deg_rt_h=Range(0.012, 0.07, log=True),
          bi_deg_h=Range(0.05, 1.0, log=True),
          rrw_deg_h_rt_h=Range(0.01, 0.5, log=True),
          lsb_dps=Range(1e-6, 1e-4, log=True),
          full_scale_dps=Range(490.0, 1000.0),
          turn_on_bias_dps=Range(0.0, 5e-4),
          warmup_dps=Range(1e-5, 2e-4, log=True),
          sample_rate_hz=Range(100.0, 1000.0, log=True)),
    Grade("navigation_fog",
          arw_deg_rt_h=Range(0.0005, 0.005, log=True),
          bi_deg_h=Range(0.001, 0.01, log=True),
          rrw_deg_h_rt_h=Range(0.0005, 0.01, log=True),
          lsb_dps=Range(1e-7, 1e-5, log=True),
          full_scale_dps=Range(490.0, 1000.0),
          turn_on_bias_dps=Range(0.0, 3e-5),
          warmup_dps=Range(1e-6, 3e-5, log=True),
          sample_rate_hz=Range(100.0, 1000.0, log=True)),
)
GRADE_BY_NAME = {g.name: g for g in GRADES}


@dataclass(frozen=True)
class Sensor:
    """One drawn sensor: the parameters of a run's gyro."""

    grade: str
    sample_rate_hz: float
    arw_deg_rt_h: float
    bi_deg_h: float
    gm_sigma_dps: tuple[float, float, float]
    rrw_deg_h_rt_h: float
    lsb_dps: float
    full_scale_dps: float
    turn_on_bias_dps: float
    warmup_dps: float
    warmup_tau_s: float

    @property
    def white_density_dps_rt_hz(self) -> float:
        return self.arw_deg_rt_h / 60.0

    @property
    def rrw_dps_per_rt_s(self) -> float:
        return self.rrw_deg_h_rt_h / 3600.0 / 60.0


def draw_sensor(rng: np.random.Generator, grade: Grade, min_rate_hz: float = 0.0) -> Sensor:
    """Draw a sensor of ``grade``; its sample rate at least ``min_rate_hz`` (within the grade's)."""
    bi = grade.bi_deg_h.draw(rng)
    rate_range = Range(max(grade.sample_rate_hz.lo, min_rate_hz), grade.sample_rate_hz.hi, log=True)
    return Sensor(
        grade=grade.name,
        sample_rate_hz=round(rate_range.draw(rng)),
        arw_deg_rt_h=grade.arw_deg_rt_h.draw(rng),
        bi_deg_h=bi,
        gm_sigma_dps=tuple(bi / 3600.0 * GM_FACTOR.draw(rng) for _ in GM_TAUS_S),
        rrw_deg_h_rt_h=grade.rrw_deg_h_rt_h.draw(rng),
        lsb_dps=grade.lsb_dps.draw(rng),
        full_scale_dps=grade.full_scale_dps.draw(rng),
        turn_on_bias_dps=grade.turn_on_bias_dps.draw_signed(rng),
        warmup_dps=grade.warmup_dps.draw_signed(rng),
        warmup_tau_s=WARMUP_TAU_S.draw(rng),
    )


def white_noise(sensor: Sensor, n: int, rng: np.random.Generator) -> np.ndarray:
    """The angle random walk: white rate noise, deg/s."""
    return rng.normal(0.0, sensor.white_density_dps_rt_hz * np.sqrt(sensor.sample_rate_hz), n)


def gauss_markov(sigma: float, tau_s: float, fs: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """A stationary first-order Gauss-Markov process of standard deviation ``sigma``."""
    a = np.exp(-1.0 / (tau_s * fs))
    drive = rng.normal(0.0, sigma * np.sqrt(1.0 - a * a), n)
    x0 = rng.normal(0.0, sigma)
    return lfilter([1.0], [1.0, -a], drive, zi=[a * x0])[0]


def stochastic_error(sensor: Sensor, n: int, rng: np.random.Generator) -> np.ndarray:
    """White noise + Gauss-Markov biases + rate random walk, deg/s (no deterministic terms)."""
    fs = sensor.sample_rate_hz
    err = white_noise(sensor, n, rng)
    for sigma, tau in zip(sensor.gm_sigma_dps, GM_TAUS_S):
        err += gauss_markov(sigma, tau, fs, n, rng)
    err += np.cumsum(rng.normal(0.0, sensor.rrw_dps_per_rt_s / np.sqrt(fs), n))
    return err


def deterministic_bias(sensor: Sensor, n: int) -> np.ndarray:
    """Turn-on bias + warm-up ramp, deg/s."""
    t = np.arange(n) / sensor.sample_rate_hz
    return sensor.turn_on_bias_dps + sensor.warmup_dps * (1.0 - np.exp(-t / sensor.warmup_tau_s))


def measure(sensor: Sensor, truth_dps: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """What the gyro outputs for the true rate ``truth_dps``: error added, saturated, quantised."""
    n = len(truth_dps)
    raw = truth_dps + stochastic_error(sensor, n, rng) + deterministic_bias(sensor, n)
    raw = np.clip(raw, -sensor.full_scale_dps, sensor.full_scale_dps)
    return np.round(raw / sensor.lsb_dps) * sensor.lsb_dps


def analytic_avar(sensor: Sensor, tau_s: float) -> float:
    """Allan variance of :func:`stochastic_error` at ``tau_s`` (deg/s)^2, from its terms."""
    avar = sensor.white_density_dps_rt_hz ** 2 / tau_s
    for sigma, tc in zip(sensor.gm_sigma_dps, GM_TAUS_S):
        x = tau_s / tc
        avar += 2.0 * sigma ** 2 / x * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))
    avar += sensor.rrw_dps_per_rt_s ** 2 * tau_s / 3.0
    return float(avar)
