"""The fleet report's judgements (gyrodenoise/flightlog/fleet.py) on hand-made summaries whose
answer is known: which stream is flagged, and what the flag says."""
import math

import numpy as np
import pytest

from gyrodenoise.flightlog.fleet import fleet_rows, format_table, noise_density, write_fleet_report
from gyrodenoise.flightlog.streams import noise_per_axis
from tests.helpers import SHARED_DATA

SHARED_LOGS = SHARED_DATA / "logs"

FS = 25.0


def _stream(name, density, all_zero=False):
    """A stream whose white-noise density is ``density`` deg/s/sqrt(Hz) at FS:
    the bridge's noise figure is sigma (std of first differences / sqrt 2),
    sigma = density sqrt(FS / 2)."""
    noise = 0.0 if all_zero else density * math.sqrt(FS / 2.0)
    return {"name": name, "samples": 1000, "rate_hz": FS, "restarts": 0, "noise_unit": "deg/s",
            "noise": {a: {"raw": noise, "filtered": noise, "ratio": 1.0} for a in "xyz"},
            "motion": {}, "warnings": [], "all_zero": all_zero}


def _summary(logs):
    return {"logs": [{"file": f"/logs/{name}", "streams": streams} for name, streams in logs],
            "failed": [], "n_logs": len(logs), "n_ok": len(logs), "n_failed": 0}


def test_one_noisy_imu_beside_normal_siblings_is_that_imu():
    logs = [(f"ok{i}.bin", [_stream("IMU[0]", 0.010 + 0.001 * i), _stream("IMU[1]", 0.011 + 0.001 * i)])
            for i in range(5)]
    logs.append(("sick.bin", [_stream("IMU[0]", 0.011), _stream("IMU[1]", 0.30)]))
    rows = fleet_rows(_summary(logs))
    flagged = [(r["log"], r["stream"]) for r in rows if r.get("flag")]
    assert flagged == [("sick.bin", "IMU[1]")]
    why = next(r["flag_why"] for r in rows if r.get("flag"))
    assert "sibling IMU(s) in this log normal: this IMU" in why


def test_all_imus_of_one_log_noisy_together_points_at_the_vehicle():
    logs = [(f"ok{i}.bin", [_stream("IMU[0]", 0.010 + 0.001 * i), _stream("IMU[1]", 0.011 + 0.001 * i)])
            for i in range(5)]
    logs.append(("shaky.bin", [_stream("IMU[0]", 0.24), _stream("IMU[1]", 0.24)]))
    rows = fleet_rows(_summary(logs))
    flagged = [r for r in rows if r.get("flag")]
    assert [(r["log"], r["stream"]) for r in flagged] == [("shaky.bin", "IMU[0]"), ("shaky.bin", "IMU[1]")]
    assert all("vehicle vibration or motion more likely than a sick IMU" in r["flag_why"] for r in flagged)
    assert "more likely than a sick IMU" in format_table(rows)


def test_an_all_zero_stream_is_said_dead_not_ok():
    logs = [(f"ok{i}.bin", [_stream("IMU[0]", 0.01)]) for i in range(3)]
    logs.append(("dead.bin", [_stream("IMU[0]", 0.01), _stream("IMU[1]", 0.0, all_zero=True)]))
    rows = fleet_rows(_summary(logs))
    dead = [r for r in rows if r.get("all_zero")]
    assert [(r["log"], r["stream"]) for r in dead] == [("dead.bin", "IMU[1]")]
    line = next(x for x in format_table(rows).splitlines() if "dead.bin | IMU[1]" in x)
    assert "ALL ZERO: no data (sensor absent or dead)" in line


def _welch_density(x, fs):
    """Independent reference: sqrt of the mean one-sided PSD (scipy's Welch, Hann,
    1 s segments), deg/s/sqrt(Hz), over the band above 2 Hz (no motion there at rest)."""
    from scipy.signal import welch
    f, pxx = welch(x - np.mean(x), fs=fs, nperseg=min(len(x), int(fs)))
    return float(np.sqrt(np.mean(pxx[f > 2.0])))


def test_density_equals_welch_on_white_noise():
    """The fleet's density is the one-sided density of the bridge's noise figure (itself
    std(diff) / sqrt 2, no second sqrt 2). White noise of known density, seeded: the fleet's
    figure, Welch's estimate and the truth agree within 3 %."""
    rng = np.random.default_rng(21)
    fs, density = 400.0, 0.02                         # deg/s/sqrt(Hz)
    x = rng.normal(0.0, density * math.sqrt(fs / 2.0), 200_000)
    noise = noise_per_axis(x[:, None], None)[0]
    got = noise_density(noise, fs)
    assert got == pytest.approx(density, rel=0.03)
    assert got == pytest.approx(_welch_density(x, fs), rel=0.03)


def test_density_of_a_real_static_log_equals_welch():
    """A disarmed copter log (IMU[0]: 0.00463 printed, Welch
    0.0058-0.0066): the fleet's density per axis within 15 % of Welch's above 2 Hz."""
    from gyrodenoise.flightlog import dataflash
    from gyrodenoise.flightlog.streams import detect_restarts
    path = SHARED_LOGS / "copter_2021-12-08_15-42-00.bin"
    if not path.exists():
        pytest.skip(f"third-party log not present: {path}")
    _, _, streams = dataflash.read(path)
    s = next(s for s in streams if s.name == "IMU[0]")
    detect_restarts(s)
    x, _, _ = s.work_units()
    for k, got in enumerate(noise_per_axis(x, s.restarts)):
        ref = _welch_density(x[:, k], s.rate_hz)
        assert noise_density(got, s.rate_hz) == pytest.approx(ref, rel=0.15), k


def _slow(name, noise):
    return {"name": name, "samples": 300, "rate_hz": 1.0, "restarts": 0, "noise_unit": "deg/s",
            "noise": {a: {"raw": noise, "filtered": noise, "ratio": None} for a in "xyz"},
            "motion": {a: None for a in "xyz"}, "warnings": [], "too_slow_to_denoise": True}


def test_old_and_new_dataflash_imu_names_are_one_fleet():
    """A log naming its first IMU "IMU" (Copter 3.3) is compared with
    logs naming it "IMU[0]" (4.x): at 7x a flagged-looking log's density it is flagged."""
    logs = [(f"ok{i}.bin", [_stream("IMU[0]", 0.010 + 0.002 * i)]) for i in range(4)]
    logs.append(("old.bin", [_stream("IMU", 0.30)]))
    rows = fleet_rows(_summary(logs))
    old = next(r for r in rows if r["log"] == "old.bin")
    assert old["compared_as"] == "IMU[0]" and old["flag"] and old["fleet_size"] == 5
    assert old["density_vs_fleet_median"] == pytest.approx(0.30 / 0.014)


def test_table_labels_rates_and_slow_rows(tmp_path):
    """The noise columns say what they average; 2002 Hz is not
    printed 2e+03; a telemetry row reads as written raw, not as an improvement; the
    plot's title names why logs are left to the table."""
    fast = dict(_stream("ISB.gyro[0]", 0.002), rate_hz=2001.6)
    logs = [("a.bin", [fast]), ("t.tlog", [_slow("RAW_IMU", 7.4)])]
    paths = write_fleet_report(_summary(logs), tmp_path)
    md = paths[0].read_text()
    header = next(x for x in md.splitlines() if x.startswith("| log |"))
    assert "mean of the x, y, z figures" in header
    line = next(x for x in md.splitlines() if "| a.bin |" in x)
    assert "| 2002 |" in line and "e+0" not in line
    line = next(x for x in md.splitlines() if "| t.tlog |" in x)
    assert "7.4 deg/s (written raw)" in line and "->" not in line
    assert "too slow to denoise (1 Hz < 20 Hz): written raw" in line
    assert paths[2].read_bytes().endswith(b"IEND\xaeB`\x82")
    from gyrodenoise.flightlog.fleet import plot_title
    title = plot_title(fleet_rows(_summary(logs)))
    assert "1 log(s) with telemetry streams only, below 20 Hz" in title and "no stream to denoise" not in title


def _row(log, stream, density):
    return {"log": log, "stream": stream, "status": "ok", "compared_as": stream, "noise_unit": "deg/s",
            "noise_density_deg_s_rthz": density, "too_slow_to_denoise": density is None}


def test_fleet_median_cell_says_why_it_is_empty():
    """A stream with no peer (the only ISB.gyro[0] of the fleet), one with a single
    peer, and one with no density: the "x fleet median" cell says why."""
    from gyrodenoise.flightlog.fleet import _flag, vs_fleet_text
    rows = [_row("a.bin", "IMU[0]", 0.01), _row("b.bin", "IMU[0]", 0.011), _row("c.bin", "IMU[0]", 0.012),
            _row("a.bin", "ISB.gyro[0]", 0.001), _row("a.bin", "IMU[1]", 0.02), _row("b.bin", "IMU[1]", 0.02),
            _row("a.tlog", "RAW_IMU", None)]
    _flag(rows)
    cells = [vs_fleet_text(r) for r in rows]
    assert cells[0] == "0.91x of 3 IMU[0]"
    assert cells[3] == "no peer: the only ISB.gyro[0] with a density in the fleet"
    assert cells[4] == "only 2 IMU[1] with a density in the fleet (a median needs 3)"
    assert cells[6] == "no density: too slow to denoise"
