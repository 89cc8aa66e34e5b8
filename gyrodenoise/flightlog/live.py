"""Live links: receive MAVLink, filter the gyro fields sample by sample, forward everything.

Every message received on the input connection is written to the output
connection as soon as it has been handled: gyro messages (RAW_IMU,
SCALED_IMU*, HIGHRES_IMU) re-packed with the filtered values, all others
byte for byte; the added latency is the handling time of one message (reported
as ``handling_us``). Unreadable bytes (a bad CRC, an unknown message id, bytes
that do not frame) are dropped and counted, never forwarded: what comes out is
never more than what came in.

A UDP link (:class:`DatagramReader`) is read a datagram at a time, each datagram
being whole MAVLink packets (as autopilots, MAVProxy and routers send them): the
packets of one datagram go out as one datagram (datagrams out <= datagrams in), and
a datagram that does not frame as whole packets is dropped unparsed and counted
(a flood of garbage costs a length check per datagram, not a parse). Datagrams
wait in a bounded queue (:data:`QUEUE_BYTES`; when it is full the oldest datagram
of the sender holding the most is dropped, and counted) between the socket, drained
first at each step, and the filter: memory and latency stay bounded whatever comes
in. Each sender has its own queue and the senders are served in turn
(:class:`FairQueue`): a flood from one sender does not crowd out another. Other
links (TCP, serial) are read as a byte stream by pymavlink, a message at a time.

Each stream (message type, system, component, instance) and axis has its own
:class:`gyrodenoise.Denoiser`, stepped once per sample with the restart flag of
:class:`gyrodenoise.flightlog.streams.RestartDetector` (same rules as for files). The filter's
sample rate (which only sets the warm-up length) is ``sample_rate`` when given,
else the rate of the first two samples; the denoiser is created at the second
sample and fed the first one then: this gives the same output as creating it
at the first sample (the first sample of a warm-up is passed through raw).

A stream sampled too slowly to denoise
(:func:`gyrodenoise.analysis.motion_metrics.too_slow_to_denoise`, telemetry at 1-4 Hz) is
forwarded raw, as in the file mode: the rate is measured over its first
:data:`RATE_SAMPLES` steps (inside the filter's warm-up, at least 10 (n+1)
samples, so nothing filtered has been forwarded before the decision).

Signed links (:mod:`gyrodenoise.flightlog.signing`): with the link's key every
packet is checked as it arrives; one that fails (unsigned or MAVLink 1 once
a packet signed with the key has come, a bad signature, a timestamp not newer than its
stream's last) is not filtered and not forwarded, and is counted per source; a
gyro packet the filter changes is re-signed (original link id and timestamp, or
one more than the stream's last one out). Without the key a signed packet is
forwarded as it came, gyro raw, and counted (``signed_left_raw``).
"""

from __future__ import annotations

import math
import os
import select
import socket
import sys
import time
from array import array
from collections import deque

import numpy as np

from gyrodenoise.core.kernels import DEFAULT_METHOD
from gyrodenoise.errors import InputError

from gyrodenoise.flightlog.signing import KEY_HINT, MAGIC_V2, LinkSigning, is_signed
from gyrodenoise.flightlog.streams import UNIT_TO_DEG_S, GyroStream, RestartDetector, measured_rate_hz, misfit
from gyrodenoise.flightlog.tlog import _AP_VERSION_RE, GYRO_FIELDS, check_crcs, packet_len, GYRO_MESSAGES, decide_raw_imu_unit, field_dtype, repacked


#: a live RAW_IMU stream whose unit is still open (see :func:`gyrodenoise.flightlog.tlog.decide_raw_imu_unit`)
#: is decided with what is known after this many seconds of its own boot time
UNIT_WAIT_S = 10.0
#: a live stream's rate is judged (too slow to denoise or not) after this many time steps
RATE_SAMPLES = 8


class _LiveStream:
    """One live gyro stream: restart detection, one denoiser per axis, and the
    safety net sample by sample (finite, inside the raw range of the session,
    fitting the field type; else the stream is forwarded raw from there on).

    A RAW_IMU stream whose unit is not yet known (``to_deg`` is ``"pending"``)
    is forwarded unfiltered until :func:`gyrodenoise.flightlog.tlog.decide_raw_imu_unit`
    decides it (the same rule as the file mode, on what the link showed so far;
    final after :data:`UNIT_WAIT_S`); the denoisers start then."""

    def __init__(self, name, message, unit, to_deg, note, gap_factor, field_dtype="<f4", *,
                 time_field=None, time_scale=1.0):
        self.name, self.message, self.unit, self.to_deg, self.note = name, message, unit, to_deg, note
        self.field_dtype = field_dtype
        self.time_field, self.time_scale = time_field, time_scale     # the message's boot-time field, to s
        self.any_v2 = False        # a MAVLink 2 frame seen (what decides a RAW_IMU unit)
        self.waited_s = 0.0        # boot time seen while the unit is pending
        self.det = RestartDetector(gap_factor)
        self.den = None
        self.tracking = False      # bias tracking on: the check adds back the bias removed
        self.t, self.raw, self.fw, self.r = [], [], [], []
        self.events = []
        self.rate = None
        self.warmup = 0
        self.start = None          # index of the first sample with a known unit
        self.non_finite = [0, 0, 0]
        self.dropouts_healed = [0, 0, 0]
        self.slow = None           # too slow to denoise: None until RATE_SAMPLES steps were seen
        self.lo = [math.inf] * 3   # raw range of the session (work units), per axis
        self.hi = [-math.inf] * 3
        self.left_raw = None
        self.signed_raw = 0        # signed samples forwarded raw for want of the key
        self.changed = 0           # samples forwarded changed

    @property
    def pending(self):
        return self.to_deg == "pending"

    def decide(self, unit, to_deg, note):
        self.unit, self.to_deg, self.note = unit, to_deg, note

    def step(self, t, raw, sample_rate, method, ar_order, warmup_s=None, filter_kw=None):
        """One sample (field units) in; the values to forward (field units) out."""
        reason = self.det.update(t)
        i = len(self.t)
        if reason:
            self.events.append({"stream": self.name, "sample": i, "time_s": t,
                                "previous_time_s": self.t[-1], "reason": reason})
        raw = [float(v) for v in raw]
        self.t.append(t)
        self.raw.append(raw)
        self.r.append(bool(reason))
        if self.slow is None and len(self.t) > RATE_SAMPLES:
            from gyrodenoise.analysis.motion_metrics import too_slow_to_denoise
            self.slow = too_slow_to_denoise(measured_rate_hz(self.t, self.r))
        if self.pending or self.left_raw or self.slow:
            self.fw.append(raw)
            return raw
        k = self.to_deg if self.to_deg is not None else 1.0
        z = [v * k for v in raw]
        if self.start is None:
            self.start = i
        if i == self.start:
            self._envelope(z, True)
            self.fw.append(raw)                          # first sample of a warm-up: raw
            return raw
        if self.den is None:
            self._start_denoisers(t, k, sample_rate, method, ar_order, warmup_s, filter_kw)
        self._envelope(z, bool(reason))
        out = []
        for j, (d, zz) in enumerate(zip(self.den, z)):
            y = d.step(zz, bool(reason))
            if not math.isfinite(zz):
                # a dropout: healed by the core as gd.denoise heals it (the filter restarts at
                # this sample and passes it through: y is the raw NaN/inf; with the AR methods'
                # outlier gate a +-inf is rejected and y is the held prediction). The range the
                # output is checked against stays the session's: it holds the core's
                self._dropout(j)
                out.append(raw[j] if not math.isfinite(y) else y / k)
                continue
            b = d.bias_hat if self.tracking else 0.0
            bad = self._check(j, y + b)
            if bad:
                self._leave_raw(i, j, y + b, bad if not b else f"(the output {y:.6g} plus the bias removed {b:.6g}) {bad}")
                self.fw.append(raw)
                return raw
            out.append(raw[j] if y == zz else y / k)      # passed through (warm-up): bit for bit
        if (misfit(np.asarray(out), self.field_dtype) & np.isfinite(z)).any():   # a dropout goes as it came
            self._leave_raw(i, None, out, f"does not fit the field type {np.dtype(self.field_dtype).name}")
            self.fw.append(raw)
            return raw
        self.fw.append(out)
        return out

    def _start_denoisers(self, t, k, sample_rate, method, ar_order, warmup_s, filter_kw):
        """One denoiser per axis at the second sample of known unit (rate: ``sample_rate``,
        else from the first two samples), fed the first one (``k``: to work units)."""
        from gyrodenoise.core.kernels import P_BIAS, P_WARMUP
        from gyrodenoise.denoiser import Denoiser
        if sample_rate:
            rate = float(sample_rate)
        else:
            dt = t - self.t[self.start]
            rate = 1.0 / dt if dt > 0 else 50.0
        self.rate = rate
        kw = {} if warmup_s is None else {"warmup_s": float(warmup_s)}
        kw.update(filter_kw or {})
        self.den = [Denoiser(sample_rate_hz=rate, method=method, ar_order=ar_order, **kw)
                    for _ in range(3)]
        self.warmup = int(self.den[0].params[P_WARMUP])
        self.tracking = self.den[0].params[P_BIAS] > 0.0
        for j, (d, v0) in enumerate(zip(self.den, self.raw[self.start])):
            d.step(v0 * k, False)
            if not math.isfinite(v0 * k):
                self._dropout(j)

    def _dropout(self, j):
        """Count a non-finite sample of axis ``j``, fed to its denoiser and healed there."""
        self.non_finite[j] += 1
        self.dropouts_healed[j] += 1

    def _envelope(self, z, new_session):
        for j, zz in enumerate(z):
            if not math.isfinite(zz):
                if new_session:            # a restart on a dropout: the range starts at the next sample
                    self.lo[j], self.hi[j] = math.inf, -math.inf
                continue
            if new_session or zz < self.lo[j]:
                self.lo[j] = zz if new_session else min(self.lo[j], zz)
            if new_session or zz > self.hi[j]:
                self.hi[j] = zz if new_session else max(self.hi[j], zz)

    def _check(self, j, y):
        """None, or what is wrong with value ``y`` (work units) of axis ``j``: the output, plus
        the bias removed after this sample when bias tracking is on (the value the filter
        clamps into the range: the output stays inside the range shifted by that bias)."""
        if not math.isfinite(y):
            return "not finite"
        m = 1e-9 * (1.0 + max(abs(self.lo[j]), abs(self.hi[j])))
        if not self.lo[j] - m <= y <= self.hi[j] + m:
            return f"outside the raw range since the last restart [{self.lo[j]:.6g}, {self.hi[j]:.6g}]"
        return None

    def _leave_raw(self, i, j, value, why):
        ax = "xyz"[j] + ": " if j is not None else ""
        self.left_raw = (f"{ax}filtered value {value if j is None else f'{value:.6g}'} at sample {i} "
                         f"(t={self.t[i]:.3f} s) {why}; forwarded raw from that sample on")

    def as_stream(self):
        n = len(self.t)
        k = self.to_deg if isinstance(self.to_deg, float) else 1.0
        unit = self.unit if not self.pending else "counts"
        s = GyroStream(name=self.name, message=self.message, unit=unit,
                       to_deg_s=self.to_deg if isinstance(self.to_deg, float) else None,
                       time_s=np.asarray(self.t), raw=np.asarray(self.raw, dtype=np.float64).reshape(n, 3),
                       index=np.arange(n), note=self.note if not self.pending else
                       "RAW_IMU unit never decided on this link (no HEARTBEAT of the sender): forwarded raw",
                       field_dtype=self.field_dtype)
        s.restarts = np.asarray(self.r, dtype=bool)
        s.restart_events = self.events
        s.repeated_timestamps = self.det.repeated
        s.rate_hz = measured_rate_hz(s.time_s, s.restarts)
        s.filtered = np.asarray(self.fw, dtype=np.float64).reshape(n, 3)
        x, f = s.raw * k, s.filtered * k
        s._work = (x, f, "deg/s" if s.to_deg_s is not None else unit, self.rate or 0.0)
        s.non_finite = list(self.non_finite)
        s.dropouts_healed = list(self.dropouts_healed)
        s.left_raw = self.left_raw
        s.warmup_samples = (self.start or 0) + self.warmup
        s.not_filtered = None
        if self.signed_raw and not self.changed:
            s.not_filtered = (f"its packets are signed (MAVLink 2) and no --signing-key was given: forwarded raw, "
                              f"signatures kept (a signed packet is never sent unsigned); {KEY_HINT}")
        return s


def _differ(a, b):
    """True if the values ``a`` and ``b`` differ (NaN equal to NaN)."""
    return any(x != y and not (x != x and y != y) for x, y in zip(a, b))


def _enlarge_receive_buffer(conn, size=4 << 20):
    """Ask for a larger UDP receive buffer (bursts while the process is descheduled)."""
    sock = getattr(conn, "port", None)
    if isinstance(sock, socket.socket) and sock.type == socket.SOCK_DGRAM:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
        except OSError:
            pass


def run_live(source, forward, *, duration=None, max_messages=None, method=DEFAULT_METHOD, ar_order=3,
             gap_factor=5.0, sample_rate=None, raw_imu_unit="auto", raw_imu_scale=None, log=None,
             warmup_s=None, filter_kw=None, signing_key=None):
    """Bridge ``source`` to ``forward`` (pymavlink connection strings) until
    ``duration`` seconds have passed or ``max_messages`` messages were
    forwarded (or Ctrl-C). ``signing_key``: the link's 32-byte MAVLink 2 key
    (packets checked, changed ones re-signed). Returns (report dict, list of GyroStream)."""
    src, dst = _open_links(source, forward)
    if log:
        log(f"listening on {source}, forwarding to {forward or '(nowhere)'}")
    bridge = _LiveBridge(method=method, ar_order=ar_order, gap_factor=gap_factor, sample_rate=sample_rate,
                         warmup_s=warmup_s, filter_kw=filter_kw, raw_imu_unit=raw_imu_unit,
                         raw_imu_scale=raw_imu_scale, log=log, signing_key=signing_key)
    bridge.reader = link_reader(src)
    t_start = time.monotonic()
    try:
        stopped_by = _forward_until_stopped(src, dst, bridge, t_start + duration if duration else None,
                                            max_messages)
    finally:
        src.close()
        if dst is not None:
            dst.close()
    report = {
        "mode": "live", "input": source, "forward": forward, "stopped_by": stopped_by,
        "seconds": round(time.monotonic() - t_start, 3), "messages_in": bridge.n_in,
        "messages_forwarded": bridge.n_out, **bridge.reader.report(isinstance(bridge.reader, DatagramReader)),
        **bridge.link.report(), "handling_us": _handling_us(bridge.handle_ns),
        "method": method, "ar_order": int(ar_order), "gap_factor": gap_factor, "warmup_s": warmup_s,
        "filter_options": dict(filter_kw or {}),
        "form": "causal", "form_note": "a live link is filtered as it comes, one sample at a time",
    }
    return report, [st.as_stream() for st in bridge.streams.values()]


def _open_links(source, forward):
    """(input connection, output connection or None), MAVLink 2 with the ArduPilot
    dialect; InputError with one line when one cannot be opened."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil
    mavutil.set_dialect("ardupilotmega")
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
    return src, dst


def _forward_until_stopped(src, dst, bridge, deadline, max_messages):
    """Receive, handle and forward messages (a UDP datagram's together); return what stopped it:
    ``"count"`` (``max_messages`` readable messages received), ``"duration"`` (``deadline``, a
    :func:`time.monotonic` time, passed) or ``"interrupt"`` (Ctrl-C)."""
    reader = bridge.reader
    try:
        while True:
            if max_messages is not None and bridge.n_in >= max_messages:
                return "count"
            timeout = 0.2
            if deadline is not None:
                timeout = deadline - time.monotonic()
                if timeout <= 0:
                    return "duration"
                timeout = min(timeout, 0.2)
            msgs = reader.next(timeout)
            if not msgs:
                continue
            out = []
            for msg in msgs:
                h0 = time.perf_counter_ns()
                b = bridge.handle(msg)
                if b:
                    out.append(b)
                bridge.handle_ns.append(time.perf_counter_ns() - h0)
            if dst is not None and out:
                dst.write(b"".join(out))        # one datagram in, at most one out
                bridge.n_out += len(out)
                reader.writes_out += 1
    except KeyboardInterrupt:
        return "interrupt"


#: bytes of datagrams waiting to be handled, at most (:class:`FairQueue`; beyond, dropped and
#: counted): two 64 kB datagrams of a flood, many seconds of a fast IMU link (~50 bytes a packet)
QUEUE_BYTES = 1 << 17
#: datagrams read from the socket at most before the next one is handled
DRAIN_MAX = 256
#: Linux's socket option that puts the count of datagrams the kernel dropped (receive
#: buffer full) on each datagram received
_SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40 if sys.platform.startswith("linux") else None)


def mavlink_frames(data):
    """The offsets of the MAVLink 1 / 2 packets of a datagram that is whole packets end
    to end (lengths only: the CRCs are checked by :func:`crc_ok`), else None."""
    offsets, p, n = [], 0, len(data)
    while p < n:
        ln = packet_len(data, p, n)
        if ln is None or ln < 0 or p + ln > n:
            return None
        offsets.append(p)
        p += ln
    return offsets or None


#: a datagram of more packets than this has their CRCs checked together (numpy), not one by one
MANY_PACKETS = 8


def crc_ok(data, offsets):
    """Which of the packets at ``offsets`` of ``data`` have a known message id and a good
    CRC: :func:`gyrodenoise.flightlog.tlog.check_crcs`, the tlog reader's vectorised check
    (it addresses a tlog record, whose packet starts 8 bytes in)."""
    buf = np.frombuffer(data, dtype=np.uint8)
    at = np.asarray(offsets, dtype=np.int64)
    v2 = buf[at] == MAGIC_V2          # the id: a MAVLink 1 packet's at byte 5, a 2's at bytes 7-9
    msgid = np.where(v2, buf[at + 7].astype(np.int64) | (buf[at + 8].astype(np.int64) << 8)
                     | (buf[at + 9].astype(np.int64) << 16), buf[at + 5].astype(np.int64))
    return check_crcs(buf, at - 8, np.diff(np.append(at, len(buf))) + 8, v2, msgid)


class _ReadCounts:
    """What a link reader counted: ``unreadable`` (records dropped: datagrams that do
    not frame, packets that do not decode, pymavlink's BAD_DATA) and their bytes, the
    datagrams in and out, dropped from a full queue, dropped by the kernel."""

    def __init__(self):
        self.unreadable = self.unreadable_bytes = 0
        self.datagrams_in = self.writes_out = 0
        self.garbage_datagrams = self.overload_dropped = 0
        self.kernel_dropped = None

    def bad(self, n_bytes):
        self.unreadable += 1
        self.unreadable_bytes += n_bytes

    def report(self, datagrams):
        rep = {"unreadable_records": self.unreadable, "unreadable_bytes": self.unreadable_bytes,
               "unreadable_note": "dropped, never forwarded"}
        if datagrams:
            rep.update({"datagrams_in": self.datagrams_in, "datagrams_out": self.writes_out,
                        "garbage_datagrams": self.garbage_datagrams,
                        "queue_bytes": QUEUE_BYTES, "overload_dropped_datagrams": self.overload_dropped,
                        "kernel_dropped_datagrams": self.kernel_dropped})
        return rep


#: a sender's datagram dropped from a full queue is the largest of its oldest this many
DROP_AMONG = 32


class FairQueue:
    """Datagrams waiting to be handled: one first-in first-out queue per sender, the
    senders served in turn, ``limit`` bytes in all at most: beyond, the sender holding
    the most bytes loses the largest of its :data:`DROP_AMONG` oldest datagrams (a flood
    from one sender delays another by one of its datagrams at most and takes its place
    in the queue only; large garbage goes before the small packets of a link it is mixed with)."""

    def __init__(self, limit):
        self.limit = limit
        self.senders = {}              # sender -> [deque of (item, size), bytes]; in serving order
        self.bytes = 0

    def __len__(self):
        return sum(len(q) for q, _ in self.senders.values())

    def put(self, sender, item, size):
        """Queue ``item`` (``size`` bytes) of ``sender``; how many datagrams were dropped for it."""
        entry = self.senders.setdefault(sender, [deque(), 0])
        entry[0].append((item, size))
        entry[1] += size
        self.bytes += size
        dropped = 0
        while self.bytes > self.limit:
            who = max(self.senders, key=lambda k: self.senders[k][1])
            q = self.senders[who]
            oldest = [q[0][i][1] for i in range(min(len(q[0]), DROP_AMONG))]
            i = oldest.index(max(oldest))
            n = q[0][i][1]
            del q[0][i]
            q[1] -= n
            self.bytes -= n
            dropped += 1
            if not q[0]:
                del self.senders[who]
        return dropped

    def get(self):
        """The oldest item of the next sender in turn, or None."""
        for who in self.senders:
            q = self.senders.pop(who)
            item, n = q[0].popleft()
            q[1] -= n
            self.bytes -= n
            if q[0]:
                self.senders[who] = q  # to the end of the turn
            return item
        return None


class DatagramReader(_ReadCounts):
    """A UDP link's datagrams (``sock``: non-blocking), decoded with ``parser`` (a
    pymavlink ``MAVLink``): :meth:`next` drains the socket into a :class:`FairQueue` (a
    datagram that is not whole packets counted and dropped there, :func:`mavlink_frames`)
    and returns the messages of the next datagram queued."""

    def __init__(self, sock, parser):
        super().__init__()
        self.sock, self.parser = sock, parser
        self.queue = FairQueue(QUEUE_BYTES)
        self.anc = 0
        if _SO_RXQ_OVFL is not None:
            try:
                sock.setsockopt(socket.SOL_SOCKET, _SO_RXQ_OVFL, 1)
                self.anc = socket.CMSG_SPACE(4)
                self.kernel_dropped = 0
            except OSError:
                pass

    def _drain(self):
        for _ in range(DRAIN_MAX):
            try:
                data, anc, _, sender = self.sock.recvmsg(1 << 16, self.anc)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:            # e.g. ECONNREFUSED of an earlier send: nothing to read
                return
            for level, kind, value in anc:
                if level == socket.SOL_SOCKET and kind == _SO_RXQ_OVFL and len(value) >= 4:
                    self.kernel_dropped = max(self.kernel_dropped or 0, int.from_bytes(value[:4], sys.byteorder))
            self.datagrams_in += 1
            offsets = mavlink_frames(data)
            if offsets is None:
                self.garbage_datagrams += 1
                self.bad(len(data))
                continue
            self.overload_dropped += self.queue.put(sender, (data, offsets), len(data))

    def next(self, timeout):
        """The readable messages of the next datagram ([] for none within ``timeout`` s)."""
        self._drain()
        item = self.queue.get()
        if item is None:
            select.select([self.sock], [], [], timeout)
            self._drain()
            item = self.queue.get()
            if item is None:
                return []
        data, offsets = item
        ends = offsets[1:] + [len(data)]
        good = crc_ok(data, offsets) if len(offsets) > MANY_PACKETS else [True] * len(offsets)
        msgs = []
        for a, b, ok in zip(offsets, ends, good):
            try:
                if not ok:
                    raise ValueError("bad CRC or unknown message id")
                msgs.append(self.parser.decode(bytearray(data[a:b])))
            except Exception:  # noqa: BLE001 - pymavlink's MAVError and struct errors: a bad packet
                self.bad(b - a)
        return msgs


class StreamReader(_ReadCounts):
    """A byte-stream link (TCP, serial) read by pymavlink a message at a time;
    unreadable bytes (BAD_DATA) counted and dropped."""

    def __init__(self, conn):
        super().__init__()
        self.conn = conn

    def next(self, timeout):
        msg = self.conn.recv_match(blocking=True, timeout=timeout)
        if msg is None:
            return []
        if msg.get_type() == "BAD_DATA":
            self.bad(len(getattr(msg, "data", None) or b""))
            return []
        return [msg]


def link_reader(conn):
    """The reader of an input connection: :class:`DatagramReader` for a UDP socket, else
    :class:`StreamReader`."""
    sock = getattr(conn, "port", None)
    if isinstance(sock, socket.socket) and sock.type == socket.SOCK_DGRAM:
        sock.setblocking(False)
        return DatagramReader(sock, conn.mav)
    return StreamReader(conn)


def _handling_us(handle_ns):
    """Mean, 99th percentile and largest handling time of a message, microseconds."""
    hs = np.asarray(handle_ns, dtype=np.float64) / 1000.0
    return {"mean": float(hs.mean()) if len(hs) else None,
            "p99": float(np.percentile(hs, 99)) if len(hs) else None,
            "max": float(hs.max()) if len(hs) else None}


class _LiveBridge:
    """What a live link has seen so far: its gyro streams, its vehicles (what
    decides a RAW_IMU unit) and the message counts; :meth:`handle` turns one
    received message into the bytes to forward."""

    def __init__(self, *, method, ar_order, gap_factor, sample_rate, warmup_s, filter_kw,
                 raw_imu_unit, raw_imu_scale, log, signing_key=None):
        self.method, self.ar_order, self.gap_factor = method, ar_order, gap_factor
        self.sample_rate, self.warmup_s, self.filter_kw = sample_rate, warmup_s, filter_kw
        self.raw_imu_unit, self.raw_imu_scale, self.log = raw_imu_unit, raw_imu_scale, log
        self.streams = {}          # (system, component, message type, instance) -> _LiveStream
        self.vehicles = {}         # system id -> {"autopilots": set, "ap_version": bool}
        self.n_in = self.n_out = 0
        self.link = LinkSigning(signing_key)
        self.handle_ns = array("q")          # ns per message: 8 bytes each
        self.reader = None                   # the input link's reader (link_reader)

    def handle(self, msg):
        """The bytes to forward for one received message (readable: the readers drop
        the rest): a gyro message re-packed with the filtered values (re-signed if it
        came signed and the key is known), any other as it came; nothing (``b""``) for
        a packet that fails the signature check."""
        self.n_in += 1
        mtype = msg.get_type()
        pkt = bytes(msg.get_msgbuf())
        if self.link.check(pkt) is not None:
            return b""                   # not filtered, not forwarded: counted per source
        out = pkt
        sysid = msg.get_srcSystem()
        if mtype == "HEARTBEAT":
            self._vehicle(sysid)["autopilots"].add(msg.autopilot)
        elif mtype == "STATUSTEXT" and _AP_VERSION_RE.search(msg.text or ""):
            self._vehicle(sysid)["ap_version"] = True
        elif mtype in GYRO_MESSAGES:
            out = self._filter_gyro(msg, mtype, sysid, pkt)
        if out is pkt:
            self.link.passed(pkt)
        return out

    def _vehicle(self, sysid):
        return self.vehicles.setdefault(sysid, {"autopilots": set(), "ap_version": False})

    def _filter_gyro(self, msg, mtype, sysid, out):
        st = self._stream(msg, mtype, sysid)
        t_s = getattr(msg, st.time_field) * st.time_scale
        if st.pending:
            self._decide_unit(st, out, t_s, sysid)
        vals = st.step(t_s, [getattr(msg, g) for g in GYRO_FIELDS], self.sample_rate, self.method,
                       self.ar_order, self.warmup_s, self.filter_kw)
        if vals is st.raw[-1]:               # unchanged samples are forwarded byte for byte
            return out
        if is_signed(out) and self.link.key is None:
            # never sent unsigned: as it came, gyro raw (and so in the stream's record)
            if _differ(vals, st.raw[-1]):
                st.signed_raw += 1
                self.link.left_raw += 1
            st.fw[-1] = st.raw[-1]
            return out
        new = repacked(out, (mtype, vals), self.link)
        if new == out:
            return out
        st.changed += 1
        return new

    def _stream(self, msg, mtype, sysid):
        """The stream of a gyro message, created at its first message."""
        inst = msg.id if "id" in msg.get_fieldnames() else 0
        key = (sysid, msg.get_srcComponent(), mtype, inst)
        st = self.streams.get(key)
        if st is None:
            tfield, tscale, unit = GYRO_MESSAGES[mtype]
            to_deg, note = (UNIT_TO_DEG_S[unit], "") if unit != "raw" else ("pending", "")
            name = f"{mtype}" + (f"[{inst}]" if inst else "") + f"@{key[0]}.{key[1]}"
            st = self.streams[key] = _LiveStream(name, mtype, unit, to_deg, note, self.gap_factor,
                                                 field_dtype(mtype), time_field=tfield, time_scale=tscale)
        return st

    def _decide_unit(self, st, out, t_s, sysid):
        """A RAW_IMU stream's unit by the file mode's rule on what the link showed so far."""
        st.any_v2 = st.any_v2 or bytes(out[:1]) == b"\xfd"
        if st.t and t_s > st.t[-1]:
            st.waited_s += t_s - st.t[-1]
        got = decide_raw_imu_unit(self.vehicles.get(sysid), st.any_v2, self.raw_imu_unit,
                                  self.raw_imu_scale, final=st.waited_s >= UNIT_WAIT_S)
        if got is not None:
            st.decide(*got)
            if self.log and got[1] is None:
                self.log(f"{st.name}: {got[2]}")
