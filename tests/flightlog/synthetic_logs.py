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
