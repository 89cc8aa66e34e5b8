"""Step response (gyrodenoise.flightlog.step_response) on SYNTHETIC closed-loop data of
known response: a second-order rate loop (natural frequency, damping, a pure delay)
driven by random setpoint steps, its output with gyro noise; the Wiener deconvolution
recovers its rise time, delay and overshoot within stated tolerances. Then through the
adapters: a synthetic DataFlash RATE log and the shared logs."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from gyrodenoise.flightlog.step_response import step_response

FS = 500.0


def _loop(wn_hz, zeta, delay_s):
    """The discrete loop (zero-order hold of the continuous second-order system) and a delay in samples."""
    wn = 2 * np.pi * wn_hz
    b, a, _ = signal.cont2discrete(([wn * wn], [1, 2 * zeta * wn, wn * wn]), 1 / FS, method="zoh")
    return np.ravel(b), a, int(round(delay_s * FS))


def _truth(wn_hz, zeta, delay_s):
    """(rise 10-90 %, delay to 50 %, overshoot %) of the loop's own unit step response."""
    b, a, d = _loop(wn_hz, zeta, delay_s)
    y = signal.lfilter(b, a, np.concatenate([np.zeros(d), np.ones(int(FS))]))
    t = np.arange(len(y)) / FS

    def cross(level):
        i = np.flatnonzero(y >= level)[0]
        return t[i - 1] + (level - y[i - 1]) / (y[i] - y[i - 1]) / FS
    return cross(0.9) - cross(0.1), cross(0.5), (y.max() - 1) * 100


def _flight(wn_hz, zeta, delay_s, seconds=120.0, noise_dps=5.0, seed=1):
    """Random setpoint steps (hold 0.1-0.6 s, +-300 deg/s) through the loop, gyro noise added."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    sp = np.zeros(n)
    i = 0
    while i < n:
        k = int(rng.uniform(0.1, 0.6) * FS)
        sp[i:i + k] = rng.uniform(-300, 300) if rng.random() < 0.7 else 0.0
        i += k
    b, a, d = _loop(wn_hz, zeta, delay_s)
    y = signal.lfilter(b, a, np.concatenate([np.zeros(d), sp])[:n])
    return sp, y + rng.normal(0, noise_dps, n)


@pytest.mark.parametrize("wn_hz, zeta, delay_s", [(8.0, 0.5, 0.004), (12.0, 0.3, 0.0), (5.0, 0.8, 0.01)])
def test_second_order_loop_recovered(wn_hz, zeta, delay_s):
    """Tolerances: rise time and delay within 8 % (+1 sample), overshoot within 3 points,
    the final value within 3 % of 1 -- a loop 20 % slower or 10 points more overshoot fails."""
    rise, t50, over = _truth(wn_hz, zeta, delay_s)
    sp, gy = _flight(wn_hz, zeta, delay_s)
    got = step_response(sp, gy, FS)
    assert got is not None and got.windows > 50
    assert got.final == pytest.approx(1.0, abs=0.03)
    assert got.rise_time_s == pytest.approx(rise, rel=0.08, abs=1 / FS)
    assert got.delay_s == pytest.approx(t50, rel=0.08, abs=1 / FS)
    assert got.overshoot_pct == pytest.approx(over, abs=3.0)


def test_quiet_setpoint_gives_none():
    """A setpoint that never moves (std below 5 deg/s in every window): no step response."""
    rng = np.random.default_rng(0)
    sp = rng.normal(0, 2.0, int(60 * FS))
    assert step_response(sp, sp + rng.normal(0, 1, len(sp)), FS) is None


def test_through_a_synthetic_dataflash_rate_log(tmp_path):
    """RATE at 500 Hz (RDes/R the loop above on roll, PDes/P a slower one on pitch, yaw
    still) in a flight from 4 s: the review reads it through the DataFlash adapter, over
    flying time, the figures as the core's; yaw (no setpoint motion) has none."""
    from gyrodenoise.flightlog.log_review import log_review, review_text

    from tests.flightlog.flight_logs import log_of_bytes
    from tests.flightlog.synthetic_logs import DataFlashWriter
    roll = _flight(8.0, 0.5, 0.004, seconds=60.0)
    pitch = _flight(5.0, 0.8, 0.01, seconds=60.0, seed=2)
    w = DataFlashWriter()
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    w.define("RATE", "Qffffff", ["TimeUS", "RDes", "R", "PDes", "P", "YDes", "Y"])
    w.add("EV", 2_000_000, 10)
    w.add("EV", 4_000_000, 28)
    n = len(roll[0])
    for j in range(n):
        us = 4_000_000 + int(round(j * 1e6 / FS))
        if j % 50 == 0:
            w.add("CTUN", us, 0.45)
        w.add("RATE", us, roll[0][j], roll[1][j], pitch[0][j], pitch[1][j], 0.0, 0.0)
    rev = log_review(log_of_bytes(w.bytes(), "dataflash"))
    sr = rev.fields["step_response"]
    assert sr["source"].startswith("RATE") and sr["axes"]["yaw"] is None
    for axis, p in (("roll", (8.0, 0.5, 0.004)), ("pitch", (5.0, 0.8, 0.01))):
        rise, t50, over = _truth(*p)
        f = sr["axes"][axis]
        assert f["rise_time_s"] == pytest.approx(rise, rel=0.08, abs=1 / FS)
        assert f["overshoot_pct"] == pytest.approx(over, abs=3.0)
    assert any(line.startswith("step response: roll rise") for line in review_text(rev.fields))
    assert set(rev.step_curves) == {"roll", "pitch"}
    # the page: a plot of the averaged responses and the figures' table
    from gyrodenoise.flightlog.html_report import write_log_report
    html = write_log_report(tmp_path / "rate.report.html", {"file": "rate.bin", "format": "dataflash",
                                                            "streams": [], **rev.fields}).read_text()
    step = html[html.index("<h2 id=step>"):]
    assert "Plotly.newPlot" in step and "rise 10-90 % [ms]" in step
    assert f"<td>roll</td><td>{sr['axes']['roll']['rise_time_s'] * 1000:.0f}</td>" in step


def test_through_a_synthetic_px4_ulog():
    """PX4: vehicle_rates_setpoint at 250 Hz (rad/s) held over vehicle_angular_velocity at
    500 Hz, the roll loop above; armed and in the air throughout: the review's roll figures
    are the loop's (the hold adds at most one 500 Hz sample of delay)."""
    from gyrodenoise.flightlog.log_review import log_review

    from tests.flightlog.flight_logs import log_of_bytes
    from tests.flightlog.synthetic_logs import ULogWriter
    sp, gy = _flight(8.0, 0.5, 0.004, seconds=60.0)
    u = ULogWriter()
    u.define("sensor_combined", [("uint64_t", "timestamp"), ("float[3]", "gyro_rad")])
    u.define("vehicle_rates_setpoint", [("uint64_t", "timestamp"), ("float", "roll"), ("float", "pitch"),
                                        ("float", "yaw")])
    u.define("vehicle_angular_velocity", [("uint64_t", "timestamp"), ("float[3]", "xyz")])
    u.define("vehicle_status", [("uint64_t", "timestamp"), ("uint8_t", "arming_state")])
    u.define("vehicle_land_detected", [("uint64_t", "timestamp"), ("uint8_t", "landed")])
    sc, rs, av, vs, ld = (u.subscribe(n) for n in ("sensor_combined", "vehicle_rates_setpoint",
                                                    "vehicle_angular_velocity", "vehicle_status",
                                                    "vehicle_land_detected"))
    u.add(vs, 1000, 2)
    u.add(ld, 1000, 0)
    for j in range(len(sp)):
        us = 2000 + int(round(j * 1e6 / FS))
        r = np.radians(gy[j])
        if j % 2 == 0:
            u.add(rs, us, np.radians(sp[j]), 0.0, 0.0)
        u.add(av, us, [r, 0.0, 0.0])
        u.add(sc, us, [r, 0.0, 0.0])
    u.add(vs, 2000 + int(len(sp) * 1e6 / FS), 2)
    u.add(ld, 2000 + int(len(sp) * 1e6 / FS), 0)
    sr = log_review(log_of_bytes(u.bytes(), "ulog")).fields["step_response"]
    assert sr is not None and sr["source"].startswith("vehicle_rates_setpoint")
    rise, t50, over = _truth(8.0, 0.5, 0.004)
    f = sr["axes"]["roll"]
    assert f["rise_time_s"] == pytest.approx(rise, rel=0.08, abs=1 / FS)
    assert f["delay_s"] == pytest.approx(t50, rel=0.08, abs=1 / FS)
    assert f["overshoot_pct"] == pytest.approx(over, abs=3.0)
