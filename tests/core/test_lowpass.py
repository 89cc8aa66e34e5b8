"""method="lowpass": the Butterworth cascade against scipy (an independent
design and filter), its -3 dB point, the zero-phase option, bad parameters."""
import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.core import kernels as K


@pytest.mark.parametrize("order", [1, 2, 3, 4, 8])
@pytest.mark.parametrize("cutoff_hz,fs", [(20.0, 200.0), (5.0, 1000.0), (40.0, 100.0)])
def test_equals_scipy_butter_sosfilt(order, cutoff_hz, fs):
    """Same as scipy.signal.sosfilt(butter(...)) started in its steady state for
    the first sample, where that stays inside the input's envelope (the
    kernels clamp to the envelope; a slow sine + noise never overshoots it)."""
    from scipy.signal import butter, sosfilt, sosfilt_zi
    rng = np.random.default_rng(order)
    z = 3.0 + 0.1 * rng.standard_normal(3000) + np.sin(np.arange(3000) * 0.05)
    y = gd.denoise(z, fs, method="lowpass", cutoff_hz=cutoff_hz, order=order)
    sos = butter(order, cutoff_hz, fs=fs, output="sos")
    ref, _ = sosfilt(sos, z, zi=sosfilt_zi(sos) * z[0])
    ref = np.clip(ref, np.minimum.accumulate(z), np.maximum.accumulate(z))
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-11)
    # the per-sample path gives the same numbers
    d = gd.Denoiser(fs, method="lowpass", cutoff_hz=cutoff_hz, order=order)
    np.testing.assert_allclose([d.step(v) for v in z[:500]], y[:500], rtol=0, atol=1e-12)


@pytest.mark.parametrize("order", [1, 2, 4])
def test_gain_at_the_cutoff_is_minus_3_db(order):
    fs, fc = 1000.0, 50.0
    t = np.arange(20000) / fs
    z = np.sin(2 * np.pi * fc * t)
    y = gd.denoise(z, fs, method="lowpass", cutoff_hz=fc, order=order)
    amp = np.sqrt(2) * np.std(y[10000:])
    assert 20 * np.log10(amp) == pytest.approx(-3.0103, abs=0.02)


def test_zero_phase_has_no_lag_and_squared_gain():
    fs, f = 200.0, 2.0
    t = np.arange(8000) / fs
    z = np.sin(2 * np.pi * f * t)
    causal = gd.denoise(z, fs, method="lowpass", cutoff_hz=10.0, order=2)
    zp = gd.denoise(z, fs, method="lowpass", cutoff_hz=10.0, order=2, zero_phase=True)
    mid = slice(2000, 6000)

    def lag(y):
        return np.angle(np.sum(y[mid] * np.exp(-2j * np.pi * f * t[mid])) /
                        np.sum(z[mid] * np.exp(-2j * np.pi * f * t[mid])))

    assert abs(lag(zp)) < 1e-3                  # radians
    assert lag(causal) < -0.1                   # the causal filter lags
    # restarts: each run filtered on its own
    rs = np.zeros(t.size, dtype=bool)
    rs[4000] = True
    y = gd.denoise(z, fs, method="lowpass", cutoff_hz=10.0, zero_phase=True, restarts=rs)
    np.testing.assert_allclose(y[4000:], gd.denoise(z[4000:], fs, method="lowpass", cutoff_hz=10.0,
                                                    zero_phase=True), rtol=0, atol=1e-12)


@pytest.mark.parametrize("kw,word", [({"cutoff_hz": 0.0}, "cutoff_hz"), ({"cutoff_hz": 100.0}, "cutoff_hz"),
                                     ({"cutoff_hz": float("nan")}, "cutoff_hz"), ({"order": 9}, "order"),
                                     ({"order": 1.5}, "order")])
def test_bad_lowpass_parameters_are_refused(kw, word):
    with pytest.raises(ValueError, match=word):
        K.make_params(method="lowpass", sample_rate_hz=200.0, **kw)


def test_zero_phase_only_for_lowpass():
    with pytest.raises(ValueError, match="zero_phase"):
        gd.denoise(np.zeros(100), 100.0, method="kf", zero_phase=True)


def test_cli_denoise_lowpass_and_its_errors(tmp_path):
    import subprocess
    import sys
    t = np.arange(2000) / 200.0
    z = np.sin(t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    rec = tmp_path / "rec.csv"
    np.savetxt(rec, np.c_[t, z], delimiter=",", header="time,rate", comments="")
    cli = [sys.executable, "-m", "gyrodenoise.cli", "denoise", str(rec)]
    out = tmp_path / "out.csv"
    r = subprocess.run(cli + ["-o", str(out), "--method", "lowpass", "--cutoff-hz", "10", "--zero-phase"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    got = np.loadtxt(out, delimiter=",", skiprows=1)[:, 2]
    ref = gd.denoise(z, 200.0, method="lowpass", cutoff_hz=10.0, zero_phase=True)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
    for extra, word in ((["--method", "lowpass", "--cutoff-hz", "150"], "cutoff_hz"),
                        (["--method", "kf", "--zero-phase"], "--zero-phase"),
                        (["--method", "lowpass", "--order", "0"], "order")):
        bad = tmp_path / "bad.csv"
        r = subprocess.run(cli + ["-o", str(bad)] + extra, capture_output=True, text=True)
        assert r.returncode == 2 and word in r.stderr and "Traceback" not in r.stderr
        # one error line (the reader's notes on the record -- unit, time base -- may stand before it)
        lines = r.stderr.strip().splitlines()
        assert [ln for ln in lines if not ln.startswith("gyrodenoise: note:")] == [lines[-1]] and not bad.exists()
        assert lines[-1].startswith("gyrodenoise: error:")
