"""References of the MAVLink bridge tests, independent of the bridge: pymavlink's own
reading of the raw fields, a whole-stream restart rule written here, the core's batch
denoiser (``gyrodenoise.denoise``) on those samples; and the bridge run as a program."""
from __future__ import annotations

import functools
import math
import subprocess

import numpy as np

import gyrodenoise as gd
from gyrodenoise.core.kernels import DEFAULT_METHOD
from gyrodenoise.flightlog import tlog
from tests.helpers import gyrodenoise_cmd

R2D = 180.0 / math.pi


def run_cli(*args, timeout=120):
    return subprocess.run(gyrodenoise_cmd() + ["mavlink", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def ref_restarts(t, factor=5.0):
    """Independent rule: time backwards, or a step over factor x the median step of the
    stream (the first step has nothing before it to be compared with, in a file as on a
    live link: it is only judged on its sign)."""
    dt = np.diff(np.asarray(t, dtype=float))
    med = np.median(dt[dt > 0])
    r = np.zeros(len(t), dtype=bool)
    r[1:] = (dt < 0) | (dt > factor * med)
    if len(t) > 1:
        r[1] = dt[0] < 0
    return r


@functools.lru_cache(maxsize=8)
def df_reference(path):
    """pymavlink's DFReader: {stream: (time_s, gyro rad/s (n,3))} and all messages."""
    from pymavlink import DFReader
    r = DFReader.DFReader_binary(str(path))
    streams, msgs = {}, []
    while True:
        m = r.recv_msg()
        if m is None:
            break
        d = m.to_dict()
        msgs.append(d)
        t = m.get_type()
        if t in ("IMU", "IMU2", "IMU3"):
            name = f"{t}[{m.I}]" if "I" in m.get_fieldnames() else t
            ts = m.TimeUS * 1e-6 if "TimeUS" in d else m.TimeMS * 1e-3
            streams.setdefault(name, []).append((ts, m.GyrX, m.GyrY, m.GyrZ))
    return {k: (np.array(v)[:, 0], np.array(v)[:, 1:]) for k, v in streams.items()}, msgs


@functools.lru_cache(maxsize=8)
def tlog_reference(path):
    """pymavlink's reading of a tlog: gyro streams {type: (time_s, (n,3))}, all messages, BAD_DATA count."""
    from pymavlink import mavutil
    m = mavutil.mavlink_connection(str(path), robust_parsing=True)
    streams, msgs, bad = {}, [], 0
    while True:
        msg = m.recv_match()
        if msg is None:
            break
        t = msg.get_type()
        if t == "BAD_DATA":
            bad += 1
            continue
        msgs.append(msg.to_dict())
        if t in tlog.GYRO_MESSAGES:
            ts = msg.time_usec * 1e-6 if t in ("RAW_IMU", "HIGHRES_IMU") else msg.time_boot_ms * 1e-3
            streams.setdefault(t, []).append((ts, msg.xgyro, msg.ygyro, msg.zgyro))
    m.close()
    return {k: (np.array(v)[:, 0], np.array(v)[:, 1:]) for k, v in streams.items()}, msgs, bad


def ref_filter(raw_deg, rate, restarts, method=None, order=3, causal=False):
    """What the bridge's file mode gives: the core's default method, in its offline
    form on a whole log (``motion``), or the causal filter (``causal=True``, --causal)."""
    method = method or DEFAULT_METHOD          # the bridge's default is the core's
    offline = method == "motion" and not causal
    return np.stack([gd.denoise(raw_deg[:, k], rate, method=method, ar_order=order, restarts=restarts,
                                offline=offline) for k in range(raw_deg.shape[1])], axis=1)


def by_name(rep):
    return {s["name"]: s for s in rep["streams"]}
