"""The shared Betaflight blackbox LOG00037.BFL through the bridge (the blackbox adapter,
gyrodenoise.flightlog.adapters.blackbox, and the Betaflight strategy): the CLI (``--json``)
and the review. The pre-filter stream (debug GYRO_SCALED) is what the review analyses, and
its spectrum puts the motor peak near 121-126 Hz, as scipy's Welch estimate of the decoded
values does; the logged chain (from the header) attenuates it; the review gives ``set``
lines or "no change" with its reasons; the filtered streams are written beside the log
(CSV) and the report says the format cannot be patched."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from scipy.signal import welch

from gyrodenoise.flightlog import blackbox, formats
from gyrodenoise.flightlog.log_review import log_review
from tests.helpers import SHARED_LOGS, main_in_process

LOG = SHARED_LOGS / "betaflight" / "LOG00037.BFL"
pytestmark = pytest.mark.skipif(not LOG.is_file(), reason=f"third-party log not present: {LOG} (licence forbids "
                                                          "copying it into the repo)")
MOTOR_BAND_HZ = (118.0, 129.0)          # the motor peak of the pre-filter gyro (121-126 Hz) and a bin either side


def _peak_hz(freq_hz, psd, lo=60.0, hi=400.0):
    sel = (freq_hz >= lo) & (freq_hz <= hi)
    return float(freq_hz[sel][np.argmax(psd[sel])])


def test_blackbox_through_the_cli(tmp_path, capfd):
    out = tmp_path / "out"
    status, stdout, err = main_in_process(capfd, "mavlink", LOG, "-o", out, "--json")
    assert status == 0, err
    rep = json.loads(stdout)["logs"][0]
    assert rep["format"] == "blackbox" and rep["unreadable_records"] == 0
    stages = {s["name"]: (s["message"], s["stage"], round(s["rate_hz"])) for s in rep["streams"]}
    assert stages == {"gyroADC": ("gyroADC", "post-filter", 1000),
                      "gyro pre-filter (debug GYRO_SCALED)": ("debug", "pre-filter", 1000)}
    # not patched, and said so; the filtered gyroADC beside the log, one row per frame
    assert rep["patched"] is False and rep["not_patched_reason"] == blackbox.NOT_PATCHABLE_REASON
    assert rep["output_log"] == str(out / "LOG00037.filtered.csv")
    bb = blackbox.read_blackbox(LOG)[0]
    with open(rep["output_log"]) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(bb.main)
    np.testing.assert_allclose([float(r["gyroADC_y"]) for r in rows], bb.gyro_dps[:, 1])
    filtered = np.array([[float(r[f"gyroADC_filtered_{a}"]) for a in "xyz"] for r in rows])
    assert np.isfinite(filtered).all() and not np.allclose(filtered, bb.gyro_dps)
    # the flight: armed from the log's start, in the air most of its 17 s
    assert rep["segments"][0]["kind"] == "armed" and rep["segments"][0]["start_s"] == pytest.approx(bb.time_s[0])
    assert 12.0 < rep["flying_time_s"] < 17.1 and "motorOutput 158..2047" in rep["segments_note"]
    # the vehicle's filters from the header, the review on the pre-filter stream
    vf = rep["vehicle_filters"]
    assert vf["autopilot"] == "betaflight" and vf["filter_rate_hz"] == 8000.0
    assert [s["params"] for s in vf["stages"] if s["kind"] == "lowpass"] == [
        "dyn_lpf_gyro_min_hz, dyn_lpf_gyro_max_hz", "gyro_lowpass2_hz"]
    review = rep["filter_review"]
    assert review["source"]["stage"] == "pre-filter" and review["source"]["message"] == "debug"
    assert review["figures"]["logged"]["noise_rms_deg_s"]["rss"] < review["figures"]["pre_filter"]["noise_rms_deg_s"]["rss"]
    if review["verdict"] == "change":
        assert review["param_lines"] and all(line.startswith("set ") and " = " in line for line in review["param_lines"])
    else:
        assert review["param_lines"] == [] and any(w.startswith("no change") for w in review["why"])
    assert review["why"]
    assert rep["vibration"]["accel_source"] == "accSmooth / acc_1G"


def test_blackbox_review_spectrum_shows_the_motor_peak():
    log = formats.read_log(LOG)
    assert [a.name for a in log.accel] == ["accSmooth"]        # accSmooth / acc_1G: 1 g at rest and in hover
    assert np.median(np.linalg.norm(log.accel[0].values, axis=1)) == pytest.approx(9.8, rel=0.15)
    review = log_review(log)
    plot = review.plot
    assert plot is not None
    pre = np.asarray(plot.psd_pre).sum(axis=0)
    got = _peak_hz(plot.freq_hz, pre)
    assert MOTOR_BAND_HZ[0] <= got <= MOTOR_BAND_HZ[1]
    # scipy's Welch PSD of the decoded pre-filter gyro over the whole log puts it there too
    x = blackbox.read_blackbox(LOG)[0].gyro_prefilter_dps
    f, p = welch(x - x.mean(axis=0), fs=1000.0, nperseg=1024, axis=0)
    assert MOTOR_BAND_HZ[0] <= _peak_hz(f, p.sum(axis=1)) <= MOTOR_BAND_HZ[1]
    # the logged chain (lowpasses at 8 kHz) takes the peak down: less power after it at the peak
    k = int(np.argmin(np.abs(plot.freq_hz - got)))
    logged = np.asarray(plot.psd_logged).sum(axis=0)
    assert logged[k] < 0.9 * pre[k]


def test_two_logs_in_one_file_are_two_boots(tmp_path):
    """A flash dump holds one log per arming: each is a boot, on its own time, with its own segments."""
    two = tmp_path / "LOG00001.BBL"
    two.write_bytes(LOG.read_bytes() * 2)
    log = formats.read_log(two)
    n = len(blackbox.read_blackbox(LOG)[0].main)
    assert [b.first_record for b in log.boots] == [0, n]
    assert [s.n for s in log.gyro] == [2 * n, 2 * n]
    review = log_review(log)
    flying = [s for s in review.segments if s.kind == "flying"]
    assert {s.session for s in flying} == {0, 1}
    assert sum(s.duration_s for s in flying if s.session == 1) == pytest.approx(
        sum(s.duration_s for s in flying if s.session == 0))
    out = tmp_path / "f.csv"
    rep = log.format.write_filtered(log, out)
    assert rep["patched"] is False and len(out.read_text().splitlines()) == 2 * n + 1


@pytest.mark.parametrize("seed", range(4))
def test_mutated_blackbox_goes_through_or_gives_one_line(tmp_path, seed):
    """LOG00037 with seeded byte flips or a cut: the whole pipeline (read, review, filter,
    the filtered CSV) gives a report or the one-line InputError, never anything else; the
    CSV holds one row per frame read and the damage is counted."""
    from gyrodenoise.errors import InputError
    from gyrodenoise.flightlog.pipeline import process_log
    from tests.flightlog.test_fuzz_logs import flips, truncation
    rng = np.random.default_rng(seed)
    data, what = (flips if seed % 2 else truncation)(LOG.read_bytes(), rng)
    src = tmp_path / "m.bfl"
    src.write_bytes(data)
    try:
        rep = process_log(src, tmp_path / "out", plots=False, csv=False, html=False)
    except InputError as exc:
        assert "\n" not in str(exc), what
        return
    frames = sum(len(b.main) for b in blackbox.read_blackbox(src))
    assert rep["messages"] == frames, what
    assert len(open(rep["output_log"]).read().splitlines()) == frames + 1, what
    if seed % 2 == 0:
        assert rep["truncation"], what          # no end-of-log event after a cut
