"""SYNTHETIC logs for the tests of the log data, flight segments and vibration review:
a minimal DataFlash writer (FMT messages, then messages packed as their formats say)
and a telemetry-log writer (pymavlink's packer, records stamped with a wall time)."""
from __future__ import annotations

import struct

import numpy as np

# DataFlash format character -> struct character (pymavlink's DFReader table)
_STRUCT = {"b": "b", "B": "B", "h": "h", "H": "H", "i": "i", "I": "I", "f": "f", "d": "d",
           "n": "4s", "N": "16s", "Z": "64s", "c": "h", "C": "H", "e": "i", "E": "I", "L": "i",
           "M": "B", "q": "q", "Q": "Q", "a": "32h"}


class DataFlashWriter:
    """Builds a DataFlash log in memory: ``define(name, format, columns)`` once per
    type, then ``add(name, *values)`` (strings as bytes or str, ``c``/``e``... already
    scaled to the integers as logged); ``bytes()`` the log. ``define(..., type_id=T)``
    declares (or re-declares, mid-log) type id T. ``written``: (name, offset, format,
    columns) of every message added, in order."""

    def __init__(self):
        self.out = bytearray()
        self.types = {}
        self.written = []
        self._next_id = 0x81

    def define(self, name, fmt, columns, type_id=None):
        if type_id is None:
            tid, self._next_id = self._next_id, self._next_id + 1
        else:
            tid = type_id
            self.types = {k: v for k, v in self.types.items() if v[0] != tid}
        st = "<" + "".join(_STRUCT[c] for c in fmt)
        length = 3 + struct.calcsize(st)
        self.types[name] = (tid, st, fmt, list(columns))
        self.out += struct.pack("<BBBBB4s16s64s", 0xA3, 0x95, 0x80, tid, length, name.encode(),
                                fmt.encode(), ",".join(columns).encode())

    def add(self, name, *values):
        tid, st, fmt, columns = self.types[name]
        self.written.append((name, len(self.out), fmt, columns))
        flat = []
        for v in values:
            if isinstance(v, str):
                v = v.encode()
            if isinstance(v, (list, tuple, np.ndarray)):
                flat.extend(int(x) for x in v)
            else:
                flat.append(v)
        self.out += bytes([0xA3, 0x95, tid]) + struct.pack(st, *flat)

    def bytes(self):
        return bytes(self.out)


def tlog_writer(sysid=1):
    """(mav module, add(msg, wall_us), bytes()) of a telemetry log built in memory."""
    from pymavlink.dialects.v20 import ardupilotmega as mav
    m = mav.MAVLink(None, srcSystem=sysid, srcComponent=1)
    out = bytearray()

    def add(msg, wall_us):
        out.extend(struct.pack(">Q", int(wall_us)) + msg.pack(m))

    return mav, add, lambda: bytes(out)


# ULog type -> struct character
_ULOG_STRUCT = {"int8_t": "b", "uint8_t": "B", "int16_t": "h", "uint16_t": "H", "int32_t": "i",
                "uint32_t": "I", "int64_t": "q", "uint64_t": "Q", "float": "f", "double": "d",
                "bool": "?", "char": "c"}


class ULogWriter:
    """Builds a ULog file in memory: ``define(name, [(type, field), ...])`` (types as
    ULog writes them: ``float``, ``int16_t[32]``...), ``subscribe(name, multi_id)``
    (returns the msg id), ``add(msg_id, *values)`` (arrays as sequences), ``sync()``,
    ``info(key, text)``, ``param(name, value)``; ``bytes()`` the file."""

    def __init__(self, start_us=0):
        self.out = bytearray(b"ULog\x01\x12\x35\x01" + struct.pack("<Q", start_us))
        self._msg("B", bytes(40))                      # flag bits: no flags, no appended data
        self.structs = {}
        self.subs = {}

    def _msg(self, mtype, payload):
        self.out += struct.pack("<HB", len(payload), ord(mtype)) + payload

    def info(self, key, text):
        k = f"char[{len(text)}] {key}".encode()
        self._msg("I", bytes([len(k)]) + k + text.encode())

    def param(self, name, value):
        k = (f"float {name}" if isinstance(value, float) else f"int32_t {name}").encode()
        self._msg("P", bytes([len(k)]) + k + struct.pack("<f" if isinstance(value, float) else "<i", value))

    def define(self, name, fields):
        st = "<"
        logged = list(fields)
        while logged and logged[-1][1].startswith("_padding"):    # a logger leaves trailing padding out
            logged.pop()
        for tname, fname in logged:
            base, _, n = tname.partition("[")
            st += (n.rstrip("]") if n else "") + ("x" if fname.startswith("_padding") else _ULOG_STRUCT[base])
        self.structs[name] = st
        self._msg("F", (name + ":" + "".join(f"{t} {f};" for t, f in fields)).encode())

    def subscribe(self, name, multi_id=0):
        msg_id = len(self.subs)
        self.subs[msg_id] = name
        self._msg("A", struct.pack("<BH", multi_id, msg_id) + name.encode())
        return msg_id

    def add(self, msg_id, *values):
        flat = []
        for v in values:
            if isinstance(v, (list, tuple, np.ndarray)):
                flat.extend(v.tolist() if isinstance(v, np.ndarray) else v)
            else:
                flat.append(v)
        self._msg("D", struct.pack("<H", msg_id) + struct.pack(self.structs[self.subs[msg_id]], *flat))

    def sync(self):
        self._msg("S", b"\x2F\x73\x13\x20\x25\x0C\xBB\x12")

    def bytes(self):
        return bytes(self.out)


def crash_dataflash(crash_s=20.0, end_s=30.0, disarm_s=None, tumble=True, spike=True,
                    swing=None, rate_hz=200.0, seed=0, clips=True):
    """A SYNTHETIC ArduCopter DataFlash flight with a crash at ``crash_s`` (None: none):
    IMU (GyrX/Y/Z rad/s, AccX/Y/Z m/s/s) at ``rate_hz`` from 1 s to ``end_s``; armed at
    2 s, in the air at 4 s (EV 28); CTUN.ThO steady at 0.45 in the air (0.1 before);
    VIBE at 10 Hz: VibeZ 20 m/s/s in flight, 90 after the crash, Clip +1 per sample
    after it (with ``clips``; on the ground after a crash the counter runs). Before the crash the
    body rate is noise of 5 deg/s per axis plus a 90 deg/s roll manoeuvre (0.25 Hz)
    from 8 to 12 s. The crash: from ``crash_s`` 0.3 s of a 1500 deg/s roll rate and (with
    ``spike``) a 12 g accelerometer spike of 40 ms; then (``tumble``) ATT.Roll at 175 deg,
    and a disarm (EV 11) at ``disarm_s`` where given. ``swing``: (start, end) of a
    motor failure -- the roll rate swinging +-131 deg/s at 0.5 Hz with the throttle steady.
    Returns the log's bytes."""
    rng = np.random.default_rng(seed)
    w = DataFlashWriter()
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    w.define("ATT", "Qff", ["TimeUS", "Roll", "Pitch"])
    w.define("VIBE", "QBfffI", ["TimeUS", "IMU", "VibeX", "VibeY", "VibeZ", "Clip"])
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("ARM", "QBIBB", ["TimeUS", "ArmState", "ArmChecks", "Forced", "Method"])
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    for text in ("ArduCopter V4.5.7 (0123abcd)", "CubeOrange 00300021 31305110 30393738", "Frame: QUAD/X"):
        w.add("MSG", 900_000, text)
    t = 1.0 + np.arange(int(round((end_s - 1.0) * rate_hz))) / rate_hz
    crashed = np.zeros(len(t), bool) if crash_s is None else t >= crash_s
    gyr = rng.normal(0, 5.0, (len(t), 3))
    man = (t >= 8) & (t < 12)
    gyr[man, 0] += 90 * np.sin(2 * np.pi * 0.25 * (t[man] - 8))
    if swing is not None:
        sw = (t >= swing[0]) & (t < swing[1])
        gyr[sw, 0] += 131 * np.sin(2 * np.pi * 0.5 * (t[sw] - swing[0]))
    acc = np.stack([rng.normal(0, 1.0, len(t)), rng.normal(0, 1.0, len(t)), -9.8 + rng.normal(0, 1.0, len(t))], 1)
    if crash_s is not None:
        hit = (t >= crash_s) & (t < crash_s + 0.3)
        gyr[hit, 0] = 1500.0
        if spike:
            acc[(t >= crash_s) & (t < crash_s + 0.04), 2] = 12 * 9.8
        if tumble:
            acc[t >= crash_s + 0.3, 2] += 19.6                     # upside down: +g on z
        gyr[t >= crash_s + 0.3] *= 0.2                            # lying still
    gyr = np.radians(gyr)
    events = [(2.0, 10), (4.0, 28)] + ([(disarm_s, 11)] if disarm_s is not None else [])
    k = 0
    for j in range(len(t)):
        us = int(round(t[j] * 1e6))
        while k < len(events) and events[k][0] * 1e6 <= us:
            e_us = int(round(events[k][0] * 1e6))
            w.add("EV", e_us, events[k][1])
            if events[k][1] in (10, 11):
                w.add("ARM", e_us, int(events[k][1] == 10), 0, 0, 0)
            k += 1
        w.add("IMU", us, 0, *gyr[j], *acc[j])
        if j % int(rate_hz / 10) == 0:
            air = 4.0 <= t[j] and (disarm_s is None or t[j] < disarm_s)
            w.add("CTUN", us, (0.45 + rng.normal(0, 0.005)) if air else 0.1)
            roll = 175.0 if (tumble and crashed[j] and t[j] >= crash_s + 0.3) else 0.0
            w.add("ATT", us, roll, 0.0)
            vz = 90.0 if crashed[j] else 20.0
            clip = int(np.sum(crashed[:j][:: int(rate_hz / 10)])) if clips else 0   # counted after the impact
            w.add("VIBE", us, 0, 10.0, 10.0, vz, clip)
    return w.bytes()
