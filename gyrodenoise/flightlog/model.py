"""The typed model of a flight log, whatever its format: :class:`FlightLog`.

A format's adapter (:mod:`gyrodenoise.flightlog.formats`) reads a file into a
:class:`FlightLog`; everything after the reading (the flight segments, the
vibration and filter reviews, the filtered copy) works on it and asks the
format's adapter, never the format's name, for what differs between formats.

* :class:`Boot` -- one boot session of the vehicle in the file (a log downloaded
  whole, a reboot, logs concatenated hold several): where it starts in the
  file's record numbering (a gyro stream's ``index`` and a message's ``record``
  use the same numbering), its span on its own time axis and that axis'
  :class:`TimeBase`.
* :class:`TimeBase` -- what a log's ``time_s`` counts: the time since boot, or
  (PX4 SITL, some telemetry logs) a Unix epoch clock, in which case the times are
  moved to start at 0 at the boot's first sample and ``offset_s`` keeps the
  epoch time of that 0; the axes and the report say which.
* :class:`LogFacts` -- the report's fields on the file itself.
* :class:`FlightEvidence` -- what a format's adapter found about arming and being in
  the air in one boot, the input of :func:`gyrodenoise.flightlog.segments.flight_segments`.
* :class:`LogParameters` -- the autopilot that wrote the log and its parameters.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrodenoise.flightlog.streams import GyroStream

#: the time bases a log's clock can have
BOOT_TIME, UNIX_EPOCH = "boot time", "Unix epoch"
#: a clock reading above this (us) is a Unix epoch time, not a time since boot (about 11.6 days)
EPOCH_US_MIN = 1e12


_INSTANCE_RE = re.compile(r"\[(\d+)\]")
_NUMBERED_RE = re.compile(r"^[A-Za-z_]*?[A-Za-z_](\d)$")


def number_instances(streams):
    """Set each gyro stream's ``instance``: the ``[n]`` of its name (a DataFlash ``I``, a
    ULog ``multi_id``, a telemetry ``id``), else the sensor number its message names
    (``IMU2``, ``SCALED_IMU3``: 1, 2), else 0."""
    for s in streams:
        m = _INSTANCE_RE.search(s.name)
        n = _NUMBERED_RE.match(s.message or "")
        s.instance = int(m.group(1)) if m else int(n.group(1)) - 1 if n else 0
    return streams


@dataclass(frozen=True)
class TimeBase:
    """What ``time_s`` of a boot counts. ``kind``: :data:`BOOT_TIME` or
    :data:`UNIX_EPOCH`; ``offset_s``: the clock's reading (s) at ``time_s`` 0 (0 for
    a boot time; the epoch time of the boot's first sample for an epoch clock)."""
    kind: str = BOOT_TIME
    offset_s: float = 0.0

    @property
    def axis_label(self):
        """The label of a time axis in this base."""
        if self.kind == UNIX_EPOCH:
            return "time since the log's start [s] (Unix epoch clock)"
        return "boot time [s]"

    def to_fields(self):
        return {"kind": self.kind, "offset_s": self.offset_s, "axis": self.axis_label}


@dataclass(frozen=True)
class Boot:
    """One boot session. ``first_record``: the record (reader-defined numbering: a
    DataFlash byte offset, a telemetry frame index, a ULog sample) where it begins;
    ``start_s``/``end_s``: its span on its own time axis (NaN when no timed message);
    ``wall_clock_offset_s``: the Unix time of its ``time_s`` 0 where the log records
    one (a telemetry log's record stamps), else None."""
    index: int
    first_record: int
    start_s: float
    end_s: float
    time_base: TimeBase = TimeBase()
    wall_clock_offset_s: float | None = None

    def to_fields(self):
        return {"session": self.index, "first_record": self.first_record,
                "start_s": _round(self.start_s), "end_s": _round(self.end_s),
                "time_base": self.time_base.to_fields(),
                "wall_clock_offset_s": self.wall_clock_offset_s}


def _round(x):
    return None if x is None or not np.isfinite(x) else round(float(x), 6)


@dataclass
class LogFacts:
    """The report's fields on the file itself. ``unreadable_bytes`` and
    ``data_corruption`` are left out of the report where the format does not tell them."""
    messages: int
    unreadable_records: int | None
    truncated_bytes: int
    truncation: str | None
    unreadable_bytes: int | None = None
    data_corruption: bool | None = None
    #: why a would-be gyro stream was not read (the format's reader says), each a line
    streams_skipped: list[str] | None = None

    def to_fields(self):
        out = {"messages": self.messages, "unreadable_records": self.unreadable_records}
        if self.unreadable_bytes is not None:
            out["unreadable_bytes"] = self.unreadable_bytes
        if self.data_corruption is not None:
            out["data_corruption"] = self.data_corruption
        if self.streams_skipped is not None:
            out["streams_skipped"] = list(self.streams_skipped)
        out.update(truncated=self.truncated_bytes > 0, truncated_bytes=self.truncated_bytes,
                   truncation=self.truncation)
        return out


@dataclass
class ReadOptions:
    """How to read a log: ``raw_imu_unit``/``raw_imu_scale`` -- the unit of a telemetry
    log's RAW_IMU (``auto``: from the log)."""
    raw_imu_unit: str = "auto"
    raw_imu_scale: float | None = None


#: the kind of the segment that follows a crash (:mod:`gyrodenoise.flightlog.impact`)
AFTER_IMPACT = "after impact"


@dataclass(frozen=True)
class Segment:
    """A stretch of one boot: ``kind`` ``ground``/``armed``/``flying``/``after impact``/``hover``
    (or, for a figure over a whole boot, ``whole log``), ``start_s``/``end_s`` on the boot's
    time axis (start and end included), ``session`` the boot (None: any boot, a figure over
    the whole of a log of one boot); ``impact``: the crash an ``after impact`` segment
    starts with (:class:`gyrodenoise.flightlog.impact.Impact`)."""
    kind: str
    start_s: float
    end_s: float
    session: int | None = 0
    impact: Any = None

    @property
    def duration_s(self):
        return self.end_s - self.start_s

    def contains(self, time_s, sessions=None):
        """Bool array: ``time_s`` inside the segment (and, given each sample's boot
        ``sessions``, in its boot)."""
        t = np.asarray(time_s, dtype=np.float64)
        m = (t >= self.start_s) & (t <= self.end_s)
        if sessions is not None and self.session is not None:
            m &= np.asarray(sessions) == self.session
        return m

    def to_fields(self):
        """The report's dict (the JSON edge)."""
        out = {"kind": self.kind, "start_s": self.start_s, "end_s": self.end_s}
        if self.session is not None:
            out["session"] = self.session
        if self.impact is not None:
            out["impact"] = self.impact.to_fields()
        return out


@dataclass
class Throttle:
    """Throttle 0..1 at ``time_s`` (for hover stretches and, without land evidence,
    for being in the air); ``source``: which field."""
    time_s: np.ndarray
    value: np.ndarray
    source: str


@dataclass
class FlightEvidence:
    """What one boot of a log says about arming and being in the air: ``state`` (0
    ground, 1 armed, 2 flying) on the timeline ``time_s``; ``throttle`` for hover;
    ``note``: which evidence gave it (the names of the fields it read)."""
    time_s: np.ndarray
    state: np.ndarray
    throttle: Throttle | None
    note: str


@dataclass(frozen=True)
class LogEvent:
    """Something the log says happened: ``text`` (a DataFlash ``EV`` id as ``EV 10``, a
    ``MSG``/``STATUSTEXT``/ULog logged message), at ``time_s`` of boot ``boot``."""
    time_s: float
    boot: int
    text: str


@dataclass(frozen=True)
class ModeChange:
    """The flight mode ``mode`` (the log's name or number for it) from ``time_s`` of boot ``boot``."""
    time_s: float
    boot: int
    mode: str


@dataclass
class LogParameters:
    """``autopilot``: the strategy of the autopilot that wrote the log
    (:mod:`gyrodenoise.flightlog.autopilots`); ``values``: ``{NAME: value}``;
    ``notes``: what was odd in reading them."""
    autopilot: Any
    values: dict
    notes: list = field(default_factory=list)


@dataclass
class FlightLog:
    """One log as read by its format's adapter. ``payload``: the adapter's own
    parsed file (typed by the adapter: bytes and scan, frames, the pyulog object),
    which only the adapter reads. Messages of any type: :meth:`messages`."""
    format: Any                              # the LogFormat adapter
    path: Path
    gyro: list[GyroStream]
    facts: LogFacts
    payload: Any
    boots: list[Boot] = field(default_factory=list)
    accel: list = field(default_factory=list)   # AccelStream: the accelerometer streams the adapter reads
    options: ReadOptions = field(default_factory=ReadOptions)
    _cache: dict = field(default_factory=dict, repr=False)
    _parameters: LogParameters | None = field(default=None, repr=False)
    _events: list | None = field(default=None, repr=False)
    _modes: list | None = field(default=None, repr=False)

    @property
    def time_base(self) -> TimeBase:
        """The time base of the log's first boot (every boot of one file shares its clock)."""
        return self.boots[0].time_base if self.boots else TimeBase()

    def messages(self, name):
        """Every field of message (topic) ``name`` as ``{field: numpy column}`` plus
        ``time_s`` (on the boot's time axis) and, where the format numbers its records,
        ``record``; None when the log has no such message (cached)."""
        if name not in self._cache:
            got = self.format.messages(self, name)
            if got is not None and self.time_base.offset_s:
                got["time_s"] = got["time_s"] - self.time_base.offset_s
            self._cache[name] = got
        return self._cache[name]

    def message_names(self):
        """The message types (topics) of the log, sorted, as :meth:`messages` takes them."""
        return self.format.message_names(self)

    def boot_messages(self, name, boot):
        """:meth:`messages` of boot ``boot`` only (the rows whose ``record`` lies in it;
        all rows of a log of one boot)."""
        m = self.messages(name)
        if m is None or len(self.boots) < 2 or "record" not in m:
            return m
        keep = self.boot_of(m["record"]) == boot
        return {k: (v[keep] if isinstance(v, np.ndarray) and v.shape[:1] == keep.shape else v)
                for k, v in m.items()}

    def boot_starts(self):
        """Records at which boots 1, 2, ... begin (int64 array; empty for one boot)."""
        return np.asarray([b.first_record for b in self.boots[1:]], dtype=np.int64)

    def boot_of(self, records):
        """The boot (int array) of each of ``records`` (a message's ``record`` column,
        a gyro stream's ``index``)."""
        return np.searchsorted(self.boot_starts(), np.asarray(records), side="right")

    def events(self) -> list[LogEvent]:
        """The log's events and messages, in log order (cached; the adapter's ``events``)."""
        if self._events is None:
            self._events = self.format.events(self)
        return self._events

    def modes(self) -> list[ModeChange]:
        """The flight mode changes, in log order (cached; the adapter's ``modes``)."""
        if self._modes is None:
            self._modes = self.format.modes(self)
        return self._modes

    def rows_boot(self, m):
        """The boot (int array) of each row of message columns ``m`` (0 without ``record``)."""
        if m is None:
            return np.zeros(0, np.int64)
        n = len(m["time_s"])
        return self.boot_of(m["record"]) if "record" in m and len(self.boots) > 1 else np.zeros(n, np.int64)

    def parameters(self) -> LogParameters:
        """The autopilot and its parameters (cached; :meth:`LogFormat.parameters`)."""
        if self._parameters is None:
            self._parameters = self.format.parameters(self)
        return self._parameters


def fmt_value(v):
    """A parameter value as the lines to paste write it (37, 0.32)."""
    if v is None:
        return "?"
    if isinstance(v, float) and v.is_integer():
        return str(int(v))
    return f"{v:g}" if isinstance(v, float) else str(v)
