"""The registry of the log formats the bridge reads and writes: :data:`FORMATS`.

Each format is one adapter object (a module under :mod:`gyrodenoise.flightlog.adapters`)
with this interface (:class:`LogFormat`); nothing outside an adapter asks which
format a log is:

* ``name`` (str: the report's ``format``), ``suffixes`` (lower-case file suffixes),
  ``gyro_looked_for``, ``flight_looked_for``, ``vibration_looked_for`` (what the
  notes name when a log holds none);
* ``sniff(head: bytes) -> bool`` -- True when the first bytes of a file are this
  format (by content; the suffix decides only where no format's content matches);
* ``sniff_folder(path) -> bool`` -- True when the folder at ``path`` is one log of this
  format (a ROS 2 bag: a folder with its ``metadata.yaml``); a folder no format claims
  is a folder of logs;
* ``read(path, options: ReadOptions) -> FlightLog`` -- the typed log
  (:mod:`gyrodenoise.flightlog.model`): gyro streams, facts, boots with their time
  bases, and the adapter's own ``payload``; InputError (one line) on a file it
  cannot read;
* ``write_filtered(log, path, link=None) -> dict`` -- the filtered copy (the gyro
  fields patched with each stream's ``filtered``, every other byte kept; a format that
  cannot be patched writes the filtered streams and says so); the report's fields on
  the writing; ``filtered_name(path, stem)`` -- its file name;
* ``signing(log, key) -> LinkSigning | None`` and ``keep_signed_raw(log, link)`` --
  a format with signed packets checks them (others return None / do nothing);
* ``messages(log, name) -> dict | None`` and ``message_names(log) -> list`` -- any
  message as numpy columns (``time_s`` on the log's clock, ``record`` where the
  format numbers its records as the gyro streams' ``index``);
* ``flight_evidence(log, boot, autopilot) -> FlightEvidence | str`` -- arming, in the
  air and throttle in one boot (a str: what was looked for, when it holds none);
* ``vibration_levels(log)``, ``accelerometer(log)`` -- the vibration review's sources
  (:mod:`gyrodenoise.flightlog.vibration`), None where the format has none;
* ``parameters(log) -> LogParameters`` -- the autopilot and its parameters;
* ``events(log)``, ``modes(log)`` -- the log's events and messages (``LogEvent``) and its
  flight mode changes (``ModeChange``), in log order;
* ``vehicle_rate(log, streams) -> list`` -- the vehicle's own body-rate estimate for
  the HTML report (empty where none).

An adapter derives from :class:`gyrodenoise.flightlog.adapters.BaseFormat`, which
answers for the parts a format lacks (no signing, messages, flight evidence, vibration
source, events or rate estimate). A new format (a Betaflight blackbox, a ROS bag) is one
adapter module and one line in :data:`FORMATS`; :func:`read_log` never sends a file to a format whose ``sniff``
(or suffix) did not claim it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog.adapters import blackbox as _blackbox
from gyrodenoise.flightlog.adapters import dataflash as _dataflash
from gyrodenoise.flightlog.adapters import rosbag as _rosbag
from gyrodenoise.flightlog.adapters import tlog as _tlog
from gyrodenoise.flightlog.adapters import ulog as _ulog
from gyrodenoise.flightlog.model import FlightLog, ReadOptions

#: bytes read from the start of a file for ``sniff``
HEAD_BYTES = 600


class LogFormat(Protocol):
    """The adapter interface of a log format (see the module doc)."""
    name: str
    description: str
    suffixes: tuple
    gyro_looked_for: str
    flight_looked_for: str
    vibration_looked_for: str

    def sniff(self, head: bytes) -> bool: ...
    def sniff_folder(self, path) -> bool: ...
    def read(self, path, options: ReadOptions) -> FlightLog: ...
    def write_filtered(self, log: FlightLog, path, link=None) -> dict: ...
    def filtered_name(self, path, stem) -> str: ...
    def signing(self, log: FlightLog, key): ...
    def keep_signed_raw(self, log: FlightLog, link) -> None: ...
    def messages(self, log: FlightLog, name): ...
    def message_names(self, log: FlightLog) -> list: ...
    def flight_evidence(self, log: FlightLog, boot: int, autopilot): ...
    def vibration_levels(self, log: FlightLog): ...
    def accelerometer(self, log: FlightLog): ...
    def attitude(self, log: FlightLog): ...
    def rate_setpoint(self, log: FlightLog) -> list: ...
    def identity(self, log: FlightLog) -> dict: ...
    def parameters(self, log: FlightLog): ...
    def events(self, log: FlightLog) -> list: ...
    def modes(self, log: FlightLog) -> list: ...
    def vehicle_rate(self, log: FlightLog, streams) -> list: ...


#: every format the bridge reads, sniffed in this order
FORMATS: tuple[LogFormat, ...] = (_dataflash.FORMAT, _ulog.FORMAT, _tlog.FORMAT,
                                  _rosbag.FORMAT, _blackbox.FORMAT)
#: file suffix -> the name of its format (a folder's log files are found by these)
LOG_SUFFIXES = {sfx: f.name for f in FORMATS for sfx in f.suffixes}


def format_named(name) -> LogFormat:
    """The adapter of format ``name`` (``"tlog"``, ``"dataflash"``, ``"ulog"``)."""
    for f in FORMATS:
        if f.name == name:
            return f
    raise InputError(f"unknown log format {name!r} (known: {', '.join(f.name for f in FORMATS)})")


def folder_format(path) -> LogFormat | None:
    """The format that claims the folder at ``path`` as one log (``sniff_folder``), or None."""
    return next((f for f in FORMATS if f.sniff_folder(path)), None)


def log_format(path) -> LogFormat:
    """The format of the file at ``path``: the first whose ``sniff`` claims its first
    bytes, else the one its suffix names; of a folder, the one that claims it as a log
    (:func:`folder_format`); InputError when none does."""
    p = Path(path)
    if p.is_dir():
        fmt = folder_format(p)
        if fmt is None:
            raise InputError(f"{path}: a folder that is no log (no format claims it: a ROS 2 bag "
                             f"has a metadata.yaml)")
        return fmt
    try:
        with open(p, "rb") as fh:
            head = fh.read(HEAD_BYTES)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    for f in FORMATS:
        if f.sniff(head):
            return f
    suffix = p.suffix.lower()
    for f in FORMATS:
        if suffix in f.suffixes:
            return f
    raise InputError(f"{path}: unknown file type (expected "
                     + ", ".join(f"{f.description} {'/'.join(f.suffixes)}" for f in FORMATS) + ")")


def sniffed(path) -> LogFormat | None:
    """The format whose ``sniff`` claims the first bytes of the regular file at ``path``,
    or None (also when it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(HEAD_BYTES)
    except OSError:
        return None
    return next((f for f in FORMATS if f.sniff(head)), None)


def log_kind(path) -> str:
    """The name of the format a file is named as: by its suffix where a format claims it
    (the name alone: a URL, a file not fetched yet), else by its content
    (:func:`log_format`; InputError when neither tells). Reading goes by content."""
    name = LOG_SUFFIXES.get(Path(path).suffix.lower())
    return name if name else log_format(path).name


def read_log(path, fmt: LogFormat | None = None, options: ReadOptions | None = None) -> FlightLog:
    """The :class:`FlightLog` of the file at ``path`` (its format from
    :func:`log_format` unless given). InputError when it has no gyro stream."""
    fmt = fmt or log_format(path)
    log = fmt.read(Path(path), options or ReadOptions())
    if not log.gyro:
        raise InputError(f"{path}: no gyro stream (looked for {fmt.gyro_looked_for})")
    return log
