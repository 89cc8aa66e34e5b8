"""The offline form of ``method="motion"`` (batch.smooth_motion) near sharp steps and on real
vibration that exceeds the noise: never worse than the raw samples.

Before the break test and the smoother's pass-through (the held-out benchmark's independent simulator (benchmarks/heldout)), a
10 deg/s step in a navigation FOG's noise (sd 1e-4) made the output alternate between 0 and
0.1-0.19 deg/s over the samples before the step (the backward bank's fastest filter rings after
the step, every slower filter restarts from it, and the two-filter combination of the least
implausible model kept the ringing): 82x raw's RMSE."""

import numpy as np
import pytest

import gyrodenoise as gd


def _rmse(y, truth):
    return float(np.sqrt(np.mean((y - truth) ** 2)))


def test_a_sharp_step_in_a_quiet_gyro_does_not_alternate():
    """100 Hz, 10 deg/s step at sample 2000, noise sd 1e-4 (the benchmark's minimal repro): the
    samples before the step stay within 5 sigma of the truth, and the RMSE is at most raw's."""
    rng = np.random.default_rng(0)
    truth = np.where(np.arange(4000) >= 2000, 10.0, 0.0)
    raw = truth + 1e-4 * rng.standard_normal(truth.size)
    y = gd.denoise(raw, 100.0, offline=True)
    assert np.abs(y[1990:2000] - truth[1990:2000]).max() < 5e-4
    assert np.abs(y[2000:2010] - truth[2000:2010]).max() < 5e-4
    assert _rmse(y, truth) <= _rmse(raw, truth)


def _steps(rng, t):
    levels = rng.uniform(-30.0, 30.0, 6)
    return levels[np.minimum((t / t[-1] * 6).astype(int), 5)]


def _ramps(rng, t):
    knots = np.linspace(0.0, t[-1], 7)
    return np.interp(t, knots, rng.uniform(-20.0, 20.0, knots.size))


def _vibration(rng, t):
    """A slow manoeuvre plus frame vibration (10-40 % of the Nyquist band, 0.1 deg/s rms):
    real motion, far above a FOG's noise."""
    fs = 1.0 / (t[1] - t[0])
    spec = np.fft.rfft(rng.standard_normal(t.size))
    f = np.fft.rfftfreq(t.size, 1.0 / fs)
    spec[(f < 0.1 * fs) | (f > 0.4 * fs)] = 0.0
    vib = np.fft.irfft(spec, t.size)
    return 5.0 * np.sin(2.0 * np.pi * 0.2 * t) + 0.1 * vib / vib.std()


def _offline_over_raw(motion, fs, noise):
    rng = np.random.default_rng([int(fs), int(-np.log10(noise) * 10)])
    t = np.arange(int(20 * fs)) / fs
    truth = motion(rng, t)
    raw = truth + noise * rng.standard_normal(t.size)
    return _rmse(gd.denoise(raw, fs, offline=True), truth) / _rmse(raw, truth)


CASES = [(m, fs, noise) for m in (_steps, _ramps) for fs in (100.0, 400.0) for noise in (1e-4, 1e-3, 3e-2)]
CASES += [(_vibration, fs, noise) for fs in (100.0, 400.0) for noise in (1e-4, 1e-3)]


@pytest.mark.parametrize("motion, fs, noise", CASES)
def test_offline_is_never_worse_than_raw(motion, fs, noise):
    """Seeded step, ramp and vibration records, 20 s, from a navigation FOG's noise to a MEMS's
    (the vibration 100-1000x the noise, as on the benchmark's FOG car records): the offline
    RMSE is at most raw's x 1.005."""
    assert _offline_over_raw(motion, fs, noise) <= 1.005


@pytest.mark.xfail(strict=True, reason="open: vibration 3x the noise, broad over 20-80 % of the Nyquist band, "
                   "is averaged as noise (offline 2.3-2.5x raw's RMSE; the causal form 2.0-2.7x)")
@pytest.mark.parametrize("fs", [100.0, 400.0])
def test_offline_on_vibration_a_few_times_the_noise(fs):
    assert _offline_over_raw(_vibration, fs, 3e-2) <= 1.005
