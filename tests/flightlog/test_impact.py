"""Crash handling (gyrodenoise.flightlog.impact): a SYNTHETIC DataFlash flight with a
crash at a known time ends there, what follows is shown but kept out of the vibration
verdict; a flip without an impact and a motor failure ridden out are no crash; a
steady throttle with the vehicle swinging is no hover. The shared log171.bin ends in
a crash (Copter 3.3: IMU at 50 Hz, ATT upside down after it)."""
from __future__ import annotations

import functools

import pytest

from gyrodenoise.flightlog.log_review import log_review, review_text
from gyrodenoise.flightlog.segments import flight_segments

from tests.flightlog.flight_logs import log_of_bytes, shared_flight_log
from tests.flightlog.synthetic_logs import crash_dataflash

CRASH_S = 20.0


@functools.lru_cache(maxsize=None)
def _review(**kw):
    log = log_of_bytes(crash_dataflash(crash_s=kw.pop("crash_s", CRASH_S), **kw), "dataflash")
    return log_review(log)


def _main(segs):
    return [(s.kind, s.start_s, s.end_s) for s in segs if s.kind != "hover"]


def test_crash_ends_the_flight_at_the_impact():
    rev = _review()
    assert _main(rev.segments) == [("ground", 1.0, 2.0), ("armed", 2.0, 4.0), ("flying", 4.0, CRASH_S),
                                   ("after impact", CRASH_S, 29.9)]
    (imp,) = rev.fields["impacts"]
    assert imp["time_s"] == CRASH_S and imp["rate_peak_deg_s"] == pytest.approx(1500, abs=20)
    assert imp["accel_peak_m_s2"] > 100 and "tumble" in imp["confirmed_by"]
    assert rev.fields["flying_time_s"] == pytest.approx(CRASH_S - 4.0)
    # no hover after the impact
    assert all(s.end_s < CRASH_S for s in rev.segments if s.kind == "hover")


def test_post_impact_clipping_does_not_drive_the_vibration_verdict():
    vib = _review().fields["vibration"]
    flying, after = vib["segments"]
    assert flying["kind"] == "flying" and flying["verdict"] == "pass"
    assert flying["figures"]["Clip"]["increase"] == 0
    assert after["kind"] == "after impact" and after["in_verdict"] is False and after["verdict"] == "fail"
    assert "after impact" in after["note"]
    assert vib["verdict"] == "pass"
    assert "vibration: PASS" in "\n".join(review_text(_review().fields))


def test_disarm_after_the_impact_confirms_it():
    rev = _review(tumble=False, disarm_s=21.5)
    assert ("after impact", CRASH_S, 21.5) in _main(rev.segments)
    assert "no longer flying 1.5 s later" in rev.fields["impacts"][0]["confirmed_by"]


@pytest.mark.parametrize("kw", [{"spike": False, "clips": False},       # a flip: no spike, no clipping
                                {"tumble": False}])                     # upright, flying on: nothing follows
def test_no_impact_without_all_its_evidence(kw):
    rev = _review(**kw)
    assert rev.fields["impacts"] == [] and "after impact" not in [s.kind for s in rev.segments]


def test_motor_failure_with_steady_throttle_is_not_hover():
    """The roll rate swings +-131 deg/s from 14 to 24 s while CTUN.ThO stays at 0.45."""
    def hovers(**kw):
        segs, note = flight_segments(log_of_bytes(crash_dataflash(crash_s=None, **kw), "dataflash"))
        assert "body rate" in note
        return [(s.start_s, s.end_s) for s in segs if s.kind == "hover"]
    assert any(a <= 14.0 and b >= 24.0 for a, b in hovers())             # steady: hover across 14-24 s
    hov = hovers(swing=(14.0, 24.0))
    assert all(b <= 14.2 or a >= 23.8 for a, b in hov) and any(a >= 23.8 for a, b in hov)


def test_log171_crash():
    """log171.bin: the vehicle hits the ground at 239.14 s (IMU 2042 deg/s, 108 m/s/s),
    then lies upside down (ATT.Roll ~180) while the log runs on to 254 s."""
    segs, note = flight_segments(shared_flight_log("log171.bin"))
    (after,) = [s for s in segs if s.kind == "after impact"]
    assert after.start_s == pytest.approx(239.14, abs=0.05) and after.end_s == pytest.approx(253.97, abs=0.01)
    assert after.impact.rate_peak_deg_s > 1500 and after.impact.accel_peak_m_s2 > 100
    assert "tumble" in after.impact.confirmed_by
    assert all(s.end_s <= after.start_s for s in segs if s.kind in ("flying", "hover"))


def test_clipping_alone_stands_for_the_spike():
    """No 3 g sample in the logged accelerometer (a low-passed log under-reads it), but
    VIBE.Clip rises just after the rate jump: the impact is found, said clipped."""
    (imp,) = _review(spike=False).fields["impacts"]
    assert imp["time_s"] == CRASH_S and imp["clipped"] is True and imp["accel_peak_m_s2"] < 3 * 9.81
    assert "clipping" in imp["reason"]
