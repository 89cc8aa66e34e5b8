"""PX4 ULog ``.ulg``: the adapter (:mod:`gyrodenoise.flightlog.formats`).

One boot per file. Its clock: ``timestamp`` in us since boot, or -- PX4 SITL logs
-- a Unix epoch time (above 1e12 us): then every time is moved to start at 0 at
the log's start (``start_timestamp``) and the time base says so, with the epoch
time of that 0 as the boot's wall-clock offset.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gyrodenoise.flightlog import overview, step_response, events, impact, logdata, parameters, segments, ulog, vehicle_rate, vibration
from gyrodenoise.flightlog.adapters import BaseFormat
from gyrodenoise.flightlog.model import EPOCH_US_MIN, UNIX_EPOCH, Boot, FlightLog, LogFacts, TimeBase, number_instances

MAGIC = b"ULog\x01\x12\x35"


class ULogFormat(BaseFormat):
    name = "ulog"
    description = "a PX4 log"
    suffixes = (".ulg",)
    setpoint_looked_for = "vehicle_rates_setpoint, vehicle_angular_velocity"
    gyro_looked_for = "sensor_combined.gyro_rad, sensor_gyro, sensor_gyro_fifo"
    flight_looked_for = ("vehicle_status.arming_state, actuator_armed.armed, vehicle_land_detected.landed, "
                         "vehicle_gps_position vel_m_s/alt, airspeed")
    vibration_looked_for = "vehicle_imu_status (accel_vibration_metric...), sensor_combined.accelerometer_m_s2"

    def sniff(self, head):
        return head[:7] == MAGIC

    def read(self, path, options):
        u, streams, refs = ulog.read(path)
        cut = ulog.truncated_bytes(path)
        facts = LogFacts(messages=sum(len(next(iter(d.data.values()), ())) for d in u.data_list),
                         streams_skipped=refs.skipped,
                         unreadable_records=None,
                         data_corruption=bool(getattr(u, "file_corruption", False)),
                         truncated_bytes=max(cut, 0),
                         truncation="message cut by the end of the file" if cut > 0 else None)
        log = FlightLog(format=self, path=Path(path), gyro=number_instances(streams), facts=facts,
                        payload=logdata.ULogFile(u, refs), options=options)
        start_us = float(u.start_timestamp)
        base = TimeBase()
        if start_us > EPOCH_US_MIN or any(s.n and np.nanmedian(s.time_s) > EPOCH_US_MIN * 1e-6 for s in streams):
            offset = start_us * 1e-6 if start_us > EPOCH_US_MIN else \
                float(min(np.nanmin(s.time_s) for s in streams if s.n))
            base = TimeBase(UNIX_EPOCH, offset)
            for s in streams:
                s.time_s = s.time_s - offset
        t0 = start_us * 1e-6 - base.offset_s
        ends = [float(np.nanmax(s.time_s)) for s in streams if s.n]
        log.accel = ulog.accel_streams(refs)
        for a in log.accel:
            a.time_s = a.time_s - base.offset_s
        log.boots = [Boot(index=0, first_record=0, start_s=t0, end_s=max(ends) if ends else np.nan,
                          time_base=base, wall_clock_offset_s=base.offset_s if base.kind == UNIX_EPOCH else None)]
        return log

    def write_filtered(self, log, path, link=None):
        ulog.write_filtered(log.payload.ulog, log.gyro, log.payload.refs, path)
        return {}

    def messages(self, log, name):
        return logdata.ulog_messages(log.payload, name)

    def message_names(self, log):
        return logdata.ulog_message_names(log.payload)

    def flight_evidence(self, log, boot, autopilot):
        return segments.ulog_evidence(log, self.flight_looked_for)

    def vibration_levels(self, log):
        return vibration.ulog_levels(log)

    def rate_setpoint(self, log):
        return step_response.ulog_rate_setpoint(log)

    def identity(self, log):
        return overview.ulog_identity(log)

    def accelerometer(self, log):
        return vibration.ulog_accel(log)

    def attitude(self, log):
        return impact.ulog_attitude(log)

    def events(self, log):
        return events.ulog_events(log)

    def modes(self, log):
        return events.ulog_modes(log)

    def parameters(self, log):
        return parameters.ulog_parameters(log)

    def vehicle_rate(self, log, streams):
        return vehicle_rate.ulog_rate_series(log)


FORMAT = ULogFormat()
