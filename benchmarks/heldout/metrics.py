"""What a filtered record is judged by, against the truth."""

import numpy as np


def rmse(estimate: np.ndarray, truth: np.ndarray) -> float:
    return float(np.sqrt(np.mean((estimate - truth) ** 2)))


def angle_error_rms(estimate: np.ndarray, truth: np.ndarray, fs: float, window_s: float) -> float:
    """RMS over all (sliding) windows of ``window_s`` of the integrated rate error, deg."""
    m = max(1, int(round(window_s * fs)))
    angle = np.concatenate([[0.0], np.cumsum(estimate - truth)]) / fs
    d = angle[m:] - angle[:-m]
    return float(np.sqrt(np.mean(d * d)))
