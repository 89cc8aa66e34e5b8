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
