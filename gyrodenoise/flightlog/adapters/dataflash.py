"""ArduPilot DataFlash ``.bin``: the adapter (:mod:`gyrodenoise.flightlog.formats`).

Boots: a DataFlash file can hold several (a log downloaded whole, logs concatenated):
:func:`gyrodenoise.flightlog.logdata.dataflash_boot_starts`; each boot's ``time_s`` is
its own boot time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gyrodenoise.flightlog import overview, step_response, dataflash, events, impact, logdata, parameters, segments, vehicle_rate, vibration
from gyrodenoise.flightlog.adapters import BaseFormat
from gyrodenoise.flightlog.model import Boot, FlightLog, LogFacts, number_instances


class DataFlashFormat(BaseFormat):
    name = "dataflash"
    description = "an ArduPilot DataFlash log"
    suffixes = (".bin",)
    setpoint_looked_for = "RATE RDes/R, PDes/P, YDes/Y"
    gyro_looked_for = "IMU, IMU2, IMU3 with GyrX/GyrY/GyrZ, ISBH/ISBD gyro bursts"
    flight_looked_for = ("ARM.ArmState, EV (ARMED/DISARMED/NOT_LANDED/LAND_COMPLETE), CTUN.ThO/ThrOut, "
                         "RCOU C1..C4, GPS Spd/Alt, ARSP.Airspeed")
    vibration_looked_for = "VIBE (VibeX/Y/Z, Clip), IMU AccX/AccY/AccZ"

    def sniff(self, head):
        return head[:2] == bytes((dataflash.HEAD1, dataflash.HEAD2))

    def read(self, path, options):
        data, sc, streams = dataflash.read(path)
        facts = LogFacts(messages=sc.n_messages, unreadable_records=len(sc.bad_regions),
                         unreadable_bytes=sc.bad_bytes, truncated_bytes=sc.truncated_bytes,
                         truncation="message cut by the end of the file" if sc.truncated_bytes else None,
                         streams_skipped=sc.skipped)
        log = FlightLog(format=self, path=Path(path), gyro=number_instances(streams), facts=facts,
                        payload=logdata.DataFlashFile(data, sc))
        for s in streams:
            if s.message == "ISBD":           # batch-sampler index: ISBD offset * 32 + position in its arrays
                s.records = s.index // 32
        log.boots = _boots(log)
        return log

    def write_filtered(self, log, path, link=None):
        Path(path).write_bytes(dataflash.patch(log.payload.data, log.payload.scan, log.gyro))
        return {}

    def messages(self, log, name):
        return logdata.dataflash_messages(log.payload, name)

    def message_names(self, log):
        return logdata.dataflash_message_names(log.payload)

    def flight_evidence(self, log, boot, autopilot):
        return segments.dataflash_evidence(log, boot, self.flight_looked_for)

    def vibration_levels(self, log):
        return vibration.dataflash_levels(log)

    def rate_setpoint(self, log):
        return step_response.dataflash_rate_setpoint(log, log.gyro)

    def identity(self, log):
        return overview.ardupilot_identity(log)

    def accelerometer(self, log):
        return vibration.dataflash_accel(log)

    def attitude(self, log):
        return impact.dataflash_attitude(log)

    def events(self, log):
        return events.dataflash_events(log)

    def modes(self, log):
        return events.dataflash_modes(log)

    def parameters(self, log):
        return parameters.dataflash_parameters(log)

    def vehicle_rate(self, log, streams):
        return vehicle_rate.dataflash_rate_series(log, streams)


def _boots(log):
    """The boots of a DataFlash log, each on its own boot time."""
    starts = logdata.dataflash_boot_starts(log.payload)
    a, t = log.payload.anchors
    edges = np.concatenate([[0], starts, [np.iinfo(np.int64).max]])
    out = []
    for k in range(len(edges) - 1):
        sel = (a >= edges[k]) & (a < edges[k + 1]) & np.isfinite(t)
        span = (float(t[sel].min()), float(t[sel].max())) if sel.any() else (np.nan, np.nan)
        out.append(Boot(index=k, first_record=int(edges[k]), start_s=span[0], end_s=span[1]))
    return out


FORMAT = DataFlashFormat()
