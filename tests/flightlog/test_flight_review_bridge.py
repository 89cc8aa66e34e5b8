"""The flight review through the bridge (``gyrodenoise mavlink ... --json``, spec section 8):
a SYNTHETIC DataFlash log with known arming and landing times, a known tone in the
batch sampler's pre-filter gyro and known filter parameters gives the segments
exactly, the tone within one PSD bin, the notch recommended on it and the HTML
report written; ``--whole-log`` changes what the figures are over; every shared log
gets the section-8 keys with valid shapes; the fleet compares like with like."""
from __future__ import annotations

import json

import numpy as np
import pytest

from gyrodenoise.flightlog import autopilots, fleet
from tests.helpers import SHARED_LOGS, run_main
from tests.flightlog.synthetic_logs import DataFlashWriter

FS = 2000.0
TONE_HZ = 123.4
MUL = 10000.0                     # ISBD int16 / mul = rad/s
BURST = 1024
ARM_S, TAKEOFF_S, LAND_S, DISARM_S = 4.0, 6.0, 16.0, 18.0
N_BURSTS = 20
PARAMS = {"INS_GYRO_FILTER": 40.0, "INS_HNTCH_ENABLE": 0.0, "INS_LOG_BAT_MASK": 1.0, "INS_LOG_BAT_OPT": 0.0,
          "INS_GYR_ID": 1.0, "MOT_THST_HOVER": 0.3}
STAGES = ("pre-filter", "post-filter", "unknown")
KINDS = ("ground", "armed", "flying", "after impact", "hover")


def synthetic_log(path, seed=3, events=None, params=None, tone_amp=3.0, tone_hz=TONE_HZ, first_burst=0):
    """SYNTHETIC DataFlash log written to ``path``: PARM (PARAMS), IMU at 50 Hz from 1 to
    21 s (white noise, rad/s), CTUN at 10 Hz, the batch sampler's gyro (ISBH/ISBD,
    instance 0, pre-filter) in N_BURSTS bursts of 1024 samples at 2 kHz each second from
    1 s, a 3 deg/s tone at TONE_HZ on x in 0.3 deg/s white noise; EV/ARM: armed at 4 s,
    in the air at 6 s, landed at 16 s, disarmed at 18 s (``events`` [(time_s, EV id)]
    replaces them, and without any the throttle stays at 0.1; ``params`` the PARM values; ``tone_amp`` the tone's
    deg/s, ``tone_hz`` its frequency; ``first_burst`` the number N of the first burst)."""
    rng = np.random.default_rng(seed)
    w = DataFlashWriter()
    w.define("PARM", "QNf", ["TimeUS", "Name", "Value"])
    w.define("IMU", "Qffffff", ["TimeUS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("ARM", "QBIBB", ["TimeUS", "ArmState", "ArmChecks", "Forced", "Method"])
    w.define("ISBH", "QHBBHHQf", ["TimeUS", "N", "type", "instance", "mul", "smp_cnt", "SampleUS", "smp_rate"])
    w.define("ISBD", "QHHaaa", ["TimeUS", "N", "seqno", "x", "y", "z"])
    for name, v in (PARAMS if params is None else params).items():
        w.add("PARM", 500_000, name, v)
    if events is None:
        events = [(ARM_S, 10), (TAKEOFF_S, 28), (LAND_S, 18), (DISARM_S, 11)]
    recs = []                                              # (time_us, order, name, values)
    for ts, i in events:
        recs.append((int(ts * 1e6), 0, "EV", (i,)))
        if i in (10, 11):
            recs.append((int(ts * 1e6), 1, "ARM", (int(i == 10), 0, 0, 0)))
    for t in 1.0 + np.arange(200) / 10.0:
        thr = 0.5 + 0.05 * np.sin(t) if events and TAKEOFF_S <= t <= LAND_S else 0.1
        recs.append((int(round(t * 1e6)), 2, "CTUN", (float(thr),)))
    for t in 1.0 + np.arange(1000) / 50.0:
        g = rng.normal(0.0, 0.002, 3)
        recs.append((int(round(t * 1e6)), 3, "IMU", (*map(float, g), 0.0, 0.0, -9.81)))
    for n in range(N_BURSTS):
        t0 = 1.0 + n
        t = t0 + np.arange(BURST) / FS
        x = rng.normal(0.0, 0.3, (BURST, 3))
        x[:, 0] += tone_amp * np.sin(2 * np.pi * tone_hz * t)
        counts = np.clip(np.rint(np.radians(x) * MUL), -32768, 32767).astype(int)
        us = int(round(t0 * 1e6))
        recs.append((us, 4, "ISBH", (first_burst + n, 1, 0, int(MUL), BURST, us, FS)))
        for q in range(BURST // 32):
            sl = slice(32 * q, 32 * q + 32)
            recs.append((us + 1 + q, 5, "ISBD", (first_burst + n, q, counts[sl, 0], counts[sl, 1], counts[sl, 2])))
    for us, _, name, vals in sorted(recs, key=lambda r: (r[0], r[1])):
        w.add(name, us, *vals)
    path.write_bytes(w.bytes())
    return path


def _log_review(path):
    """The review fields of a log read in-process (no filtering, no outputs)."""
    from gyrodenoise.flightlog.formats import read_log
    from gyrodenoise.flightlog.log_review import log_review
    return log_review(read_log(path)).fields


def test_never_armed_gives_no_filter_review(tmp_path):
    """The same SYNTHETIC log with no arming event and the throttle at 0.1: all ground;
    the tone in the pre-filter gyro must not become a notch recommendation -- the
    review is None and its note says why."""
    rep = _log_review(synthetic_log(tmp_path / "idle.bin", events=[]))
    assert {s["kind"] for s in rep["segments"]} == {"ground"}
    assert rep["filter_review"] is None
    assert "never armed" in rep["filter_review_note"] and "at rest" in rep["filter_review_note"]


def test_real_never_armed_log_has_no_filter_review():
    """copter_00061 never armed (motors at 1000 us): no throttle notch from its peaks at rest."""
    from tests.helpers import shared_log
    rep = _log_review(shared_log("copter_00061-2021-11-21_18-03-38.bin"))
    assert rep["filter_review"] is None and "never armed" in rep["filter_review_note"]


@pytest.fixture(scope="module")
def synthetic_run(tmp_path_factory):
    """(report of the synthetic log, its --whole-log report, the out folder)."""
    d = tmp_path_factory.mktemp("review")
    log = synthetic_log(d / "synthetic.bin")
    st, out, err = run_main("mavlink", log, "-o", d / "out", "--json", "--no-csv", "--warmup-s", "0.1")
    assert st in (0, 1), err
    rep = json.loads(out)["logs"][0]
    st, out, err = run_main("mavlink", log, "-o", d / "whole", "--json", "--no-csv", "--no-plots",
                            "--warmup-s", "0.1", "--whole-log")
    assert st in (0, 1), err
    return rep, json.loads(out)["logs"][0], d


@pytest.mark.slow
def test_synthetic_segments_exact(synthetic_run):
    rep, _, _ = synthetic_run
    main = [(s["kind"], s["start_s"], s["end_s"]) for s in rep["segments"] if s["kind"] != "hover"]
    assert main[:4] == [("ground", 1.0, ARM_S), ("armed", ARM_S, TAKEOFF_S), ("flying", TAKEOFF_S, LAND_S),
                        ("armed", LAND_S, DISARM_S)]
    assert main[4][0] == "ground" and main[4][1] == DISARM_S
    assert rep["flying_time_s"] == LAND_S - TAKEOFF_S
    assert rep["over"] == "flying"


@pytest.mark.slow
def test_synthetic_review_finds_the_tone_and_recommends_the_notch(synthetic_run):
    rep, _, _ = synthetic_run
    vf = rep["vehicle_filters"]
    assert vf["autopilot"] == "ardupilot" and vf["parameters"]["INS_GYRO_FILTER"] == 40.0
    assert [s["kind"] for s in vf["stages"]] == ["lowpass"]
    stages = {s["name"]: s["stage"] for s in rep["streams"]}
    assert stages == {"IMU": "post-filter", "ISB.gyro[0]": "pre-filter"}
    fr = rep["filter_review"]
    assert fr is not None, rep["filter_review_note"]
    assert fr["source"]["stream"] == "ISB.gyro[0]" and fr["source"]["over"] == "flying"
    df = fr["source"]["resolution_hz"]
    assert abs(fr["peaks"][0]["freq_hz"] - TONE_HZ) <= df
    assert abs(fr["recommended"]["INS_HNTCH_FREQ"] - TONE_HZ) <= df
    assert fr["recommended"]["INS_HNTCH_ENABLE"] == 1
    assert any(line.startswith("INS_HNTCH_FREQ,") for line in fr["param_lines"])
    assert "_plot" not in fr
    # the spectrum of the pre-filter stream, over flying time, sees the tone too
    isb = next(s for s in rep["streams"] if s["name"] == "ISB.gyro[0]")
    assert isb["spectrum"]["over"] == "flying" and isb["noise_over"] == "flying"
    assert abs(isb["spectrum"]["dominant_peak"]["freq_hz"] - TONE_HZ) <= 2 * isb["spectrum"]["resolution_hz"]


@pytest.mark.slow
def test_synthetic_report_html_written(synthetic_run):
    rep, _, d = synthetic_run
    html = rep["report_html"]
    assert html and html.endswith("synthetic.report.html")
    text = open(html, encoding="utf-8").read()
    assert "<html" in text.lower() and "INS_HNTCH_FREQ" in text
    assert "<script src" not in text and "<link" not in text          # self-contained


@pytest.mark.slow
def test_whole_log_changes_over(synthetic_run):
    rep, whole, _ = synthetic_run
    assert rep["over"] == "flying" and whole["over"] == "whole log"
    assert whole["filter_review"]["source"]["over"] == "whole log"
    assert {s["noise_over"] for s in whole["streams"]} == {"whole log"}
    assert whole["report_html"] is None                 # --no-plots: no HTML either
    # more bursts over the whole log than over the flight
    assert whole["filter_review"]["source"]["n_segments"] > rep["filter_review"]["source"]["n_segments"]


def check_section8(rep):
    """The keys of the interface spec's section 8 with their shapes (a schema-like check)."""
    assert isinstance(rep["segments"], list)
    for s in rep["segments"]:
        assert set(s) >= {"kind", "start_s", "end_s"} and s["kind"] in KINDS
        assert s["start_s"] <= s["end_s"]
    if not rep["segments"]:
        assert isinstance(rep["segments_note"], str) and rep["segments_note"]
    vf = rep["vehicle_filters"]
    assert vf["autopilot"] in (*autopilots.AUTOPILOTS, None)
    assert isinstance(vf["parameters"], dict) and isinstance(vf["stages"], list)
    assert all(isinstance(s, dict) and "kind" in s for s in vf["stages"])
    if vf["autopilot"] is None:
        assert vf["stages"] == []
    for s in rep["streams"]:
        assert s["stage"] in STAGES
    fr = rep["filter_review"]
    if fr is None:
        assert isinstance(rep["filter_review_note"], str) and rep["filter_review_note"]
    else:
        assert {"source", "figures", "recommended", "param_lines"} <= set(fr)
        for k in ("logged", "recommended"):
            assert set(fr["figures"][k]["phase_lag_ms"]) == {"10", "20", "30"}
            assert "noise_rms_deg_s" in fr["figures"][k]
        assert isinstance(fr["recommended"], dict) and isinstance(fr["param_lines"], list)
    vib = rep["vibration"]
    if vib is None:
        assert isinstance(rep["vibration_note"], str) and rep["vibration_note"]
    else:
        assert vib["source"] and vib["over"] in ("flying", "whole log")
        assert vib["verdict"] in ("pass", "warn", "fail", None)
        assert isinstance(vib["segments"], list)
    assert rep["over"] in ("flying", "whole log")
    assert "report_html" in rep


@pytest.mark.slow
def test_synthetic_log_section8(synthetic_run):
    rep, whole, _ = synthetic_run
    check_section8(rep)
    check_section8(whole)


SHARED = sorted(p.name for p in SHARED_LOGS.glob("*") if p.is_file()) if SHARED_LOGS.is_dir() else []


@pytest.mark.slow
@pytest.mark.skipif(not SHARED, reason=f"no shared logs in {SHARED_LOGS}")
def test_every_shared_log_has_the_section8_keys(tmp_path):
    """Every shared log through one run (no plots, no CSV): each report that completes
    has the section-8 keys with valid shapes; copter_00061 never flew."""
    st, out, err = run_main("mavlink", SHARED_LOGS, "-o", tmp_path, "--json", "--no-plots", "--no-csv",
                            "--no-progress")
    summary = json.loads(out)
    assert summary["n_ok"] >= 1, err
    for rep in summary["logs"]:
        check_section8(rep)
        assert json.dumps(rep, allow_nan=False)
    by = {p["file"].split("/")[-1]: p for p in summary["logs"]}
    c61 = by.get("copter_00061-2021-11-21_18-03-38.bin")
    if c61 is not None:
        assert c61["flying_time_s"] == 0 and c61["over"] == "whole log"
        assert not any(s["kind"] == "flying" for s in c61["segments"])


def _row(log, stream, stage, density, rate=50.0):
    return {"log": log, "file": log, "stream": stream, "status": "ok", "compared_as": fleet.compared_as(stream),
            "stage": stage, "rate_hz": rate, "noise_density_deg_s_rthz": density, "noise_unit": "deg/s"}


def test_fleet_compares_like_with_like():
    """A 2 kHz pre-filter batch-sampler stream (far noisier per sqrt(Hz) than the 50 Hz
    post-filter IMU streams) is compared with its own kind only: no NOISY flag from
    the IMU streams' median, and the IMU streams are not flagged against it."""
    rows = [_row(f"l{i}", "IMU", "post-filter", 0.01 * (1 + 0.01 * i)) for i in range(5)]
    rows += [_row(f"l{i}", "ISB.gyro[0]", "pre-filter", 0.5 * (1 + 0.01 * i), rate=2000.0) for i in range(3)]
    rows += [_row("l9", "IMU", "pre-filter", 0.6)]        # the same IMU name, another stage: its own group
    fleet._flag(rows)
    assert not any(r["flag"] for r in rows)
    imu = [r for r in rows if r["stream"] == "IMU" and r["stage"] == "post-filter"]
    assert {r["fleet_size"] for r in imu} == {5} and {r["peer_group"] for r in imu} == {"IMU[0] post-filter"}
    isb = [r for r in rows if r["stream"] == "ISB.gyro[0]"]
    assert {r["fleet_size"] for r in isb} == {3}
    assert all(0.9 < r["density_vs_fleet_median"] < 1.1 for r in imu + isb)
    lone = rows[-1]
    assert lone["fleet_size"] == 1 and "no peer" in lone["vs_fleet_note"] and "pre-filter" in lone["vs_fleet_note"]
    # a noisy IMU among its like is still flagged
    rows[0]["noise_density_deg_s_rthz"] = 0.05
    fleet._flag(rows)
    assert rows[0]["flag"] and not any(r["flag"] for r in rows[1:])


def test_fleet_report_gives_each_logs_review(tmp_path):
    logs = [{"file": "a.bin", "streams": [], "flying_time_s": 12.5, "over": "flying",
             "vibration": {"verdict": "warn"}, "filter_review": {"param_lines": ["INS_GYRO_FILTER,37"]},
             "report_html": None},
            {"file": "b.bin", "streams": [], "flying_time_s": 0.0, "over": "whole log", "vibration": None,
             "filter_review": None, "filter_review_note": "no pre-filter gyro stream: IMU is logged after the filters"}]
    text = fleet.format_log_table({"logs": logs})
    assert "| a.bin | 12.5 | flying | warn | `INS_GYRO_FILTER,37` |" in text
    assert "| b.bin | 0.0 | whole log | no data | none: no pre-filter gyro stream |" in text


def test_rate_scale_tells_centidegrees():
    """SYNTHETIC: a RATE record 100x the gyro (ArduCopter 3.x, cdeg/s) is scaled by 0.01;
    one in deg/s (4.x) is kept."""
    from gyrodenoise.flightlog.vehicle_rate import rate_scale
    from gyrodenoise.flightlog.streams import RAD_TO_DEG, GyroStream
    t = np.arange(500) / 50.0
    w = 30.0 * np.sin(2 * np.pi * 0.5 * t)[:, None] * np.array([1.0, 0.7, 0.3])      # deg/s
    g = GyroStream(name="IMU", message="IMU", unit="rad/s", to_deg_s=RAD_TO_DEG, time_s=t,
                   raw=w / RAD_TO_DEG, index=np.arange(500))
    tr = t[::5]
    assert rate_scale(tr, 100.0 * w[::5], [g]) == 0.01
    assert rate_scale(tr, w[::5], [g]) == 1.0
    assert rate_scale(tr, w[::5], []) == 1.0


def test_two_boots_reviewed_each_on_its_own(tmp_path):
    """Two SYNTHETIC flights in one file, the tone at 123.4 Hz in the first and 80.0 Hz
    in the second (the second flies 10 s, the first 10 s too: the first is the log's
    review): each boot's filter review finds its own tone, none sees the other's; the
    log's review is boot 0's and says so."""
    a = synthetic_log(tmp_path / "a.bin").read_bytes()
    # (burst numbers go on in the second boot: the low-level reader matches ISBD to ISBH by N
    # over the whole file, so a second boot that starts again at N 0 would mix the boots' bursts)
    b = synthetic_log(tmp_path / "b.bin", seed=5, tone_hz=80.0, first_burst=N_BURSTS).read_bytes()
    both = tmp_path / "both.bin"
    both.write_bytes(a + b)
    rep = _log_review(both)
    assert [x["flying_time_s"] for x in rep["boots"]] == [10.0, 10.0]
    got = [x["filter_review"]["peaks"][0]["freq_hz"] for x in rep["boots"]]
    df = rep["boots"][0]["filter_review"]["source"]["resolution_hz"]
    assert abs(got[0] - TONE_HZ) <= df and abs(got[1] - 80.0) <= df
    for x, other in zip(rep["boots"], (80.0, TONE_HZ)):
        assert all(abs(p["freq_hz"] - other) > 3 * df for p in x["filter_review"]["peaks"])
    assert rep["filter_review"]["source"]["boot"] == 0 and "boot 0" in rep["filter_review_note"]
