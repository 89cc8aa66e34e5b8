"""One adapter per log format (the interface: :mod:`gyrodenoise.flightlog.formats`).

:class:`BaseFormat` gives what a format that lacks a part answers (no signing, no
messages, no flight evidence, no vibration source, no events, no rate estimate; no log that is a folder): an
adapter implements ``sniff``, ``read``, ``write_filtered`` and ``parameters``, and
overrides the rest where its logs hold them.
"""

from __future__ import annotations

from pathlib import Path


class BaseFormat:
    """Defaults of the adapter interface for what a format does not have."""
    name = description = ""
    suffixes: tuple = ()
    gyro_looked_for = flight_looked_for = vibration_looked_for = setpoint_looked_for = ""

    def sniff_folder(self, path):
        return False

    def filtered_name(self, path, stem):
        """The file name of the filtered copy of the log at ``path``: ``STEM.filtered`` and its
        suffix (none for a log that is a folder)."""
        path = Path(path)
        return f"{stem}.filtered" + ("" if path.is_dir() else path.suffix or self.suffixes[0])

    def signing(self, log, key):
        return None

    def keep_signed_raw(self, log, link):
        return None

    def messages(self, log, name):
        return None

    def message_names(self, log):
        return []

    def flight_evidence(self, log, boot, autopilot):
        return f"no flight evidence in the log (looked for {self.flight_looked_for or 'nothing: not read'})"

    def vibration_levels(self, log):
        return None

    def accelerometer(self, log):
        return None

    def identity(self, log):
        """``{"vehicle", "firmware", "board", "frame", "vehicle_id"}`` as the log names them
        (:mod:`gyrodenoise.flightlog.overview`); empty: not told."""
        return {}

    def rate_setpoint(self, log):
        """``[{"boot", "source", "time_s", "setpoint": (n, 3) deg/s, "rate": (n, 3) deg/s}]``
        (:mod:`gyrodenoise.flightlog.step_response`); empty: not logged."""
        return []

    def attitude(self, log):
        """``{"source", "time_s", "record", "roll_deg", "pitch_deg"}`` or None (not logged)."""
        return None

    def events(self, log):
        return []

    def modes(self, log):
        return []

    def vehicle_rate(self, log, streams):
        return []
