"""Flight logs for the tests, as :class:`gyrodenoise.flightlog.model.FlightLog`: a shared
log by name, or bytes built in memory (read through the format's adapter, which does
not ask for a gyro stream as :func:`gyrodenoise.flightlog.formats.read_log` does)."""
from __future__ import annotations

import tempfile
from pathlib import Path

from gyrodenoise.flightlog import formats
from gyrodenoise.flightlog.model import ReadOptions

from tests.helpers import shared_log


def shared_flight_log(name):
    """The :class:`FlightLog` of shared log ``name``."""
    return formats.read_log(shared_log(name))


def log_of_bytes(data, fmt_name):
    """The :class:`FlightLog` of the bytes ``data`` of format ``fmt_name`` ("dataflash", "tlog", "ulog")."""
    fmt = formats.format_named(fmt_name)
    path = Path(tempfile.mkdtemp(prefix="gd_log_")) / f"log{fmt.suffixes[0]}"
    path.write_bytes(bytes(data))
    return fmt.read(path, ReadOptions())
