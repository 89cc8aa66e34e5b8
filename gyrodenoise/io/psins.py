"""Reading a PSINS-format strapdown IMU log (``*.imu``, the PSINS toolbox's text format).

Layout (PSINS toolbox, G. Yan; comment lines start with ``%``):

* line 1: initial pitch, roll, yaw (deg), VE, VN, VU (m/s);
* line 2: latitude (deg), longitude (deg), height (m), t0 (s), sampling interval (ms), g (m/s^2);
* line 3: scale factors: gyro x y z (arcsec per pulse), accelerometer x y z (micro-g s per pulse);
* then one row per sample: gyro x y z pulse counts, accelerometer x y z pulse counts (integers).

A gyro's rate is ``pulses * scale / interval``: ``pulses * 0.1 arcsec / 10 ms`` for the
ring-laser gyro of ``psins_lasergyro.imu``, so its quantum is 0.1 arcsec of angle.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from gyrodenoise.errors import InputError

AXES = ("gyro_x", "gyro_y", "gyro_z")


@dataclass
class PsinsLog:
    """The gyro part of a PSINS log (rates in deg/s)."""
    rate_deg_s: np.ndarray          # (n, 3): x, y, z
    sample_rate_hz: float
    latitude_deg: float
    quantum_deg: np.ndarray         # angle per pulse, per axis (deg)
    source: str

    def axis(self, name: str) -> np.ndarray:
        """One axis by column name (``gyro_x``, ``gyro_y``, ``gyro_z``)."""
        if name not in AXES:
            raise InputError(f"no column '{name}' in a PSINS log (columns: {', '.join(AXES)}); "
                             f"use --rate-column", self.source)
        return self.rate_deg_s[:, AXES.index(name)]


def _numbers(line: str, lineno: int, source: str, want: int) -> list[float]:
    try:
        vals = [float(v) for v in line.split()]
    except ValueError:
        raise InputError(f"line {lineno}: expected {want} numbers, got {line.strip()[:60]!r}", source) from None
    if len(vals) < want or not all(math.isfinite(v) for v in vals[:want]):
        raise InputError(f"line {lineno}: expected {want} finite numbers, got {len(vals)}", source)
    return vals


def read_psins(path: str | os.PathLike[str]) -> PsinsLog:
    """Read the gyro channels of a PSINS ``.imu`` log (see the module docstring)."""
    src = str(path)
    try:
        with open(path, encoding="ascii", errors="replace") as fh:
            lines = [(i + 1, ln) for i, ln in enumerate(fh) if ln.strip() and not ln.lstrip().startswith("%")]
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", src) from None
    if len(lines) < 4:
        raise InputError("not a PSINS log: fewer than 3 header lines and one sample", src)
    _numbers(lines[0][1], lines[0][0], src, 6)
    lat, _, _, _, dt_ms, _ = _numbers(lines[1][1], lines[1][0], src, 6)[:6]
    scale = _numbers(lines[2][1], lines[2][0], src, 6)[:3]
    if not dt_ms > 0 or not all(s > 0 for s in scale):
        raise InputError("line 2/3: the sampling interval and the gyro scale factors must be positive", src)
    try:
        data = np.loadtxt([ln for _, ln in lines[3:]], ndmin=2)
    except ValueError as exc:
        raise InputError(f"samples: not a table of numbers ({' '.join(str(exc).split())[:80]})", src) from None
    if data.shape[1] < 3:
        raise InputError(f"samples: expected 6 columns, got {data.shape[1]}", src)
    q_deg = np.asarray(scale, float) / 3600.0          # arcsec per pulse -> deg per pulse
    fs = 1000.0 / dt_ms
    return PsinsLog(rate_deg_s=data[:, :3] * q_deg * fs, sample_rate_hz=fs, latitude_deg=float(lat),
                    quantum_deg=q_deg, source=src)
