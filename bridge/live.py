"""Live links: receive MAVLink, filter the gyro fields sample by sample, forward everything.

Every message received on the input connection is written to the output
connection as soon as it has been handled: gyro messages (RAW_IMU,
SCALED_IMU*, HIGHRES_IMU) re-packed with the filtered values, all others
byte for byte; nothing is buffered, so the added latency is the handling time
of one message (reported as ``handling_us``). Unreadable bytes (pymavlink's
BAD_DATA) are forwarded unchanged too, and counted.

Each stream (message type, system, component, instance) and axis has its own
:class:`gyrodenoise.Denoiser`, stepped once per sample with the restart flag of
:class:`bridge.streams.RestartDetector` (same rules as for files). The filter's
sample rate (which only sets the warm-up length) is ``sample_rate`` when given,
else the rate of the first two samples; the denoiser is created at the second
sample and fed the first one then: this gives the same output as creating it
at the first sample (the first sample of a warm-up is passed through raw).
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

from .streams import UNIT_TO_DEG_S, GyroStream, RestartDetector, measured_rate_hz
from .tlog import AUTOPILOT_ARDUPILOT, GYRO_FIELDS, GYRO_MESSAGES, _AP_VERSION_RE, _raw_imu_unit, repack


class _LiveStream:
    def __init__(self, name, message, unit, to_deg, note, gap_factor):
        self.name, self.message, self.unit, self.to_deg, self.note = name, message, unit, to_deg, note
        self.det = RestartDetector(gap_factor)
        self.den = None
        self.t, self.x, self.f, self.r = [], [], [], []
        self.events = []
        self.rate = None
        self.non_finite = [0, 0, 0]
        self.pending_restart = [False, False, False]

    def step(self, t, raw, sample_rate, method, ar_order, warmup_s=None, filter_kw=None):
        from gyrodenoise.denoiser import Denoiser
        reason = self.det.update(t)
        i = len(self.t)
        if reason:
            self.events.append({"stream": self.name, "sample": i, "time_s": t,
                                "previous_time_s": self.t[-1], "reason": reason})
        k = self.to_deg if self.to_deg is not None else 1.0
        z = [float(v) * k for v in raw]
        if i == 0:
            out = z                                   # first sample of a warm-up: raw
        else:
            if self.den is None:
                if sample_rate:
                    rate = float(sample_rate)
                else:
                    dt = t - self.t[0]
                    rate = 1.0 / dt if dt > 0 else 50.0
                self.rate = rate
                kw = {} if warmup_s is None else {"warmup_s": float(warmup_s)}
                kw.update(filter_kw or {})
                self.den = [Denoiser(sample_rate_hz=rate, method=method, ar_order=ar_order, **kw)
                            for _ in range(3)]
                for j, (d, z0) in enumerate(zip(self.den, self.x[0])):
                    if math.isfinite(z0):
                        d.step(z0, False)
                    else:
                        self.non_finite[j] += 1
            out = []
            for j, (d, zz) in enumerate(zip(self.den, z)):
                if math.isfinite(zz):
                    out.append(d.step(zz, bool(reason) or self.pending_restart[j]))
                    self.pending_restart[j] = False
                else:                             # never fed to the filter; kept as it is
                    self.non_finite[j] += 1
                    self.pending_restart[j] = self.pending_restart[j] or bool(reason)
                    out.append(zz)
        self.t.append(t)
        self.x.append(z)
        self.f.append(out)
        self.r.append(bool(reason))
        return [v / k for v in out]

    def as_stream(self):
        n = len(self.t)
        s = GyroStream(name=self.name, message=self.message, unit=self.unit, to_deg_s=self.to_deg,
                       time_s=np.asarray(self.t), raw=np.asarray(self.x).reshape(n, 3) / (self.to_deg or 1.0),
                       index=np.arange(n), note=self.note)
        s.restarts = np.asarray(self.r, dtype=bool)
        s.restart_events = self.events
        s.repeated_timestamps = self.det.repeated
        s.rate_hz = measured_rate_hz(s.time_s, s.restarts)
        x = np.asarray(self.x, dtype=np.float64).reshape(n, 3)
        f = np.asarray(self.f, dtype=np.float64).reshape(n, 3)
        s.filtered = f / (self.to_deg or 1.0)
        s._work = (x, f, "deg/s" if self.to_deg is not None else self.unit, self.rate or 0.0)
        s.non_finite = list(self.non_finite)
        return s


def _enlarge_receive_buffer(conn, size=4 << 20):
    """Ask for a larger UDP receive buffer (bursts while the process is descheduled)."""
    import socket
    sock = getattr(conn, "port", None)
    if isinstance(sock, socket.socket) and sock.type == socket.SOCK_DGRAM:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
        except OSError:
            pass


def run_live(source, forward, *, duration=None, max_messages=None, method="shakf", ar_order=3,
             gap_factor=5.0, sample_rate=None, raw_imu_unit="auto", raw_imu_scale=None, log=None,
             warmup_s=None, filter_kw=None):
    """Bridge ``source`` to ``forward`` (pymavlink connection strings) until
    ``duration`` seconds have passed or ``max_messages`` messages were
    forwarded (or Ctrl-C). Returns (report dict, list of GyroStream)."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil
    mavutil.set_dialect("ardupilotmega")
    from gyrodenoise.errors import InputError
    try:
        src = mavutil.mavlink_connection(source, robust_parsing=True)
    except Exception as exc:  # noqa: BLE001 - socket/serial errors of many kinds
        raise InputError(f"{source}: cannot open the input link ({type(exc).__name__}: {exc})") from None
    _enlarge_receive_buffer(src)
    try:
        dst = mavutil.mavlink_connection(forward) if forward else None
    except Exception as exc:  # noqa: BLE001
        src.close()
        raise InputError(f"{forward}: cannot open the output link ({type(exc).__name__}: {exc})") from None
    if log:
        log(f"listening on {source}, forwarding to {forward or '(nowhere)'}")
    streams = {}
    vehicles = {}
    n_in = n_out = n_bad = n_sig = 0
    handle_ns = []
    t_start = time.monotonic()
    deadline = t_start + duration if duration else None
    stopped_by = "interrupt"
    try:
        while True:
            if max_messages is not None and n_in >= max_messages:
                stopped_by = "count"
                break
            timeout = 0.2
            if deadline is not None:
                timeout = deadline - time.monotonic()
                if timeout <= 0:
                    stopped_by = "duration"
                    break
                timeout = min(timeout, 0.2)
            msg = src.recv_match(blocking=True, timeout=timeout)
            if msg is None:
                continue
            h0 = time.perf_counter_ns()
            n_in += 1
            mtype = msg.get_type()
            if mtype == "BAD_DATA":
                n_bad += 1
                out = bytes(msg.data) if getattr(msg, "data", None) is not None else b""
            else:
                out = msg.get_msgbuf()
                sysid = msg.get_srcSystem()
                if mtype == "HEARTBEAT":
                    vehicles.setdefault(sysid, {"autopilots": set(), "ap_version": False})["autopilots"].add(msg.autopilot)
                elif mtype == "STATUSTEXT" and _AP_VERSION_RE.search(msg.text or ""):
                    vehicles.setdefault(sysid, {"autopilots": set(), "ap_version": False})["ap_version"] = True
                elif mtype in GYRO_MESSAGES:
                    inst = msg.id if "id" in msg.get_fieldnames() else 0
                    key = (sysid, msg.get_srcComponent(), mtype, inst)
                    st = streams.get(key)
                    if st is None:
                        tfield, tscale, unit = GYRO_MESSAGES[mtype]
                        if unit == "raw":
                            v2 = bytes(out[:1]) == b"\xfd"
                            unit, to_deg, note = _raw_imu_unit(vehicles.get(sysid), v2, raw_imu_unit, raw_imu_scale)
                        else:
                            to_deg, note = UNIT_TO_DEG_S[unit], ""
                        name = f"{mtype}" + (f"[{inst}]" if inst else "") + f"@{key[0]}.{key[1]}"
                        st = streams[key] = _LiveStream(name, mtype, unit, to_deg, note, gap_factor)
                        st.tscale, st.tfield = tscale, tfield
                    vals = st.step(getattr(msg, st.tfield) * st.tscale,
                                   [getattr(msg, g) for g in GYRO_FIELDS], sample_rate, method, ar_order,
                                   warmup_s, filter_kw)
                    out, dropped = repack(bytes(out), mtype, vals)
                    n_sig += dropped
            if dst is not None and out:
                dst.write(out)
                n_out += 1
            handle_ns.append(time.perf_counter_ns() - h0)
    except KeyboardInterrupt:
        stopped_by = "interrupt"
    finally:
        src.close()
        if dst is not None:
            dst.close()
    hs = np.asarray(handle_ns, dtype=np.float64) / 1000.0
    gs = [st.as_stream() for st in streams.values()]
    report = {
        "mode": "live", "input": source, "forward": forward, "stopped_by": stopped_by,
        "seconds": round(time.monotonic() - t_start, 3), "messages_in": n_in,
        "messages_forwarded": n_out, "unreadable_records": n_bad, "signatures_dropped": n_sig,
        "handling_us": {"mean": float(hs.mean()) if len(hs) else None,
                        "p99": float(np.percentile(hs, 99)) if len(hs) else None,
                        "max": float(hs.max()) if len(hs) else None},
        "method": method, "ar_order": int(ar_order), "gap_factor": gap_factor, "warmup_s": warmup_s,
        "filter_options": dict(filter_kw or {}),
    }
    return report, gs
