"""A run of the benchmark is a seed: the seed draws the motion, the sensor, the record's length,
the truth and the raw record. The seeds are split once, here:

* ``dev``: seeds 0..99, the development set: look at these while designing a filter;
* ``heldout``: seeds 1000..1099, the held-out set: the goal lines are judged on these, and no
  design decision looks at them.
"""

from dataclasses import dataclass

import numpy as np

from benchmarks.heldout.motions import Profile, draw_earth_rate, draw_profile
from benchmarks.heldout.ranges import Range
from benchmarks.heldout.sensors import GRADES, Sensor, draw_sensor, measure

SEED_SETS = {"dev": range(0, 100), "heldout": range(1000, 1100)}
DURATION_S = Range(20.0, 60.0)
MAX_SAMPLES = 160_000  # caps the record at high sample rates (8 kHz: 20 s)


@dataclass(frozen=True)
class Case:
    seed: int
    profile: Profile
    sensor: Sensor
    earth_rate_dps: float
    truth: np.ndarray  # deg/s, Earth's rate included
    raw: np.ndarray  # deg/s, what the gyro outputs

    @property
    def fs(self) -> float:
        return self.sensor.sample_rate_hz

    @property
    def duration_s(self) -> float:
        return len(self.raw) / self.fs

    def label(self) -> str:
        return f"{self.seed}:{self.sensor.grade}/{self.profile.name}@{self.fs:g}Hz"


def make_case(seed: int) -> Case:
    """The run of ``seed`` (deterministic: the same seed gives the same arrays)."""
    rng = np.random.default_rng([seed, 42])
    profile = draw_profile(rng)
    grades = [g for g in GRADES if g.sample_rate_hz.hi >= profile.min_rate_hz]
    grade = grades[int(rng.integers(len(grades)))]
    sensor = draw_sensor(rng, grade, min_rate_hz=profile.min_rate_hz)
    fs = sensor.sample_rate_hz
    n = min(int(round(DURATION_S.draw(rng) * fs)), MAX_SAMPLES)
    t = np.arange(n) / fs
    earth = draw_earth_rate(rng)
    motion = profile.rate(rng, t, fs)
    peak = np.max(np.abs(motion))
    if peak > 0.8 * sensor.full_scale_dps:  # a motion the sensor was chosen for: within its range
        motion *= 0.8 * sensor.full_scale_dps / peak
    truth = motion + earth
    raw = measure(sensor, truth, rng)
    return Case(seed, profile, sensor, earth, truth, raw)


def seeds_of(set_name: str, n: int) -> list[int]:
    """The first ``n`` seeds of the set ``set_name``."""
    return list(SEED_SETS[set_name])[:n]
