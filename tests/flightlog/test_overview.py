"""The first screen (gyrodenoise.flightlog.overview): identity, flight time per boot and
one verdict line per part of the review, in the report and at the top of the HTML page;
on a SYNTHETIC crash flight of known identity and crash time, and on shared logs of
each autopilot (identity as their files say)."""
from __future__ import annotations

import functools

import pytest

from gyrodenoise.flightlog.formats import read_log
from gyrodenoise.flightlog.log_review import log_review

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import crash_dataflash
from tests.helpers import SHARED_LOGS


@functools.lru_cache(maxsize=None)
def _crash():
    return log_review(log_of_bytes(crash_dataflash(), "dataflash")).fields


def _verdicts(ov):
    return {v["topic"]: v for v in ov["verdicts"]}


def test_synthetic_crash_flight_overview():
    ov = _crash()["overview"]
    assert (ov["vehicle"], ov["firmware"], ov["board"], ov["frame"], ov["vehicle_id"]) == (
        "ArduCopter", "V4.5.7 (0123abcd)", "CubeOrange", "QUAD/X", "00300021 31305110 30393738")
    assert ov["flight_time_s"] == [pytest.approx(16.0)] and ov["flying_time_s"] == pytest.approx(16.0)
    v = _verdicts(ov)
    assert list(v) == ["crash", "vibration", "filters", "step response"]
    assert v["crash"]["verdict"] == "fail" and "impact at 20.00 s" in v["crash"]["reason"]
    assert v["vibration"]["verdict"] == "pass"              # the post-impact VibeZ 90 and clipping kept out
    assert v["filters"]["verdict"] is None and v["filters"]["reason"]
    assert v["step response"]["verdict"] is None and "no rate setpoint" in v["step response"]["reason"]


def test_overview_tops_the_html_page(tmp_path):
    from gyrodenoise.flightlog.html_report import write_log_report
    fields = _crash()
    page = write_log_report(tmp_path / "crash.report.html", {"file": "crash.bin", "format": "dataflash",
                                                             "streams": [], **fields})
    html = page.read_text()
    top = html.index("<h2 id=overview>")
    assert top < html.index("<h2 id=summary>")
    screen = html[top:html.index("<h2 id=summary>")]
    for text in ("ArduCopter", "V4.5.7 (0123abcd)", "CubeOrange", "QUAD/X", "16.0 s", "FAIL", "impact at 20.00 s",
                 "PASS", "no rate setpoint"):
        assert text in screen, text


@pytest.mark.parametrize("name, want", [
    ("log171.bin", ("APM:Copter", "V3.3-dev (ae3192b8)", "PX4v2", "QUAD")),
    ("betaflight/LOG00037.BFL", ("Betaflight", "Betaflight 4.2.0 (8f2d21460) STM32F745", "HBRO KAKUTEF7", None)),
    ("px4_quad_ekf_failure.ulg", ("PX4 quadrotor", "1.15.0 (git b589596a)", "NXP_MR_TROPIC",
                                  "airframe 4001 (SYS_AUTOSTART)")),
    ("px4_vtol_small.ulg", ("PX4 VTOL standard", "1.11.2 (git 8583f1da)", "CUBEPILOT_CUBEORANGE",
                            "airframe 13014 (SYS_AUTOSTART)")),
])
def test_shared_logs_identity(name, want):
    path = SHARED_LOGS / name
    if not path.exists():
        pytest.skip(f"third-party log not present: {path}")
    ov = log_review(read_log(path)).fields["overview"]
    assert (ov["vehicle"], ov["firmware"], ov["board"], ov["frame"]) == want
    assert len(ov["verdicts"]) == 4 and all(v["reason"] for v in ov["verdicts"])


def test_never_flying_log_has_no_crash_verdict():
    path = SHARED_LOGS / "px4_sample.ulg"                   # never armed
    if not path.exists():
        pytest.skip(f"third-party log not present: {path}")
    (crash,) = [v for v in log_review(read_log(path)).fields["overview"]["verdicts"] if v["topic"] == "crash"]
    assert crash["verdict"] is None and "no flight" in crash["reason"]
