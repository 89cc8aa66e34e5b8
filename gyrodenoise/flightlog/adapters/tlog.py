"""MAVLink telemetry logs ``.tlog``: the adapter (:mod:`gyrodenoise.flightlog.formats`).

Boots: where the vehicle's ``time_boot_ms`` steps back in file order
(:func:`gyrodenoise.flightlog.logdata.tlog_boot_starts`); each boot's wall-clock
offset is the median of (record stamp - boot time) over its records that carry a
``time_boot_ms`` (the ground station's clock, as it logged them).

A gyro message whose ``time_usec`` is a Unix epoch time (above 1e12 us) is put on
the boot time: minus its boot's offset, the median of (``time_usec`` - the boot time
its record's stamp gives it, as for any message without a time of its own), which
keeps the vehicle's own clock steps; without any ``time_boot_ms`` in the log its
times stay on the epoch clock, moved to start at 0, and the log's time base says so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog import overview, events, logdata, parameters, segments, tlog, vibration
from gyrodenoise.flightlog.adapters import BaseFormat
from gyrodenoise.flightlog.model import EPOCH_US_MIN, UNIX_EPOCH, Boot, FlightLog, LogFacts, TimeBase, number_instances
from gyrodenoise.flightlog.signing import LinkSigning

EPOCH_S_MIN = EPOCH_US_MIN * 1e-6


class TelemetryFormat(BaseFormat):
    name = "tlog"
    description = "a MAVLink telemetry log"
    suffixes = (".tlog", ".mavlink")
    setpoint_looked_for = "nothing: not read from telemetry logs"
    gyro_looked_for = "RAW_IMU, SCALED_IMU, SCALED_IMU2, SCALED_IMU3, HIGHRES_IMU"
    flight_looked_for = ("HEARTBEAT (base_mode armed bit, system_status) of the vehicle, "
                         "EXTENDED_SYS_STATE.landed_state")
    vibration_looked_for = "VIBRATION (vibration_x/y/z, clipping_0..2)"

    def sniff(self, head):
        return tlog.looks_like_tlog(head)

    def read(self, path, options):
        data, fr, streams = tlog.read(path, options.raw_imu_unit, options.raw_imu_scale)
        facts = LogFacts(messages=int(fr.ok.sum()), unreadable_records=fr.n_unreadable,
                         unreadable_bytes=int(fr.length[~fr.ok].sum()) + sum(e - s for s, e in fr.bad_regions),
                         truncated_bytes=fr.truncated_bytes,
                         truncation=("zero-filled tail" if fr.zero_tail else
                                     "record cut by the end of the file" if fr.truncated_bytes else None))
        log = FlightLog(format=self, path=Path(path), gyro=number_instances(streams), facts=facts,
                        payload=logdata.TelemetryFile(data, fr), options=options)
        log.boots = _boots(log)
        _epoch_streams(log)
        return log

    def write_filtered(self, log, path, link=None):
        p = log.payload
        if link is not None:
            tlog.write_filtered(p.data, p.frames, log.gyro, path, link)
            return link.report()
        return {"signatures_dropped": tlog.write_filtered(p.data, p.frames, log.gyro, path)}

    def signing(self, log, key):
        """The link's signing state once every packet went through the check of ``key``;
        the gyro streams without the rejected packets. InputError when the key verifies
        none of the log's signed packets (a wrong key), or no gyro packet is left."""
        link = LinkSigning(key)
        p = log.payload
        tlog.check_signatures(p.data, p.frames, link)
        if link.key is None or not p.frames.rejected.any():
            return link
        if link.signed and not (p.frames.signed & p.frames.usable).any():
            raise InputError(f"{log.path}: none of its {link.signed} signed packets verifies under the "
                             f"--signing-key (a wrong key, or a passphrase other than the link's?)")
        log.gyro = number_instances(tlog.gyro_streams(p.data, p.frames, log.options.raw_imu_unit,
                                                       log.options.raw_imu_scale))
        _epoch_streams(log)
        log._cache.clear()
        if not log.gyro:
            raise InputError(f"{log.path}: no gyro stream is left once the {link.n_rejected} packets that fail "
                             f"the signature check are taken out")
        return link

    def keep_signed_raw(self, log, link):
        tlog.keep_signed_raw(log.payload.frames, log.gyro, link)

    def messages(self, log, name):
        return logdata.tlog_messages(log.payload, name)

    def message_names(self, log):
        return logdata.tlog_message_names(log.payload)

    def flight_evidence(self, log, boot, autopilot):
        return segments.tlog_evidence(log, boot, autopilot, self.flight_looked_for)

    def identity(self, log):
        return overview.ardupilot_identity(log)

    def vibration_levels(self, log):
        return vibration.tlog_levels(log)

    def events(self, log):
        return events.tlog_events(log)

    def modes(self, log):
        return events.tlog_modes(log)

    def parameters(self, log):
        return parameters.tlog_parameters(log)


def _boots(log):
    starts = logdata.tlog_boot_starts(log.payload)
    anchors = logdata._tlog_anchors(log.payload)
    edges = np.concatenate([[0], starts, [np.iinfo(np.int64).max]])
    out = []
    for k in range(len(edges) - 1):
        lo = hi = np.nan
        offsets = []
        for idx, boot, wall in anchors.values():
            sel = (idx >= edges[k]) & (idx < edges[k + 1])
            if sel.any():
                lo = np.nanmin([lo, boot[sel].min()])
                hi = np.nanmax([hi, boot[sel].max()])
                offsets.append(wall[sel] * 1e-6 - boot[sel])
        wall_off = round(float(np.median(np.concatenate(offsets))), 3) if offsets else None
        out.append(Boot(index=k, first_record=int(edges[k]), start_s=float(lo), end_s=float(hi),
                        wall_clock_offset_s=wall_off))
    return out


def _epoch_streams(log):
    """Gyro streams timed by a Unix epoch ``time_usec``: onto their boot's time (see the
    module doc), or -- with no boot time in the log -- the log's time base made the epoch."""
    epoch = [s for s in log.gyro if s.n and np.nanmedian(s.time_s) > EPOCH_S_MIN]
    if not epoch:
        return
    unplaced = []
    for s in epoch:
        m = log.format.messages(log, s.message)
        t_boot = np.full(s.n, np.nan)
        if m is not None:
            pos = np.clip(np.searchsorted(m["record"], s.index), 0, len(m["record"]) - 1)
            hit = m["record"][pos] == s.index
            t_boot[hit] = m["time_s"][pos[hit]]
        boots = log.boot_of(s.index)
        t = s.time_s.copy()
        placed = True
        for k in np.unique(boots).tolist():
            sel = boots == k
            off = np.nanmedian(s.time_s[sel] - t_boot[sel]) if np.isfinite(t_boot[sel]).any() else np.nan
            if not np.isfinite(off):
                placed = False
                break
            t[sel] = s.time_s[sel] - off
        if placed:
            s.time_s = t
            s.note = (s.note + "; " if s.note else "") + ("time_usec is a Unix time: put on the boot time by "
                                                          "the records' stamps")
        else:
            unplaced.append(s)
    if unplaced:
        offset = float(min(np.nanmin(s.time_s) for s in unplaced))
        for s in unplaced:
            s.time_s = s.time_s - offset
        base = TimeBase(UNIX_EPOCH, offset)
        log.boots = [Boot(b.index, b.first_record, b.start_s, b.end_s, base, offset) for b in log.boots]


FORMAT = TelemetryFormat()
