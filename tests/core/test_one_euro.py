"""method="one_euro": the 1-euro filter (Casiez, Roussel, Vogel, CHI 2012) in the core.

Held to a reference written here from the paper (uncentred, plain Python), to scipy's
first-order filter where beta = 0, and the C core to kernels.py bit for bit."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.core import batch
from gyrodenoise.core import kernels as K

FS = 400.0


def paper_one_euro(z, fs, min_cutoff, beta, d_cutoff):
    """The 1-euro filter as the paper writes it: alpha = 1 / (1 + tau / Te), tau = 1 / (2 pi fc);
    the derivative of the raw signal low-passed at d_cutoff, the cutoff min_cutoff + beta |dx|."""
    def alpha(fc):
        return 1.0 / (1.0 + (1.0 / (2.0 * math.pi * fc)) * fs)
    y = [z[0]]
    dx = 0.0
    for k in range(1, len(z)):
        dx += alpha(d_cutoff) * ((z[k] - z[k - 1]) * fs - dx)
        y.append(y[-1] + alpha(min_cutoff + beta * abs(dx)) * (z[k] - y[-1]))
    return np.array(y)


def _record(n=4000, seed=0, offset=0.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    truth = 30.0 * np.sin(2 * math.pi * 0.7 * t) * (t > 2.0)
    return offset + truth + rng.normal(0.0, 0.5, n)


@pytest.mark.parametrize("offset", [0.0, 1.0e4])
@pytest.mark.parametrize("kw", [{}, {"min_cutoff_hz": 0.5, "beta": 0.02, "d_cutoff_hz": 2.0},
                                {"min_cutoff_hz": 150.0, "beta": 0.0}])
def test_equals_the_paper_s_filter(kw, offset):
    """To the rounding of the centring (the core filters z - z[0]): relative to the record's scale."""
    z = _record(offset=offset)
    y = gd.denoise(z, FS, method="one_euro", **kw)
    ref = paper_one_euro(z, FS, kw.get("min_cutoff_hz", 1.0), kw.get("beta", 0.001), kw.get("d_cutoff_hz", 1.0))
    assert np.max(np.abs(y - ref)) <= 1e-12 * (np.max(np.abs(z)) + 1.0)
    assert y[0] == z[0]


def test_beta_zero_is_scipy_s_first_order_low_pass():
    from scipy.signal import lfilter
    z = _record()
    a = 1.0 / (1.0 + FS / (2.0 * math.pi * 3.0))
    ref = lfilter([a], [1.0, a - 1.0], z - z[0], zi=[(1.0 - a) * 0.0])[0] + z[0]
    ref[0] = z[0]
    y = gd.denoise(z, FS, method="one_euro", min_cutoff_hz=3.0, beta=0.0)
    assert np.max(np.abs(y[1:] - ref[1:])) < 1e-10
    # and beta > 0 follows a step faster (the cutoff rises with the rate's change)
    step = np.r_[np.zeros(400), np.full(400, 50.0)]
    slow = gd.denoise(step, FS, method="one_euro", min_cutoff_hz=1.0, beta=0.0)
    fast = gd.denoise(step, FS, method="one_euro", min_cutoff_hz=1.0, beta=0.01)
    assert fast[410] > 2.5 * slow[410]


def test_restart_starts_on_the_sample():
    z = _record()
    r = np.zeros(z.size, bool)
    r[1000] = True
    y = gd.denoise(z, FS, method="one_euro", restarts=r)
    assert y[1000] == z[1000]
    assert np.array_equal(y[1000:], gd.denoise(z[1000:], FS, method="one_euro"))


@pytest.mark.parametrize("kw", [{}, {"min_cutoff_hz": 0.3, "beta": 0.5, "d_cutoff_hz": 7.0}])
def test_c_core_equals_python_bit_for_bit(kw):
    """Every output and every state float, over restarts, spikes up to 1e300, NaN and inf."""
    pytest.importorskip("gyrodenoise.core._gdcore")
    rng = random.Random(5)
    z = [rng.gauss(0.0, 1.0) + 1e3 * (i > 700) for i in range(2000)]
    for i, v in ((150, 1e155), (151, -1e300), (400, math.nan), (401, math.inf), (900, 1e7)):
        z[i] = v
    r = [i in (300, 1200) for i in range(2000)]
    p = K.make_params(2, "one_euro", FS, **kw)
    s_py = K.init_state(p)
    out_py = [K.step(p, s_py, v, q) for v, q in zip(z, r)]
    out_c, s_c = batch.run(p, K.init_state(p), np.array(z), np.array(r))
    assert np.array_equal(np.array(out_py), out_c, equal_nan=True)
    assert np.array_equal(np.array(s_py), s_c, equal_nan=True)
    d = gd.Denoiser(FS, method="one_euro", ar_order=2, **kw)      # the per-sample C path
    assert np.array_equal([d.step(v, q) for v, q in zip(z, r)], out_c, equal_nan=True)


def test_denoise_cli(tmp_path):
    from gyrodenoise.cli.program import main
    z = _record(800)
    src = tmp_path / "in.csv"
    src.write_text("time,rate\n" + "".join(f"{i / FS!r},{float(v)!r}\n" for i, v in enumerate(z)))
    out = tmp_path / "out.csv"
    assert main(["denoise", str(src), "-o", str(out), "--method", "one_euro", "--min-cutoff-hz", "2",
                 "--beta", "0.01"]) == 0
    got = np.loadtxt(out, delimiter=",", skiprows=1, usecols=2)
    assert np.allclose(got, gd.denoise(z, FS, method="one_euro", min_cutoff_hz=2.0, beta=0.01), rtol=0, atol=1e-9)


def test_cli_refuses_its_options_with_another_method(tmp_path, capsys):
    from gyrodenoise.cli.program import main
    src = tmp_path / "in.csv"
    src.write_text("time,rate\n0,1\n0.0025,2\n")
    assert main(["denoise", str(src), "-o", str(tmp_path / "o.csv"), "--method", "kf", "--beta", "0.1"]) == 2
    assert "--beta applies to --method one_euro only, not kf" in capsys.readouterr().err
    assert main(["denoise", str(src), "-o", str(tmp_path / "o.csv"), "--method", "one_euro",
                 "--min-cutoff-hz", "0"]) == 2
    assert "min_cutoff_hz out of range" in capsys.readouterr().err


def test_bridge_filters_a_log_with_it(tmp_path, capsys):
    """gyrodenoise mavlink --method one_euro: each axis is gd.denoise's one_euro of its samples
    (a log without restarts), the report names the parameters; its options with another
    method are refused in one line."""
    from gyrodenoise.cli.program import main
    from gyrodenoise.flightlog.process import process_log
    from tests.helpers import DATA
    path = DATA / "ardusub_small.BIN"
    fk = {"min_cutoff_hz": 3.0, "beta": 0.01}
    rep = process_log(path, tmp_path / "a", plots=False, html=False, method="one_euro", filter_kw=fk, causal=True)
    assert rep["filter_options"] == {**fk, "d_cutoff_hz": 1.0}
    st = rep["streams"][0]
    a = np.genfromtxt(st["csv"], delimiter=",", names=True)
    default = process_log(path, tmp_path / "b", plots=False, html=False, method="one_euro", causal=True)
    b = np.genfromtxt(default["streams"][0]["csv"], delimiter=",", names=True)
    assert st["restarts"] == 0 and not a["restart"].any()
    for ax in "xyz":
        ref = gd.denoise(a[f"raw_{ax}"], st["filter_rate_hz"], method="one_euro", **fk)
        np.testing.assert_allclose(a[f"filtered_{ax}"], ref, rtol=0, atol=1e-7)   # the CSV keeps 9 digits
        assert not np.array_equal(a[f"filtered_{ax}"], b[f"filtered_{ax}"])
        assert np.std(np.diff(a[f"filtered_{ax}"])) < np.std(np.diff(a[f"raw_{ax}"]))
    assert main(["mavlink", str(path), "-o", str(tmp_path / "c"), "--method", "kf", "--beta", "0.1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--beta applies to --method one_euro only, not kf" in err
