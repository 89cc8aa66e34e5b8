"""The rigid-body option of ``method="motion"``: ``max_motion_hz``, a
stated band of interest; content above it (a frame's vibration) counts as error.

Held here: its gain (a sinusoid inside the band kept within 5 %, a tone above it
removed, against the analytic response of the Butterworth it puts ahead of the bank),
per-sample == batch (C and plain Python), the default filter unchanged with the option
off (golden output of main's kernels.py before the option existed), bad values refused
by the library, the CLI and the bridge. C == Python bit for bit: tests/core/test_c_core_equals_python.py;
the FMUs: tests/fmu/test_build_and_run.py and tests/fmu/test_native_denoiser.py.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.core import batch
from gyrodenoise.core import kernels as K
from tests.helpers import DATA, run_main

FS = 400.0                 # a drone gyro's rate
CUT_HZ = 30.0              # the stated band of interest
NOISE_DEG_S = 0.08         # per-sample white noise (ICM-20602 class at 400 Hz)
GOLDEN = DATA / "motion_default_golden.npy"


def golden_record():
    """1600 samples at 400 Hz: noise, an 80 Hz 'vibration' tone, a step, a ramp, a lone
    spike and a restart (the golden output's input; seeded)."""
    rng = np.random.default_rng(23)
    n = 1600
    t = np.arange(n) / FS
    z = 0.08 * rng.standard_normal(n) + 2.0 * np.sin(2 * np.pi * 80.0 * t)
    z[600:] += 5.0
    z[900:1000] += np.linspace(0.0, 8.0, 100)
    z[1000:] += 8.0
    z[1300] += 30.0
    rs = np.zeros(n, dtype=bool)
    rs[1100] = True
    return z, rs


def _sine_fit(y, f_hz, lo):
    """Least-squares (sin, cos) coefficients of y[lo:] at f_hz, with a constant and a slope."""
    t = np.arange(lo, y.size) / FS
    X = np.column_stack([np.sin(2 * np.pi * f_hz * t), np.cos(2 * np.pi * f_hz * t),
                         np.ones_like(t), t - t.mean()])
    c, *_ = np.linalg.lstsq(X, y[lo:], rcond=None)
    return c[0], c[1]


def sine_gain(y, f_hz, lo):
    """Amplitude of y at f_hz over y[lo:]."""
    return math.hypot(*_sine_fit(y, f_hz, lo))


def butterworth_gain(f_hz, cutoff_hz=None, order=4):
    """|H| at f_hz of the digital (bilinear, pre-warped) Butterworth low-pass of the option:
    order 4, -3 dB at 2 x max_motion_hz (analytic)."""
    cutoff_hz = 2.0 * CUT_HZ if cutoff_hz is None else cutoff_hz
    r = math.tan(math.pi * f_hz / FS) / math.tan(math.pi * cutoff_hz / FS)
    return 1.0 / math.sqrt(1.0 + r ** (2 * order))


def sine_record(f_hz, amp, seed=1, dur_s=8.0):
    rng = np.random.default_rng(seed)
    t = np.arange(int(dur_s * FS)) / FS
    return amp * np.sin(2 * np.pi * f_hz * t + 0.3) + NOISE_DEG_S * rng.standard_normal(t.size)


# ------------------------------------------------------------------ gain
@pytest.mark.parametrize("f_hz", [0.5, 2.0, 7.5, 15.0, CUT_HZ])
@pytest.mark.parametrize("amp", [10.0, 30 * NOISE_DEG_S, 3 * NOISE_DEG_S])
def test_a_sinusoid_inside_the_band_is_kept_within_5_percent(f_hz, amp):
    """Up to max_motion_hz, causal form: the gain stays within 5 % of 1 at 10 deg/s and 30 sigma
    (the Butterworth alone is >= 0.996 there: flat to max_motion_hz, -3 dB at twice it, analytic
    below). At 3 sigma the default filter itself
    reads 1.04-1.10 here (a property of the bank): the option adds
    at most 0.02 to or from the default's gain."""
    z = sine_record(f_hz, amp, seed=int(f_hz * 10))
    lo = int(2 * FS)
    g = sine_gain(gd.denoise(z, FS, max_motion_hz=CUT_HZ), f_hz, lo) / amp
    assert butterworth_gain(f_hz) >= 0.996
    if amp >= 30 * NOISE_DEG_S:
        assert abs(g - 1.0) <= 0.05, g
    else:
        assert abs(g - sine_gain(gd.denoise(z, FS), f_hz, lo) / amp) <= 0.02, g


@pytest.mark.parametrize("f_hz", [60.0, 80.0, 120.0, 150.0, 180.0])
def test_a_tone_above_the_band_is_removed(f_hz):
    """A 3 deg/s 'vibration' tone above max_motion_hz: at most what the Butterworth ahead of
    the bank lets through (analytic |H|: 0.71 at 2 x max_motion_hz, 0.019 at 4x; +10 % + 0.01
    for the noise in the fit), and below 5 % from 4 x max_motion_hz up. Without the option
    the default keeps the tone (gain > 0.9): the option is what removes it."""
    amp = 3.0
    z = sine_record(f_hz, amp, seed=7)
    lo = int(2 * FS)
    g = sine_gain(gd.denoise(z, FS, max_motion_hz=CUT_HZ), f_hz, lo) / amp
    assert g <= 1.1 * butterworth_gain(f_hz) + 0.01, g
    if f_hz >= 4 * CUT_HZ:
        assert g < 0.05, g
    assert sine_gain(gd.denoise(z, FS), f_hz, lo) / amp > 0.9


def sine_phase(y, f_hz, lo):
    """Phase (rad) of y at f_hz over y[lo:]."""
    a, b = _sine_fit(y, f_hz, lo)
    return math.atan2(b, a)


@pytest.mark.parametrize("f_hz", [2.0, 10.0, 20.0, CUT_HZ, 60.0, 80.0, 120.0, 180.0])
def test_offline_form_gain_is_the_zero_phase_low_pass(f_hz):
    """offline=True (the default of `gyrodenoise denoise` on files): the low-pass runs
    zero-phase, so a 10 deg/s sinusoid comes out with gain |H|^2 (analytic: >= 0.99 up to
    max_motion_hz, 0.5 at twice it, 0.0004 at 4x; +-3 % and +0.01 for the noise in the fit)
    and no phase shift (< 1 degree) inside the band, where the causal form lags. The blend
    of a forward and a backward pass each low-passed inside would give |H| cos(phase):
    0.30 at max_motion_hz (the first design; this test failed on it)."""
    amp = 10.0
    z = sine_record(f_hz, amp, seed=5)
    lo = int(2 * FS)
    y = gd.denoise(z, FS, max_motion_hz=CUT_HZ, offline=True)
    g = sine_gain(y, f_hz, lo) / amp
    h2 = butterworth_gain(f_hz) ** 2
    assert 0.97 * h2 - 0.01 <= g <= 1.03 * h2 + 0.01, (g, h2)
    if f_hz <= CUT_HZ:
        assert abs(g - 1.0) <= 0.05
        shift = sine_phase(y, f_hz, lo) - sine_phase(z, f_hz, lo)
        assert abs(math.degrees(shift)) < 1.0, math.degrees(shift)
        causal = gd.denoise(z, FS, max_motion_hz=CUT_HZ)
        assert math.degrees(sine_phase(z, f_hz, lo) - sine_phase(causal, f_hz, lo)) > 2.0


def test_offline_form_c_equals_python_and_restarts():
    """The offline form with the option: the C core and the plain-Python kernels give the
    same bits (batch.run_offline, compiled or not), each run between restarts on its own
    (the second session's output does not depend on the first's samples)."""
    z, rs = golden_record()
    p = K.make_params(method="motion", sample_rate_hz=FS, max_motion_hz=CUT_HZ)
    a = batch.run_offline(p, z, rs)
    b = batch.run_offline(p, z, rs, compiled=False)
    assert a.tolist() == b.tolist()
    assert a.tolist() == gd.denoise(z, FS, restarts=rs, offline=True, max_motion_hz=CUT_HZ).tolist()
    k = int(np.flatnonzero(rs)[0])
    z2 = z.copy()
    z2[:k] += 50.0                              # another first session
    c = batch.run_offline(p, z2, rs)
    assert c[k:].tolist() == a[k:].tolist()


def test_the_option_follows_a_step_and_rest_is_averaged():
    """The bank still works behind the low-pass: at rest the output is far below raw's noise
    (>= 5x), and a 20 deg/s step is reached within 50 ms (the 60 Hz 4th-order Butterworth's
    step settles to 2.5 % in ~25 ms)."""
    rng = np.random.default_rng(4)
    n = int(6 * FS)
    z = NOISE_DEG_S * rng.standard_normal(n)
    z[int(4 * FS):] += 20.0
    y = gd.denoise(z, FS, max_motion_hz=CUT_HZ)
    rest = y[int(2 * FS):int(4 * FS)]
    assert np.std(rest) * 5 <= NOISE_DEG_S
    after = y[int(4 * FS) + int(0.05 * FS):]
    assert np.all(np.abs(after - 20.0) < 0.5)


# ------------------------------------------------------------------ one core, every path
def test_per_sample_equals_batch_c_and_python():
    """Denoiser.step one sample at a time == gd.denoise (C batch) == the plain-Python kernels'
    batch (compiled=False), bit for bit, with restarts and the option on."""
    z, rs = golden_record()
    ref = gd.denoise(z, FS, restarts=rs, max_motion_hz=CUT_HZ)
    d = gd.Denoiser(FS, max_motion_hz=CUT_HZ)
    per = np.array([d.step(v, r) for v, r in zip(z, rs)])
    p = K.make_params(method="motion", sample_rate_hz=FS, max_motion_hz=CUT_HZ)
    py, _ = batch.run(p, K.init_state(p), z, rs, compiled=False)
    assert per.tolist() == ref.tolist() == py.tolist()
    assert not np.array_equal(ref, gd.denoise(z, FS, restarts=rs))     # the option did something


def test_default_unchanged_golden():
    """With the option off (default, or max_motion_hz=0) the filter is the default's, bit for
    bit: tests/data/motion_default_golden.npy is the output of the plain-Python kernels.py on
    golden_record() (regenerated when the pass-through was added: 778 of 1600 samples moved,
    by at most 0.0038 deg/s; with p[P_MO_PT] = 0 the output is main's da1c420 golden;
    regenerated again for the summed-innovation test: 87 samples moved, by at most 2.2e-8 deg/s;
    with p[P_MO_CUS + 1] = 0 the output is the golden before it, bit for bit; regenerated for
    the bank of 13 constant-velocity + 3 constant-acceleration lanes: 789 samples moved, by at
    most 1.5e-8 deg/s (median of those 9.4e-14); with p[P_MO_NCA] = 0 the output is the golden
    before it, bit for bit; regenerated when motion's warm-up came to end at its noise floor's
    first block (127 samples, not warmup_s's 400 at 400 Hz): 1342 samples moved (the 273 of
    samples 127-399, raw before, and the bank's history after them), by at most 0.0156 deg/s
    (median of those 1.8e-6); to regenerate: the plain-Python
    batch.run(p, K.init_state(p), z, restarts=rs, compiled=False) saved with np.save)."""
    z, rs = golden_record()
    golden = np.load(GOLDEN)
    assert gd.denoise(z, FS, restarts=rs).tolist() == golden.tolist()
    assert gd.denoise(z, FS, restarts=rs, max_motion_hz=0.0).tolist() == golden.tolist()
    p = K.make_params(method="motion", sample_rate_hz=FS)
    assert p == K.make_params(method="motion", sample_rate_hz=FS, max_motion_hz=0.0)
    assert p[K.P_LP_NSEC] == 0.0


# ------------------------------------------------------------------ bad values
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, -1.0, 200.0, 300.0])
def test_library_refuses_bad_values_naming_the_option(bad):
    with pytest.raises(ValueError, match="max_motion_hz") as exc:
        gd.denoise(np.zeros(10), FS, max_motion_hz=bad)
    assert "\n" not in str(exc.value)
    with pytest.raises(ValueError, match="max_motion_hz"):
        gd.Denoiser(FS, max_motion_hz=bad)


@pytest.mark.parametrize("method", ["shakf", "kf", "lowpass", "none"])
def test_library_refuses_the_option_with_other_methods(method):
    with pytest.raises(ValueError, match="max_motion_hz applies to method 'motion' only"):
        gd.denoise(np.zeros(10), FS, method=method, max_motion_hz=CUT_HZ)
    gd.denoise(np.zeros(10), FS, method=method, max_motion_hz=0.0)      # 0 = off: accepted


@pytest.fixture(scope="module")
def vib_csv(tmp_path_factory):
    d = tmp_path_factory.mktemp("rigid")
    z, _ = golden_record()
    path = d / "vib.csv"
    np.savetxt(path, np.column_stack([np.arange(z.size) / FS, z]), delimiter=",",
               header="time,rate", comments="", fmt="%.17g")
    return path, z


def test_cli_applies_the_option(vib_csv, tmp_path):
    path, z = vib_csv
    out = tmp_path / "o.csv"
    status, _, err = run_main("denoise", path, "-o", out, "--max-motion-hz", CUT_HZ, "--causal")
    assert status == 0 and "a 4th-order low-pass flat to 30 Hz, -3 dB at 60 Hz, before the filter bank" in err
    a = np.genfromtxt(out, delimiter=",", names=True)
    ref = gd.denoise(z, FS, max_motion_hz=CUT_HZ)
    col = [n for n in a.dtype.names if n not in ("time", "raw", "rate")][0]
    np.testing.assert_allclose(a[col], ref, rtol=1e-9, atol=1e-9)


def test_cli_says_where_the_low_pass_really_cuts_and_blames_no_absent_filter(tmp_path):
    """At 50 Hz (log171.bin's rate) --max-motion-hz 20 cannot put the -3 dB point at 40 Hz: it is
    capped at 0.45 x 50 = 22.5 Hz, and the message says so (it said "content above 20 Hz removed").
    A spike note under method motion does not credit it to "the SHAKF's outlier gate"."""
    fs = 50.0
    z = np.random.default_rng(5).standard_normal(3000) * 0.1
    z[1500] = 40.0
    path = tmp_path / "drone.csv"
    np.savetxt(path, np.column_stack([np.arange(z.size) / fs, z]), delimiter=",", header="time,rate",
               comments="", fmt="%.17g")
    status, _, err = run_main("denoise", path, "-o", tmp_path / "o.csv", "--max-motion-hz", 20)
    assert status == 0, err
    assert K.rigid_cutoff_hz(20.0, fs) == pytest.approx(22.5)
    assert "flat to 20 Hz, -3 dB at 22.5 Hz (at most 0.45 x the sample rate" in err
    assert "content above 20 Hz removed" not in err
    assert "isolated spike" in err and "SHAKF's outlier gate" not in err


@pytest.mark.slow
@pytest.mark.parametrize("args,named", [
    (["--max-motion-hz", "nan"], "--max-motion-hz"), (["--max-motion-hz", "inf"], "--max-motion-hz"),
    (["--max-motion-hz", "-1"], "--max-motion-hz"), (["--max-motion-hz", "250"], "--max-motion-hz"),
    (["--max-motion-hz", "30", "--method", "kf"], "--max-motion-hz"),
    (["--max-motion-hz", "abc"], "--max-motion-hz")])
def test_cli_refuses_bad_values(vib_csv, tmp_path, args, named):
    """One line naming the option, exit 2, no traceback, nothing written."""
    import subprocess
    import sys
    path, _ = vib_csv
    out = tmp_path / "o.csv"
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "denoise", str(path), "-o", str(out), *args],
                       capture_output=True, text=True, timeout=120)
    lines = [ln for ln in p.stderr.strip().splitlines() if "error" in ln]   # (the reader's notes aside)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert len(lines) == 1 and named in lines[0], p.stderr
    assert not out.exists()


@pytest.mark.parametrize("args,named", [
    (["--max-motion-hz", "nan"], "--max-motion-hz"), (["--max-motion-hz", "inf"], "--max-motion-hz"),
    (["--max-motion-hz", "-1"], "--max-motion-hz"), (["--max-motion-hz", "abc"], "--max-motion-hz"),
    (["--max-motion-hz", "30", "--method", "lowpass"], "--max-motion-hz")])
def test_bridge_refuses_bad_values(tmp_path, args, named):
    status, out, err = run_main("mavlink", DATA / "ardusub_small.BIN", "-o", tmp_path / "o",
                            "--no-plots", "--no-csv", *args)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and named in lines[0], err
    assert out == "" and not (tmp_path / "o").exists()


def test_bridge_text_summary_names_the_option(tmp_path):
    """The text summary (not only the JSON) says that --max-motion-hz was applied: the
    "filtered log:" line said only "(method motion; ...)"."""
    status, out, err = run_main("mavlink", DATA / "ardusub_small.BIN", "-o", tmp_path / "a",
                            "--max-motion-hz", "5", "--no-plots", "--no-csv")
    assert status == 0, err
    line = [ln for ln in out.splitlines() if "filtered log:" in ln]
    assert line and "rigid body: --max-motion-hz 5 " in line[0], out


def test_bridge_applies_the_option_and_says_so(tmp_path):
    """The option reaches the filter (the CSV equals gd.denoise with it, causal form) and
    the JSON's filter_options names it; above the Nyquist frequency of every stream the option
    is refused (ardusub_small.BIN's gyro is at 25 Hz)."""
    log = DATA / "ardusub_small.BIN"
    status, out, _ = run_main("mavlink", log, "-o", tmp_path / "a", "--max-motion-hz", "5", "--causal",
                          "--no-plots", "--json")
    assert status == 0
    rep = json.loads(out)["logs"][0]
    assert rep["filter_options"]["max_motion_hz"] == 5.0
    s = rep["streams"][0]
    a = np.genfromtxt(s["csv"], delimiter=",", names=True)
    assert s["restarts"] == 0
    for ax in "xyz":
        ref = gd.denoise(a[f"raw_{ax}"], s["filter_rate_hz"], max_motion_hz=5.0)
        default = gd.denoise(a[f"raw_{ax}"], s["filter_rate_hz"])
        close = np.abs(a[f"filtered_{ax}"] - ref) <= 1e-6 * (1 + np.abs(ref))
        assert close.mean() > 0.99, ax
        assert np.max(np.abs(ref - default)) > 1e-3, ax        # the option changed the output
    status, out, err = run_main("mavlink", log, "-o", tmp_path / "b", "--max-motion-hz", "15", "--no-plots",
                                "--no-csv", "--json")
    # its only gyro stream cannot take it: the option is refused (as --cutoff-hz is), one line
    assert status == 2 and json.loads(out)["exit_status"] == 2, err
    assert "--max-motion-hz 15 is at or above the Nyquist frequency of every gyro stream" in err, err
