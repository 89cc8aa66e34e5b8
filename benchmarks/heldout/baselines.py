"""Baseline filters, each tuned per run on the truth (an oracle: the lowest RMSE over its grid).

* Butterworth low-pass, orders 1-4, on a cutoff grid: causal (``sosfilt``, started in the
  steady state of the first sample) and zero-phase (``sosfiltfilt``, the non-causal line);
* the 1-euro filter (Casiez, Roussel, Vogel, CHI 2012), a grid over min cutoff and beta, the
  derivative cutoff at the paper's 1 Hz;
* a constant-velocity Kalman filter (state: rate and its derivative, white jerk), a grid over
  the ratio q/r (only the ratio shapes the estimate).

Every filter starts from the first sample and its error counts from the first sample on. Both
lines also hold the identity (no filter, the raw record), the limit of every family's widest
setting: a tuned baseline is never worse than raw.
"""

from dataclasses import dataclass
from typing import Callable

import numba
import numpy as np
from scipy.signal import butter, sosfilt, sosfilt_zi, sosfiltfilt

from benchmarks.heldout.metrics import rmse

N_CUTOFFS = 24
ORDERS = (1, 2, 3, 4)


def cutoff_grid(fs: float, n: int = N_CUTOFFS) -> np.ndarray:
    """Cutoffs from 0.05 Hz to 0.45 fs, log-spaced, Hz."""
    return np.geomspace(0.05, 0.45 * fs, n)


def butterworth_causal(x: np.ndarray, fs: float, order: int, cutoff_hz: float) -> np.ndarray:
    sos = butter(order, cutoff_hz, fs=fs, output="sos")
    return sosfilt(sos, x, zi=sosfilt_zi(sos) * x[0])[0]


def butterworth_zero_phase(x: np.ndarray, fs: float, order: int, cutoff_hz: float) -> np.ndarray:
    sos = butter(order, cutoff_hz, fs=fs, output="sos")
    return sosfiltfilt(sos, x)


@numba.njit(cache=True)
def _one_euro(x, fs, min_cutoff, beta, d_cutoff):
    n = len(x)
    y = np.empty(n)
    te = 1.0 / fs
    a_d = 1.0 / (1.0 + 1.0 / (2.0 * np.pi * d_cutoff * te))
    y[0] = x[0]
    dx_hat = 0.0
    for k in range(1, n):
        dx = (x[k] - y[k - 1]) * fs
        dx_hat = dx_hat + a_d * (dx - dx_hat)
        cutoff = min_cutoff + beta * abs(dx_hat)
        a = 1.0 / (1.0 + 1.0 / (2.0 * np.pi * cutoff * te))
        y[k] = y[k - 1] + a * (x[k] - y[k - 1])
    return y


def one_euro(x: np.ndarray, fs: float, min_cutoff: float, beta: float, d_cutoff: float = 1.0) -> np.ndarray:
    """The 1-euro filter; the derivative of the *filtered* signal drives the cutoff (the paper's form)."""
    return _one_euro(np.asarray(x, float), float(fs), float(min_cutoff), float(beta), float(d_cutoff))


@numba.njit(cache=True)
def _cv_kalman(z, dt, q_over_r):
    n = len(z)
    y = np.empty(n)
    # in units of r: Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]], R = 1
    q11 = q_over_r * dt ** 3 / 3.0
    q12 = q_over_r * dt ** 2 / 2.0
    q22 = q_over_r * dt
    x0 = z[0]
    x1 = 0.0
    p00 = 1.0  # the first sample's variance
    p01 = 0.0
    p11 = 1e12  # the derivative unknown
    y[0] = x0
    for k in range(1, n):
        # predict
        x0 = x0 + dt * x1
        a00 = p00 + dt * (2.0 * p01 + dt * p11) + q11
        a01 = p01 + dt * p11 + q12
        a11 = p11 + q22
        # update with z[k], H = [1, 0]
        s = a00 + 1.0
        k0 = a00 / s
        k1 = a01 / s
        innov = z[k] - x0
        x0 = x0 + k0 * innov
        x1 = x1 + k1 * innov
        p00 = (1.0 - k0) * a00
        p01 = (1.0 - k0) * a01
        p11 = a11 - k1 * a01
        y[k] = x0
    return y


def cv_kalman(x: np.ndarray, fs: float, q_over_r: float) -> np.ndarray:
    return _cv_kalman(np.asarray(x, float), 1.0 / float(fs), float(q_over_r))


def kalman_grid(fs: float, n: int = N_CUTOFFS) -> np.ndarray:
    """q/r (1/s^3) whose steady-state bandwidth (q/r / dt)^(1/3) spans the Butterworth cutoffs."""
    w = 2 * np.pi * cutoff_grid(fs, n)
    return w ** 3 / fs


@dataclass(frozen=True)
class Family:
    """A baseline: its name, whether it is causal, its grid for a sample rate, and how it runs."""

    name: str
    causal: bool
    grid: Callable[[float], list[dict]]
    apply: Callable[..., np.ndarray]


def identity(x: np.ndarray, fs: float) -> np.ndarray:
    """No filter: the raw record (the limit of every family's widest setting)."""
    return np.array(x, float)


def butterworth_grid(fs: float) -> list[dict]:
    return [dict(order=o, cutoff_hz=c) for o in ORDERS for c in cutoff_grid(fs)]


IDENTITY = Family("identity", True, lambda fs: [{}], identity)
CAUSAL_FAMILIES = (
    Family("butterworth", True, butterworth_grid, butterworth_causal),
    Family("one_euro", True,
           lambda fs: [dict(min_cutoff=c, beta=b) for c in cutoff_grid(fs, 12)
                       for b in np.concatenate([[0.0], np.geomspace(1e-5, 1.0, 11)])],
           one_euro),
    Family("cv_kalman", True, lambda fs: [dict(q_over_r=q) for q in kalman_grid(fs, 32)], cv_kalman),
    IDENTITY,
)
ZERO_PHASE_FAMILIES = (
    Family("butterworth_filtfilt", False, butterworth_grid, butterworth_zero_phase),
    IDENTITY,
)


@dataclass(frozen=True)
class Tuned:
    family: str
    params: dict
    score: float  # the lowest score on the grid (an RMSE or an angle error against the truth)
    estimate: np.ndarray


Score = Callable[[np.ndarray], float]


def best_tuned_each(families: tuple[Family, ...], raw: np.ndarray, fs: float, scores: list[Score]) -> list[Tuned]:
    """For each score (an oracle: it knows the truth), the member of all ``families``' grids with
    the lowest score on this record; every member runs once and is scored by all."""
    best: list[Tuned | None] = [None] * len(scores)
    for family in families:
        for params in family.grid(fs):
            est = family.apply(raw, fs, **params)
            for i, score in enumerate(scores):
                value = score(est)
                if best[i] is None or value < best[i].score:
                    best[i] = Tuned(family.name, params, value, est)
    return best


def best_tuned(families: tuple[Family, ...], raw: np.ndarray, truth: np.ndarray, fs: float) -> Tuned:
    """The member of all ``families`` with the lowest RMSE on this record (``CAUSAL_FAMILIES``, ...)."""
    return best_tuned_each(families, raw, fs, [lambda est: rmse(est, truth)])[0]
