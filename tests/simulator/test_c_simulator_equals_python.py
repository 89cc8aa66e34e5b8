"""The simulated gyro in C (gyrodenoise/core/gdsim.c) and its plain-Python
specification (gyrodenoise/core/simkernels.py): equal bit for bit on every card
term; each term as the card says; the generator against published values and the
normal law; sample by sample and batch the same numbers.
gd.simulate and SimStream are adapters over it (the C, or the Python twin where
the extension is not built): the same numbers."""
import math

import numpy as np
import pytest

import gyrodenoise as gd
import gyrodenoise.simulator as SIM
from gyrodenoise.core import simkernels as SK
from gyrodenoise.simulator import parse_card
from tests.helpers import CHOST, DATA, REPO, run_wine

C = pytest.importorskip("gyrodenoise.core._gdcore")

#: a card with every term (shared with tests/fmu/test_native_simulator.py)
EVERY_TERM = (DATA / "every_term.toml").read_text()

# the angle Gauss-Markov term: two instances (one with sigma 0: not drawn) on top of every other term
EVERY_TERM_AGM = EVERY_TERM + "".join(f"[[terms.angle_gauss_markov]]\nsigma = {s}\ntau = {t}\n"
                                      for s, t in ((3.0e-5, 0.04), (0.0, 1.0), (1.0e-4, 2.5)))


def c_buffers(card, seed):
    v = np.array(SK.card_vector(card))
    p = np.zeros(C.sim_n_params(v))
    C.sim_params(v, float(seed), p)
    s = np.zeros(C.sim_n_state(p))
    C.sim_reset(p, s)
    return p, s


def c_simulate(card, n, seed, truth=None, restarts=None):
    p, s = c_buffers(card, seed)
    out = np.zeros(n)
    C.sim_run(p, s, None if truth is None else np.ascontiguousarray(truth, dtype=float),
              None if restarts is None else np.ascontiguousarray(restarts, dtype=bool), out)
    return out


@pytest.mark.parametrize("text", [EVERY_TERM, EVERY_TERM_AGM, "[sensor]\nsample_rate_hz = 200.0\n"],
                         ids=["every term", "every term + angle GM", "no term"])
@pytest.mark.parametrize("seed", [0, 12345, 2 ** 53 - 1])
def test_c_equals_the_python_specification_bit_for_bit(text, seed):
    card = parse_card(text)
    p, s = c_buffers(card, seed)
    pp = SK.params(SK.card_vector(card), seed)
    sp = SK.reset(pp)
    assert list(p) == pp and list(s) == sp
    n = 1500
    rng = np.random.default_rng(1)
    truth = np.cumsum(rng.standard_normal(n)) * 0.01
    rs = np.zeros(n, dtype=bool)
    rs[[0, 400, 401, 1200]] = True
    out = np.zeros(n)
    C.sim_run(p, s, truth, rs, out)
    ref = SK.run(pp, sp, n, truth, rs)
    assert np.array_equal(out, ref)
    assert list(s) == sp


def test_every_term_is_simulated():
    """Each term moves the output the way the card says (noise-free terms exactly)."""
    base = "[sensor]\nsample_rate_hz = 10.0\n[terms]\n"
    n = 600
    t = np.arange(n) / 10.0

    def sim(terms, restarts=None):
        return c_simulate(parse_card(base + terms), n, 3, restarts=restarts)

    np.testing.assert_allclose(sim("rate_ramp = { R = 3600.0 }"), (3600.0 / 3600.0 ** 2) * t, rtol=0, atol=1e-15)
    np.testing.assert_allclose(sim("constant_bias = { value = 36.0 }"), 0.01, rtol=0, atol=1e-15)
    y = sim("turn_on_transient = { amplitude = 3600.0, tau = 20.0 }", restarts=t == 30.0)
    k = np.arange(n) - np.where(t >= 30.0, 300, 0)
    np.testing.assert_allclose(y, np.exp(-k / 10.0 / 20.0), rtol=1e-14, atol=0)
    y = sim("[[terms.sinusoid]]\namplitude = 3600.0\nfrequency = 0.5\nphase_deg = 90.0")
    np.testing.assert_allclose(y, np.cos(2 * np.pi * 0.5 * t), rtol=0, atol=1e-13)
    # the bias repeatability: a fresh draw at a restart, the same bias otherwise
    y = sim("constant_bias = { value = 0.0, repeatability = 3600.0 }", restarts=t == 30.0)
    assert len(set(y[:300])) == 1 and len(set(y[300:])) == 1 and y[0] != y[300]
    # stochastic terms: the white ones at their variance (N and Q), the others not zero
    y = c_simulate(parse_card(base + "angle_random_walk = { N = 60.0 }"), 40000, 1)
    assert np.var(y) == pytest.approx(1.0 * 10.0, rel=0.03)          # (N deg/sqrt(s))^2 / T
    for term in ("bias_instability = { B = 1.0 }", "rate_random_walk = { K = 1.0 }",
                 "quantization = { Q = 1e-3 }", "[[terms.gauss_markov]]\nsigma = 1.0\ntau = 2.0"):
        assert np.std(sim(term)) > 0, term


def test_splitmix64_and_xoshiro_against_published_values():
    # splitmix64 from state 0 (Vigna's reference splitmix64.c)
    x, a = SK._splitmix64(0)
    x, b = SK._splitmix64(x)
    assert (a, b) == (0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4)
    # xoshiro256** from state {1, 2, 3, 4} (reference xoshiro256starstar.c): 11520, 0, 1509978240
    w = [1, 2, 3, 4]
    assert [SK._next_u64(w) for _ in range(3)] == [11520, 0, 1509978240]


def test_normal_deviates_follow_the_normal_law():
    from scipy import stats
    s = [0.0] * 8
    SK._seed_stream(99, 0, s, 0)
    w = SK._load(s, 0)
    z = np.array([SK._normal(w) for _ in range(20000)])
    assert stats.kstest(z, "norm").pvalue > 1e-3
    assert abs(z.mean()) < 4 / math.sqrt(len(z)) and abs(z.var() - 1) < 0.05


def test_sample_by_sample_equals_batch_and_seeds_reproduce():
    card = parse_card(EVERY_TERM)
    n = 700
    rs = np.zeros(n, dtype=bool)
    rs[333] = True
    truth = np.linspace(-1, 1, n)
    batch = c_simulate(card, n, 5, truth, rs)
    p, s = c_buffers(card, 5)
    one = np.zeros(1)
    steps = []
    for i in range(n):
        C.sim_run(p, s, truth[i:i + 1].copy(), rs[i:i + 1].copy(), one)
        steps.append(one[0])
    assert np.array_equal(steps, batch)
    assert np.array_equal(c_simulate(card, n, 5, truth, rs), batch)
    assert not np.array_equal(c_simulate(card, n, 6, truth, rs), batch)


def test_malformed_buffers_are_refused():
    card = parse_card(EVERY_TERM)
    p, s = c_buffers(card, 1)
    with pytest.raises(ValueError):
        C.sim_reset(p, np.zeros(len(s) + 1))
    with pytest.raises(ValueError):
        C.sim_params(np.zeros(5), 1.0, p)
    with pytest.raises(ValueError):
        C.sim_params(np.array(SK.card_vector(card)), -1.0, p)
    with pytest.raises(ValueError):
        C.sim_run(p, s, np.zeros(3), None, np.zeros(4))


# ------------------------------------------------ the same numbers from plain C
CORE = REPO / "gyrodenoise" / "core"


def _compile_driver(cc, exe, tmp):
    import subprocess
    proc = subprocess.run([*cc, "-std=c99", "-O2", "-ffp-contract=off", f"-I{CORE}", "-o", str(exe),
                           str(CHOST / "simdriver.c"), str(CORE / "gdsim.c"), "-lm"],
                          capture_output=True, text=True, timeout=300, cwd=tmp)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("plat", ["linux64", "win64"])
def test_plain_c_on_each_platform_equals_the_specification(plat, tmp_path):
    """gdsim.c compiled by itself (linux64: gcc; win64: the FMU's Windows compiler, run under
    wine) gives the plain-Python specification's numbers: the generator and the model are
    portable (equal bit for bit here; 1e-12 relative is the contract)."""
    import os
    import shutil
    from gyrodenoise.fmu import native
    card = parse_card(EVERY_TERM_AGM)
    n, seed = 2000, 77
    if plat == "linux64":
        if shutil.which("gcc") is None:
            pytest.skip("gcc not installed")
        exe, cmd, env = tmp_path / "simdriver", [], None
        _compile_driver(["gcc"], exe, tmp_path)
    else:
        wine = shutil.which("wine") or shutil.which("wine64")
        if wine is None:
            pytest.skip("wine not installed (scripts/install_fmu_test_tools.sh)")
        try:
            cc, _ = native.compiler_for("win64")
        except native.InputError as exc:
            pytest.skip(f"no Windows C compiler: {exc}")
        exe, cmd, env = tmp_path / "simdriver.exe", [wine], dict(os.environ, WINEDEBUG="-all")
        _compile_driver(cc, exe, tmp_path)
    vec = " ".join(repr(x) for x in SK.card_vector(card))
    proc = run_wine([*cmd, str(exe), str(seed), str(n)], input=vec, env=env, timeout=180)   # files, not pipes (linux64 too)
    assert proc.returncode == 0, proc.stderr
    got = np.array([float(x) for x in proc.stdout.split()])
    pp = SK.params(SK.card_vector(card), seed)
    rs = np.zeros(n, dtype=bool)
    rs[n // 2] = True
    ref = np.array(SK.run(pp, SK.reset(pp), n, None, rs))
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=0)
    print(f"\ngdsim.c on {plat}: max |C - Python| = {np.max(np.abs(got - ref)):.3g} deg/s "
          f"({int(np.sum(got != ref))} of {n} samples not bit-identical)")


def test_gd_simulate_is_the_c_model_and_the_fallback_gives_the_same_numbers(monkeypatch):
    """gd.simulate runs gdsim.c; without the extension SimStream runs the Python twin:
    both equal the model's buffers driven directly, bit for bit, with truth and restarts;
    the stream's state round-trips."""
    card = parse_card(EVERY_TERM)
    n = 600
    truth = np.linspace(-3.0, 3.0, n)
    rs = np.zeros(n, dtype=bool)
    rs[[0, 250, 400]] = True
    want = c_simulate(card, n, 77, truth, rs)
    rec = gd.simulate(card, n, seed=77, true_rate_deg_s=truth, restarts=rs)
    assert np.array_equal(rec.rate_deg_s, want)
    st = SIM.SimStream(card, seed=77)
    head = st.run(300, truth[:300], rs[:300])
    saved = st.get_state()
    tail = st.run(300, truth[300:], rs[300:])
    st.set_state(saved)
    assert np.array_equal(np.concatenate([head, tail]), want)
    assert np.array_equal(st.run(300, truth[300:], rs[300:]), tail)
    monkeypatch.setattr(SIM, "_core", lambda: None)
    py = SIM.SimStream(card, seed=77)
    assert py._C is None
    assert np.array_equal(py.run(n, truth, rs), want)


@pytest.mark.parametrize("seed", [-1, 2 ** 53, 1.5, True])
def test_bad_seed_is_an_input_error(seed):
    from gyrodenoise.errors import InputError
    with pytest.raises(InputError, match="seed must be a whole number"):
        gd.simulate("paper_fog", 10, seed=seed)


# ------------------------------------------------ the angle Gauss-Markov term
# sha256 of gd.simulate(paper_fog, 3000, seed=7, restarts at 0, 1000, 2000).rate_deg_s.tobytes(), computed with
# main's plain-Python twin (commit da1c420, before the angle Gauss-Markov term existed): an old card's seeds keep
# their realisations bit for bit.
PAPER_FOG_SEED7_SHA256 = "efcba9abb1b48658"


def test_a_card_without_the_new_term_draws_the_numbers_it_drew_before():
    import hashlib
    rs = np.isin(np.arange(3000), [0, 1000, 2000])
    y = gd.simulate("paper_fog", 3000, seed=7, restarts=rs).rate_deg_s
    assert hashlib.sha256(y.tobytes()).hexdigest()[:16] == PAPER_FOG_SEED7_SHA256
    # the older 92-number card vector (no angle Gauss-Markov block) is still taken, same buffers
    card = parse_card(EVERY_TERM)
    v = np.array(SK.card_vector(card))
    p_new, _ = c_buffers(card, 3)
    p_old = np.zeros(C.sim_n_params(v[:SK.AGM_AT]))
    C.sim_params(v[:SK.AGM_AT], 3.0, p_old)
    assert np.array_equal(p_new, p_old) and SK.params(list(v[:SK.AGM_AT]), 3) == list(p_new)


def test_angle_gauss_markov_has_its_own_stream():
    """Adding the term leaves every other term's realisation as it was: the card with it
    minus the card without it is the term alone (same seed), to rounding."""
    agm = "".join(f"[[terms.angle_gauss_markov]]\nsigma = {s}\ntau = {t}\n" for s, t in ((3.0e-5, 0.04), (1.0e-4, 2.5)))
    n, seed = 5000, 11
    both = c_simulate(parse_card(EVERY_TERM + agm), n, seed)
    rest = c_simulate(parse_card(EVERY_TERM), n, seed)
    alone = c_simulate(parse_card("[sensor]\nsample_rate_hz = 100.0\n" + agm), n, seed)
    assert np.std(alone) > 0
    np.testing.assert_allclose(both - rest, alone, rtol=0, atol=1e-12 * np.max(np.abs(both)))


@pytest.mark.parametrize("tau_s", [0.005, 0.2, 5.0])
def test_angle_gauss_markov_allan_variance_against_the_closed_form(tau_s):
    """Simulated Allan variance of the term (4 seeds x 2e5 samples at 100 Hz) against the
    closed form sigma^2 (3 - 4 a^m + a^2m) / (m T)^2 (spectral.angle_gm_avar), at octave
    cluster sizes 1 .. 2^11 (>= 97 clusters): within 4 standard errors of the mean of the
    4 estimates, the error of one estimate taken as sqrt(2 / (N/m - 1)) relative (IEEE 952
    C.1, conservative for a process whose Allan variance is white-like beyond tau_s) - and
    not a white angle (quantization Q = sigma) curve where the correlation time matters."""
    from gyrodenoise.analysis.allan import adev
    from gyrodenoise.modelgap.spectral import allan_columns, angle_gm_avar
    fs, n, sigma = 100.0, 200_000, 2.0e-3
    card = parse_card(f"[sensor]\nsample_rate_hz = {fs}\n[[terms.angle_gauss_markov]]\nsigma = {sigma}\n"
                      f"tau = {tau_s}\n")
    m = 2 ** np.arange(0, 12)
    est = np.array([adev(c_simulate(card, n, seed), fs, m=m)[1] ** 2 for seed in (1, 2, 3, 4)])
    want = angle_gm_avar(m, fs, tau_s, sigma)
    rel_se = np.sqrt(2.0 / (n / m - 1.0)) / 2.0          # of the mean of 4
    z = (est.mean(axis=0) / want - 1.0) / rel_se
    assert np.all(np.abs(z) < 4.0), z
    # the gap workflow's exact column (numerical integral of the PSD) is the same curve
    np.testing.assert_allclose(allan_columns([("angle_gauss_markov", tau_s)], m, fs)[:, 0] * sigma ** 2, want,
                               rtol=1e-4)
    if tau_s >= 0.2:    # at m T ~ tau_s the correlation shows: far from the white-angle value 3 sigma^2/(mT)^2
        k = int(np.argmin(np.abs(m / fs - tau_s)))
        assert est.mean(axis=0)[k] < 0.8 * 3.0 * sigma ** 2 / (m[k] / fs) ** 2


def test_angle_gauss_markov_bad_values_are_one_line():
    from gyrodenoise.errors import InputError
    base = "[sensor]\nsample_rate_hz = 100.0\n[[terms.angle_gauss_markov]]\n"
    for body, msg in (("sigma = -1.0\ntau = 1.0\n", "angle_gauss_markov\\[0\\].sigma must be >= 0 deg"),
                      ("sigma = 1.0\ntau = 0.0\n", "angle_gauss_markov\\[0\\].tau must be > 0 s"),
                      ("sigma = 1.0\n", "missing the field tau"),
                      ("sigma = 1.0\ntau = 'x'\n", "tau must be a number"),
                      ("sigma = 1.0\ntau = 1.0\nQ = 2.0\n", "unknown field")):
        with pytest.raises(InputError, match=msg) as ei:
            parse_card(base + body, "c.toml")
        assert "\n" not in str(ei.value) and "c.toml" in str(ei.value)
