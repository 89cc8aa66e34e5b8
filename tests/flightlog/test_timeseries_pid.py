"""The rate controller's PID terms as time panels (the strategy's ``pid_terms``): a SYNTHETIC
ArduCopter log's PIDR/PIDP/PIDY P, I, D, FF read back equal to what was written, one panel
per axis; a log without them says what was looked for."""
from __future__ import annotations

import numpy as np

from gyrodenoise.flightlog.timeseries import time_views

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import DataFlashWriter


def _log(with_pid=True):
    rng = np.random.default_rng(5)
    w = DataFlashWriter()
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    names = ("PIDR", "PIDP", "PIDY") if with_pid else ()
    for n in names:
        w.define(n, "Qffffff", ["TimeUS", "Tar", "Act", "P", "I", "D", "FF"])
    written = {n: [] for n in names}
    for j in range(2000):
        us = 1_000_000 + j * 2500
        w.add("IMU", us, 0, 0.0, 0.0, 0.0, 0.0, 0.0, -9.8)
        if j % 4 == 0:
            for n in names:
                row = rng.normal(0, 0.1, 4).astype(np.float32)
                w.add(n, us, 0.0, 0.0, *row)
                written[n].append(row)
    return log_of_bytes(w.bytes(), "dataflash"), {n: np.array(v) for n, v in written.items()}


def test_pid_terms_read_back_equal_one_panel_per_axis():
    log, written = _log()
    panels = [p for p in time_views(log).panels if p.key == "pid"]
    assert [p.title.split(" [")[0] for p in panels] == [f"rate PID terms, {a}" for a in ("roll", "pitch", "yaw")]
    for p, n in zip(panels, ("PIDR", "PIDP", "PIDY")):
        assert list(p.channels.columns) == ["P", "I", "D", "FF"]
        got = np.stack([p.channels.columns[c] for c in ("P", "I", "D", "FF")], 1)
        np.testing.assert_array_equal(got, written[n])


def test_no_pid_terms_said():
    log, _ = _log(with_pid=False)
    views = time_views(log)
    assert not [p for p in views.panels if p.key == "pid"]
    assert views.missing["pid"] == "no rate controller terms in the log (looked for PIDR, PIDP, PIDY (P, I, D, FF))"
