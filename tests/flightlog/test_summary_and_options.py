"""``gyrodenoise mavlink`` on files: the low-pass options and the effective cutoff, the
reasons a stream is left raw, no output folder after a failed run, the plots' time axis,
the summary's rate and records. (Interruption: test_stop_signals.py; the fleet report:
test_fleet_report.py; slow streams written raw bit for bit: test_file_mode.py.)"""
from __future__ import annotations

import json

import numpy as np
import pytest

from gyrodenoise.flightlog import process
from tests.helpers import DATA, run_main, shared_log
from tests.flightlog.references import by_name


def _main(*args):
    """``gyrodenoise mavlink ARGS`` in this process: (status, stdout, stderr)."""
    return run_main("mavlink", *args)


# ------------------------------------------------------------ item 4
def _scipy_lowpass(x, fs, cutoff_hz, order, zero_phase):
    """Independent reference: scipy's Butterworth, each pass centred on its first
    sample (the core's initial state: the delays at rest on the first sample)."""
    from scipy.signal import butter, sosfilt
    sos = butter(order, cutoff_hz, fs=fs, output="sos")
    y = sosfilt(sos, x - x[0]) + x[0]
    if zero_phase:
        y = (sosfilt(sos, y[::-1] - y[-1]) + y[-1])[::-1]
    return y


def test_lowpass_options_and_the_effective_cutoff_in_the_summary(tmp_path):
    """--method lowpass on a 25 Hz log filters at min(20 Hz, fs / 4) = 6.25 Hz and the
    summary says so (it said nothing: ``filter_options: {}``); --cutoff-hz, --order and
    --zero-phase reach the filter: the CSV equals scipy's Butterworth."""
    log = DATA / "ardusub_small.BIN"
    status, out, _ = _main(log, "-o", tmp_path / "a", "--method", "lowpass", "--no-plots", "--json")
    assert status == 0
    rep = json.loads(out)["logs"][0]
    s = rep["streams"][0]
    assert s["cutoff_hz"] == pytest.approx(min(20.0, s["filter_rate_hz"] / 4.0)) == pytest.approx(6.25, abs=0.01)
    assert rep["filter_options"] == {"cutoff_hz": None, "order": 2, "zero_phase": False}
    status, out, _ = _main(log, "-o", tmp_path / "b", "--method", "lowpass", "--no-plots", "--no-csv")
    assert "low-pass cutoff 6.25 Hz at 25 Hz (the default: min(20 Hz, rate / 4))" in out
    assert "Butterworth order 2, causal" in out

    status, out, _ = _main(log, "-o", tmp_path / "c", "--method", "lowpass", "--cutoff-hz", "3", "--order", "4",
                           "--zero-phase", "--no-plots", "--json")
    assert status == 0
    rep = json.loads(out)["logs"][0]
    s = rep["streams"][0]
    assert s["cutoff_hz"] == 3.0 and rep["filter_options"] == {"cutoff_hz": 3.0, "order": 4, "zero_phase": True}
    a = np.genfromtxt(s["csv"], delimiter=",", names=True)
    assert s["restarts"] == 0
    for ax in "xyz":
        ref = _scipy_lowpass(a[f"raw_{ax}"], s["filter_rate_hz"], 3.0, 4, True)
        # CSV: 9 significant digits; the core holds the output inside the raw range seen
        # since the restart (a few samples at the start of the backward pass may differ)
        close = np.abs(a[f"filtered_{ax}"] - ref) <= 1e-6 * (1 + np.abs(ref))
        assert close.mean() > 0.98, ax


def test_cutoff_a_stream_cannot_take_leaves_it_raw_with_the_reason(tmp_path):
    """--cutoff-hz above some streams' Nyquist but not all (copter_00061: IMUs at 25 Hz,
    the batch sampler at 2 kHz): those streams are not filtered, and say why; exit 0.
    Above every stream's Nyquist the option is refused (test_noise_and_saturation.py)."""
    log = shared_log("copter_00061-2021-11-21_18-03-38.bin")
    status, out, _ = _main(log, "-o", tmp_path, "--method", "lowpass",
                           "--cutoff-hz", "15", "--no-plots", "--no-csv", "--json")
    assert status == 0
    s = by_name(json.loads(out)["logs"][0])
    assert "cannot run at 24.9" in s["IMU[0]"]["not_filtered"] and "cutoff_hz" in s["IMU[0]"]["not_filtered"]
    assert s["ISB.gyro[0]"]["not_filtered"] is None and s["ISB.gyro[0]"]["cutoff_hz"] == 15.0


# ------------------------------------------------------------ item 6
def test_streams_never_filtered_say_why(tmp_path):
    """45 samples at 50 Hz (shorter than motion's warm-up: its first 128-sample block, whatever
    --warmup-s says; shakf's 1 s): the text says NOT FILTERED and why, the axis lines no
    'corr -, amplitude -'; the filtered log holds the raw values; shakf with a shorter warm-up
    filters them, and motion's reason says so (a shorter --warmup-s would not)."""
    log = DATA / "plane_truncated_test.BIN"
    status, out, _ = _main(log, "-o", tmp_path / "a", "--no-plots", "--no-csv")
    assert status == 0
    assert out.count("NOT FILTERED: its one session is 45 samples, not longer than the filter's warm-up "
                     "of 128 samples") == 2
    assert "--method shakf --warmup-s 0.1, filters it" in out
    assert "corr -" not in out and out.count("(written raw: not filtered: see above)") == 6 and "->" not in out
    rep = process.process_log(log, tmp_path / "b", plots=False, csv=False, warmup_s=0.1)
    assert all(s["not_filtered"] for s in rep["streams"])          # motion: --warmup-s does not shorten it
    rep = process.process_log(log, tmp_path / "c", plots=False, csv=False, method="shakf")
    assert all("a shorter --warmup-s, e.g. 0.1, filters it" in s["not_filtered"] for s in rep["streams"])
    rep = process.process_log(log, tmp_path / "d", plots=False, csv=False, method="shakf", warmup_s=0.1)
    assert not any(s["not_filtered"] for s in rep["streams"])


def test_batch_sampler_bursts_shorter_than_the_warmup_say_why(tmp_path):
    """An AR method's 1 s warm-up (2002 samples at 2 kHz) is longer than every 1024-sample
    burst: the stream is left raw with the reason. ``motion`` ends its warm-up once the
    noise level is read (128 samples), so it filters the same bursts."""
    log = shared_log("copter_00061-2021-11-21_18-03-38.bin")
    rep = process.process_log(log, tmp_path / "shakf", plots=False, csv=False, method="shakf")
    isb = by_name(rep)["ISB.gyro[0]"]
    assert "each of its 23 sessions is at most 1024 samples" in isb["not_filtered"]
    assert "warm-up of 2002 samples" in isb["not_filtered"] and "--warmup-s" in isb["not_filtered"]
    assert all(v["ratio"] is None for v in isb["noise"].values())
    motion = by_name(process.process_log(log, tmp_path / "motion", plots=False, csv=False))["ISB.gyro[0]"]
    assert motion["not_filtered"] is None and all(v["ratio"] is not None for v in motion["noise"].values())


# ------------------------------------------------------------ item 7
@pytest.mark.parametrize("case", ["empty", "garbage", "csv", "missing_fmu", "bad_udpin"])
def test_a_failed_run_leaves_no_output_folder(tmp_path, case):
    src = tmp_path / "in"
    src.mkdir()
    args = {"empty": [src / "empty.bin"], "garbage": [src / "garbage.bin"], "csv": [src / "rec.csv"],
            "missing_fmu": [DATA / "ardusub_small.BIN", "--engine", "fmu", "--fmu", src / "nope.fmu"],
            "bad_udpin": ["udpin:127.0.0.1:99999"]}[case]
    (src / "empty.bin").write_bytes(b"")
    (src / "garbage.bin").write_bytes(np.random.default_rng(7).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    (src / "rec.csv").write_text("time,rate\n0,1\n")
    out = tmp_path / "out" / "deeper"
    status, _, err = _main(*args, "-o", out)
    assert status == 2 and err.startswith("gyrodenoise: error: ")
    assert not (tmp_path / "out").exists()
    # a folder that was there before stays
    out.mkdir(parents=True)
    assert _main(*args, "-o", out)[0] == 2 and out.is_dir() and not any(out.iterdir())


# ------------------------------------------------------------ item 8
def _captured_plots(monkeypatch):
    from gyrodenoise.flightlog import plotting
    got = {}
    monkeypatch.setattr(plotting, "_draw", lambda path, title, pdata, unit, axes, spectrum=None:
                        got.__setitem__(path.name, pdata))
    return got


def test_plot_time_is_the_summary_time(tmp_path, monkeypatch):
    """log171: the restart the summary puts at t = 74.628 s was drawn at ~61 s (the
    sessions joined from 0); the plot's time is now the boot time of the summary and CSV."""
    got = _captured_plots(monkeypatch)
    rep = process.process_log(shared_log("log171.bin"), tmp_path, csv=False)
    lines, rt, labels, xlabel, _segments, _ylims = got["log171.IMU.png"]
    restart = next(e for e in rep["restarts"] if e["stream"] == "IMU")
    assert rt.tolist() == [pytest.approx(restart["time_s"], abs=1e-6)]
    assert "boot time" in xlabel and labels is None
    from gyrodenoise.flightlog import dataflash            # the x axis starts at the first sample's boot time
    _, _, streams = dataflash.read(shared_log("log171.bin"))
    assert lines[0][0][0][0] == pytest.approx(streams[0].time_s[0])


def test_plot_of_a_log_whose_time_goes_back_labels_restarts_with_boot_time(tmp_path, monkeypatch):
    """Three boot sessions (boot time goes backwards): sessions joined end to end from
    the first sample's boot time, each restart line labelled with the summary's time."""
    got = _captured_plots(monkeypatch)
    rep = process.process_log(shared_log("copter_20211202-132613.tlog"), tmp_path, csv=False)
    lines, rt, labels, xlabel, _segments, _ylims = got["copter_20211202-132613.RAW_IMU.png"]
    times = [e["time_s"] for e in rep["restarts"] if e["stream"] == "RAW_IMU"]
    assert labels.tolist() == pytest.approx(times) and "joined" in xlabel
    assert np.all(np.diff(rt) > 0)


# ------------------------------------------------------------ item 10
@pytest.mark.slow
def test_ulog_summary_has_no_dash_for_unreadable_records(tmp_path):
    status, out, _ = _main(shared_log("px4_sample.ulg"), "-o", tmp_path, "--no-plots", "--no-csv")
    first = out.splitlines()[0]
    assert status == 0 and first.endswith("(ulog): 64542 messages") and "unreadable" not in first


def test_count_with_a_log_file_is_refused(tmp_path):
    status, out, err = _main(DATA / "ardusub_small.BIN", "-o", tmp_path / "o", "--count", "5")
    assert status == 2 and out == "" and not (tmp_path / "o").exists()
    assert err.strip() == ("gyrodenoise: error: --count applies to a live link (udpin:, tcp:, ...) only, "
                           "not to log files")


def test_summary_says_the_rate_given_by_sample_rate(tmp_path):
    """--sample-rate was reported as the measured "25 Hz" only; the text says the
    filter's rate when it is another."""
    status, out, _ = _main(DATA / "ardusub_small.BIN", "-o", tmp_path, "--sample-rate", "100", "--no-plots",
                           "--no-csv")
    assert status == 0 and "25 Hz  0 restart(s)  unit rad/s  (filtered as 100 Hz: --sample-rate)" in out
