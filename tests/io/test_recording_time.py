"""The recording reader and the commands on the time model (gyrodenoise.io.timebase):
synthetic records of known rate, unit and gaps."""
import json

import numpy as np
import pytest

from gyrodenoise.cli import main
from gyrodenoise.io.recording import read_recording

N_TRUE = 0.30          # deg/sqrt(h): white noise of std N / 60 * sqrt(fs) deg/s


def _white(n, fs, seed=0):
    """White rate noise (deg/s) of angle random walk N_TRUE at ``fs``, about 0.5 deg/s."""
    return 0.5 + N_TRUE / 60.0 * np.sqrt(fs) * np.random.default_rng(seed).standard_normal(n)


def _bursty_stamps(n, fs, seed=1):
    """Host stamps of a sensor at ``fs`` read in USB packets: each packet of 3-8 samples
    stamped at its arrival (late by 0-5 ms), the samples inside 50 µs apart."""
    rng = np.random.default_rng(seed)
    t = np.empty(n)
    i = 0
    while i < n:
        k = min(int(rng.integers(3, 9)), n - i)
        arrival = (i + k - 1) / fs + rng.uniform(0.0, 0.005)
        t[i:i + k] = arrival + 50e-6 * np.arange(k)
        i += k
    return t


def _write(path, t, rate, time_fmt="%.9f"):
    with open(path, "w") as f:
        f.write("time,rate\n")
        for a, b in zip(t, rate):
            f.write(f"{time_fmt % a},{b:.6f}\n")
    return path


def _allan_json(capsys, *argv):
    code = main(["allan", *map(str, argv), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out), err


def test_bursty_host_stamps_give_the_sensor_rate_and_the_right_N(tmp_path, capsys):
    """The issue's MPU-6050: 65,067 samples over 655 s (99.3 Hz) stamped in bursts;
    1/median step says ~500 Hz (N 2.2x low before)."""
    n, fs = 65_067, 65_066 / 655.0
    path = _write(tmp_path / "bursty.csv", _bursty_stamps(n, fs), _white(n, fs))
    rec = read_recording(path)
    assert rec.sample_rate_hz == pytest.approx(fs, rel=2e-3)
    assert rec.restarts is None                                   # bursts do not restart
    d, err = _allan_json(capsys, path)
    assert d["terms"]["N"] == pytest.approx(N_TRUE, rel=0.1)
    note = next(x for x in d["notes"] if x.startswith("time column"))
    assert "host-stamped bursts" in note and note in err          # on stderr and in the JSON


@pytest.mark.parametrize("unit,scale,offset,fmt", [
    ("ms", 1e3, 0.0, "%.0f"),
    ("µs", 1e6, 0.0, "%.0f"),
    ("ns", 1e9, 0.0, "%.0f"),
    ("ns", 1e9, 1.7e18, "%.0f"),           # a ROS %time: ns since 1970
    ("s", 1.0, 1_700_000_000.0, "%.4f"),   # a Unix epoch in s
])
def test_time_units_and_epochs_are_detected_and_said(tmp_path, capsys, unit, scale, offset, fmt):
    """200 Hz in ms, µs, ns and epochs (before: 0.2 Hz, 2e-4 Hz, 2e-7 Hz, silent)."""
    n, fs = 4000, 200.0
    t = offset + np.arange(n) / fs * scale
    path = _write(tmp_path / "u.csv", t, _white(n, fs), fmt)
    rec = read_recording(path)
    assert rec.sample_rate_hz == pytest.approx(fs, rel=1e-6)
    np.testing.assert_allclose(rec.time_s, np.arange(n) / fs, atol=1e-6)   # s, from the record's zero
    assert rec.restarts is None
    d, err = _allan_json(capsys, path)
    assert f"time column in {unit} (" in err
    assert ("epoch from 2023-11-14" in err) == bool(offset)
    assert d["terms"]["N"] == pytest.approx(N_TRUE, rel=0.1)


def test_time_unit_option_wins_over_detection(tmp_path):
    """Whole seconds at 1 Hz read as ms by spacing; --time-unit s says otherwise."""
    n = 600
    path = _write(tmp_path / "s.csv", np.arange(n), _white(n, 1.0), "%d")
    assert read_recording(path).sample_rate_hz == pytest.approx(1000.0)
    assert read_recording(path, time_unit="s").sample_rate_hz == pytest.approx(1.0)
    assert read_recording(path, time_unit="s").time_s[-1] == n - 1


def _denoise_ratio(tmp_path, capsys, t, rate, *extra):
    path = _write(tmp_path / "in.csv", t, rate)
    out = tmp_path / "out.csv"
    code = main(["denoise", str(path), "-o", str(out), "--method", "shakf", *extra])
    _, err = capsys.readouterr()
    assert code == 0, err
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    assert got.shape[0] == t.size
    tail = slice(t.size // 2, None)
    return float(np.std(got[tail, 2]) / np.std(got[tail, 1])), err


def test_jitter_and_dropped_samples_do_not_restart_the_filter(tmp_path, capsys):
    """±30 % stamp jitter, then 2 % of the samples dropped: no restart, the filter keeps
    denoising (before: 0.79x and 0.89x raw, a restart at each odd step)."""
    n, fs = 12_000, 100.0
    rng = np.random.default_rng(3)
    rate = _white(n, fs)
    t = np.arange(n) / fs + rng.uniform(-0.3, 0.3, n) / fs
    rec = read_recording(_write(tmp_path / "j.csv", t, rate))
    assert rec.restarts is None and rec.sample_rate_hz == pytest.approx(fs, rel=1e-3)
    ratio, err = _denoise_ratio(tmp_path, capsys, t, rate)
    assert "jitter does not restart the filter" in err
    assert ratio < 0.3, ratio
    keep = np.sort(rng.choice(n, int(0.98 * n), replace=False))
    t2 = np.arange(n)[keep] / fs
    rec = read_recording(_write(tmp_path / "d.csv", t2, rate[keep]))
    assert rec.restarts is None and rec.sample_rate_hz == pytest.approx(fs, rel=2e-3)
    ratio, err = _denoise_ratio(tmp_path, capsys, t2, rate[keep])
    assert "bridged: no restart" in err
    assert ratio < 0.3, ratio


def test_a_real_gap_restarts_and_the_note_says_what_each_side_holds(tmp_path, capsys):
    n1, n2, fs = 3000, 5000, 100.0
    t = np.concatenate([np.arange(n1), n1 + 3000 + np.arange(n2)]) / fs      # 30 s missing
    rate = _white(n1 + n2, fs)
    rec = read_recording(_write(tmp_path / "g.csv", t, rate))
    assert rec.sample_rate_hz == pytest.approx(fs)
    assert np.flatnonzero(rec.restarts).tolist() == [n1]
    note = next(x for x in rec.notes if x.startswith("time column"))
    assert "1 gap of more than 4 missing samples (3,000 missing; longest 30.01 s" in note
    assert f"runs of {n1:,} | {n2:,} samples" in note


def test_sample_rate_is_reconciled_with_the_time_column(tmp_path, capsys):
    n, fs = 2000, 100.0
    path = _write(tmp_path / "r.csv", np.arange(n) / fs, _white(n, fs))
    rec = read_recording(path, sample_rate_hz=101.0)                  # within 2 %: as stated
    assert rec.sample_rate_hz == 101.0
    assert any("rate 101 Hz as stated" in x for x in rec.notes)
    for bad, needle in (("110", "differ by more than 2%"), ("1e300", "is not a sample rate"),
                        ("0", "is not a sample rate"), ("nan", "is not a sample rate")):
        code = main(["allan", str(path), "--sample-rate", bad, "--json"])
        out, err = capsys.readouterr()
        assert code == 2 and len(err.strip().splitlines()) == 1 and needle in err, err
        assert "Traceback" not in err


def test_sample_rate_without_a_time_column(tmp_path, capsys):
    path = tmp_path / "norate.csv"
    path.write_text("rate\n" + "".join(f"{v:.6f}\n" for v in _white(500, 50.0)))
    rec = read_recording(path, sample_rate_hz=50.0)
    assert rec.sample_rate_hz == 50.0 and any("50 Hz as stated" in x for x in rec.notes)
    for cmd in (["allan"], ["denoise", "-o", str(tmp_path / "o.csv")]):
        code = main([*cmd, str(path), "--sample-rate", "1e300"])
        _, err = capsys.readouterr()
        assert code == 2 and len(err.strip().splitlines()) == 1 and "is not a sample rate" in err, err


def test_gap_says_the_time_note_and_puts_it_in_its_json(tmp_path, capsys):
    """gap reads the record with the same time model (a time column in ms: 200 Hz, not 0.2 Hz)."""
    import gyrodenoise as gd
    r = gd.simulate("paper_fog", 20_000, seed=1)
    path = tmp_path / "ms.csv"
    np.savetxt(path, np.column_stack([r.time_s * 1000.0, r.rate_deg_s]), delimiter=",", header="time,rate",
               comments="", fmt="%.10g")
    code = main(["gap", str(path), "--model", "paper_fog", "--out", str(tmp_path / "new.toml"), "--engine", "native",
                 "--seeds", "3", "--no-plot", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    note = next(x for x in json.loads(out)["notes"] if x.startswith("time column"))
    assert note.startswith("time column in ms (by its spacing; median step 5 ms): rate 200 Hz") and note in err
