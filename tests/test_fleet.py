"""The fleet report's judgements (bridge/fleet.py) on hand-made summaries whose
answer is known: which stream is flagged, and what the flag says."""
import math

from bridge.fleet import fleet_rows, format_table

FS = 25.0


def _stream(name, density, all_zero=False):
    """A stream whose white-noise density is ``density`` deg/s/sqrt(Hz) at FS:
    the bridge's noise figure is sqrt(2) sigma, sigma = density sqrt(FS / 2)."""
    noise = 0.0 if all_zero else density * math.sqrt(FS / 2.0) * math.sqrt(2.0)
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
