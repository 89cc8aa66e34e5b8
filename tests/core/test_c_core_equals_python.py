"""The C core (gyrodenoise/core/gdcore.c, via gyrodenoise.core._gdcore) held to the
plain-Python executable specification gyrodenoise/core/kernels.py.

Every output and the final state must be the same double, bit for bit (a NaN
equal to a NaN), for every method, AR orders 1..6, the outlier gate on and off,
lam 1 and < 1, on seeded random and hostile records (steps, lone samples up to
1e300, offsets of 1e7, constant and quantised records, oscillating start-ups,
restarts): the C keeps the Python's operations and their order, and is built
without fused multiply-adds (-ffp-contract=off). No tolerance: one scaled by the
record's largest sample (1e300 in the hostile records) would let a sample of
ordinary size be wrong by any amount.
"""

from __future__ import annotations

import array
import random
import zlib

import numpy as np
import pytest

import gyrodenoise.core.kernels as K

C = pytest.importorskip(
    "gyrodenoise.core._gdcore",
    reason="the C extension gyrodenoise.core._gdcore is not built "
           "(python setup.py build_ext --inplace, or pip install .)")

from hypothesis import given, settings, strategies as st  # noqa: E402

FS = 50.0   # a short warm-up (10 (n+1) samples at least), so records stay short


def params(method, n, sigma, lam, run=5):
    return K.make_params(n, method, sample_rate_hz=FS, lam=lam, outlier_sigma=sigma,
                         outlier_run=run)


def py_run(p, z, restarts, s=None):
    """The reference: K.step over Python lists."""
    s = K.init_state(p) if s is None else list(s)
    out = [K.step(p, s, float(zi), bool(ri)) for zi, ri in zip(z, restarts)]
    return out, s


def c_step_run(p, z, restarts, s=None):
    pa = array.array("d", p)
    sa = array.array("d", K.init_state(p) if s is None else s)
    out = [C.step(pa, sa, float(zi), bool(ri)) for zi, ri in zip(z, restarts)]
    return out, list(sa)


def c_batch(p, z, restarts, s=None):
    pa = np.asarray(p, dtype=np.float64)
    sa = np.array(K.init_state(p) if s is None else s, dtype=np.float64)
    za = np.asarray(z, dtype=np.float64)
    out = np.empty_like(za)
    C.run(pa, sa, za, np.asarray(restarts, dtype=np.bool_), out)
    return out.tolist(), sa.tolist()


def assert_same(a, b, what):
    """The same doubles, bit for bit (a NaN equal to a NaN): names the first sample that
    differs, whatever the size of the others."""
    assert len(a) == len(b), f"{what}: {len(a)} values != {len(b)}"
    for i, (x, y) in enumerate(zip(a, b)):
        if x == y or (x != x and y != y):
            continue
        raise AssertionError(f"{what}[{i}]: python {x!r} != C {y!r} (difference {y - x!r})")


def check_against_python(p, z, restarts):
    ref_out, ref_s = py_run(p, z, restarts)
    out, s = c_step_run(p, z, restarts)
    assert_same(ref_out, out, "output")
    assert_same(ref_s, s, "state")
    for v in out:
        assert v - v == 0.0          # the kernels never output a non-finite number
    return ref_out, ref_s


# ----------------------------------------------------------------- records
def hostile(kind, n, rng):
    """A record of ``n`` samples and its restart flags."""
    z = [0.0] * n
    r = [False] * n
    if kind == "gauss":
        z = [rng.gauss(0.0, 1.0) for _ in range(n)]
    elif kind == "ar":                       # a coloured record the AR model can identify
        a = 0.0
        for i in range(n):
            a = 0.9 * a + rng.gauss(0.0, 0.1)
            z[i] = 3.0 + a + rng.gauss(0.0, 0.02)
    elif kind == "steps":
        lvl = 0.0
        for i in range(n):
            if i % 97 == 60:
                lvl = rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(0, 3)
            z[i] = lvl + rng.gauss(0.0, 0.01)
    elif kind == "spikes":                   # lone huge samples, up to 1e300
        z = [rng.gauss(0.0, 0.1) for _ in range(n)]
        for i in range(0, n, 53):
            z[min(n - 1, i + 40)] = rng.choice([-1.0, 1.0]) * 10.0 ** rng.choice(
                [3, 8, 20, 100, 155, 160, 200, 300])
    elif kind == "offset":                   # 1e7 deg/s offset, tiny noise
        z = [1e7 + rng.gauss(0.0, 1e-3) for _ in range(n)]
    elif kind == "constant":
        z = [2.5] * n
    elif kind == "zeros":
        z = [0.0] * n
    elif kind == "quantised":
        z = [round(rng.gauss(0.0, 0.6)) * 0.0625 for _ in range(n)]
    elif kind == "oscillating":              # +-A alternating from the first sample
        z = [(1.0 if i % 2 else -1.0) * 10.0 ** rng.uniform(-3, 4) for i in range(n)]
    elif kind == "ramp":
        z = [0.01 * i + rng.gauss(0.0, 0.05) for i in range(n)]
    elif kind == "restarts":
        z = [rng.gauss(5.0, 1.0) for _ in range(n)]
        for i in range(0, n, 37):
            r[i] = True
    else:  # pragma: no cover
        raise ValueError(kind)
    return z, r


KINDS = ("gauss", "ar", "steps", "spikes", "offset", "constant", "zeros", "quantised",
         "oscillating", "ramp", "restarts")


def mixed_record(seed, n_each=160):
    """Every hostile kind in turn (a restart at some joins), one record."""
    rng = random.Random(seed)
    z, r = [], []
    kinds = list(KINDS)
    rng.shuffle(kinds)
    for kind in kinds:
        zk, rk = hostile(kind, n_each, rng)
        if rng.random() < 0.5:
            rk[0] = True
        z += zk
        r += rk
    return z, r


# ------------------------------------------------------------------- tests
def test_constants_mirror_kernels():
    for name, value in C.CONSTANTS.items():
        assert getattr(K, name) == value and type(getattr(K, name)) is type(value), name
    for name in dir(K):
        if name.isupper() and name[:2] in ("P_", "S_", "M_") or name.startswith("METHOD_"):
            assert name in C.CONSTANTS, f"{name} of kernels.py is missing from gdcore.h"
    for n in range(0, 12):
        assert C.layout_total(n) == K.layout(n)[6]


@pytest.mark.parametrize("lam", [1.0, pytest.param(0.98, marks=pytest.mark.slow)])     # quick tier: lam 1,
@pytest.mark.parametrize("sigma", [0.0, pytest.param(3.0, marks=pytest.mark.slow), 5.0])  # gate off and on
@pytest.mark.parametrize("method", sorted(K.METHODS))
def test_c_equals_python_every_method_order(method, sigma, lam):
    for n in range(1, 7):
        p = params(method, n, sigma, lam)
        z, r = mixed_record(zlib.crc32(repr((method, sigma, lam, n)).encode()), n_each=110)
        ref_out, ref_s = check_against_python(p, z, r)
        out, s = c_batch(p, z, r)            # run: specialised for orders 1..4
        assert_same(ref_out, out, "run output")
        assert_same(ref_s, s, "run state")


@pytest.mark.slow
@pytest.mark.parametrize("method", sorted(K.METHODS))
def test_seeded_random_long(method):
    """A long, plain record (converged filter, gate active, lam < 1)."""
    rng = random.Random(7)
    z, r = hostile("ar", 3000, rng)
    for n, sigma, lam in ((1, 5.0, 1.0), (3, 3.0, 0.995), (6, 0.0, 0.99)):
        check_against_python(params(method, n, sigma, lam), z, r)


@pytest.mark.parametrize("method", sorted(K.METHODS))
def test_restarts_heal_and_counters(method):
    """Heals (1e155 squares to inf), re-openings and clamps happen and agree."""
    rng = random.Random(3)
    z = [rng.gauss(0.0, 1.0) for _ in range(900)]
    for i in (150, 151, 400, 700):
        z[i] = 1e155 * (-1) ** i
    for i in range(500, 560):                # a run of outliers: the gate re-opens
        z[i] += 300.0
    r = [i in (300, 800) for i in range(900)]
    ref_out, ref_s = check_against_python(params(method, 3, 0.0, 1.0), z, r)
    if method not in ("lowpass", "one_euro"):   # nothing squared: 1e155 stays finite there
        assert ref_s[K.S_NHEAL] >= 1
    check_against_python(params(method, 2, 5.0, 0.99, run=3), z, r)


@pytest.mark.parametrize("method", sorted(K.METHODS))
def test_restart_equals_a_fresh_start(method):
    """A restart forgets everything but the counters (S_NREJ, S_NREOPEN, S_NCLAMP,
    S_NHEAL): from the restart on, the outputs and the state are those of a fresh
    state given the rest of the record, bit for bit, in Python and in C (step and run).
    An independent reference, where the C == Python comparison is not: a restart that
    keeps some memory (the low-pass's delays, the motion bank) in both languages alike
    fails here."""
    counters = (K.S_NREJ, K.S_NREOPEN, K.S_NCLAMP, K.S_NHEAL)
    for n, sigma, lam, mmhz in ((2, 5.0, 1.0, 0.0), (3, 0.0, 0.99, 8.0)):
        if mmhz and method != "motion":
            continue
        p = K.make_params(n, method, sample_rate_hz=FS, lam=lam, outlier_sigma=sigma,
                          max_motion_hz=mmhz)
        z, _ = hostile("ar", 700, random.Random(17))
        z = [v + 40.0 * (300 <= i < 420) for i, v in enumerate(z)]     # a step the memory holds
        for cut in (420, 555):
            r = [i == cut for i in range(len(z))]
            for run in (py_run, c_step_run, c_batch):
                out, s = run(p, z, r)
                fresh_out, fresh_s = run(p, z[cut:], [False] * (len(z) - cut))
                assert_same(fresh_out, out[cut:], f"{run.__name__} output after a restart at {cut}")
                for i in counters:
                    s[i] = fresh_s[i] = 0.0
                assert_same(fresh_s, s, f"{run.__name__} state after a restart at {cut}")


def test_rare_paths():
    """Branches the records above do not reach with the default parameters."""
    rng = random.Random(9)
    white = [rng.gauss(0.0, 1.0) for _ in range(1500)]
    # b^(k+1) underflows below 1e-290 (set to 0) after ~145 samples with b = 0.01
    for method in ("shakf", "sh_classic"):
        p = K.make_params(2, method, sample_rate_hz=FS, b=0.01, gamma=50.0)
        _, s = check_against_python(p, white[:400], [False] * 400)
        assert s[K.S_BK] == 0.0
    # motion: a constant input (R at its floor), the Huber clip of the noise
    # estimates, filters restarted from the best (a step) and the growing memory
    p = params("motion", 1, 0.0, 1.0)
    z = [2.0] * 300 + white[:700] + [50.0 + 10.0 * v for v in white[700:]]
    _, s = check_against_python(p, z, [False] * len(z))
    o = K.layout(1)[6] - K.N_EXT
    assert s[o + K.M_R] > K.make_params(1, "motion")[K.P_R_FLOOR]
    # the centred sample itself overflows (z - z_ref = inf): every method heals
    for method in sorted(K.METHODS):
        z = [-1e308, 1e308, 1.0, 2.0] + white[:100] + [1.5e308, -1.5e308] + white[:50]
        _, s = check_against_python(params(method, 2, 5.0, 1.0), z, [False] * len(z))
        assert s[K.S_NHEAL] >= 1


@pytest.mark.parametrize("method", sorted(K.METHODS))
def test_split_runs_and_batch_equal_one_run(method):
    p = params(method, 4, 5.0, 0.99)
    z, r = mixed_record(11, n_each=90)
    whole_out, whole_s = c_step_run(p, z, r)
    batch_out, batch_s = c_batch(p, z, r)
    assert batch_out == whole_out and batch_s == whole_s     # run == repeated step
    # split anywhere, state carried over (through run and through step)
    rng = random.Random(5)
    cuts = sorted(rng.sample(range(1, len(z)), 6))
    s, out = None, []
    for a, b in zip([0] + cuts, cuts + [len(z)]):
        o, s = c_batch(p, z[a:b], r[a:b], s)
        out += o
    assert out == whole_out and s == whole_s
    s, out = None, []
    for a, b in zip([0] + cuts, cuts + [len(z)]):
        o, s = c_step_run(p, z[a:b], r[a:b], s)
        out += o
    assert out == whole_out and s == whole_s
    ref_out, ref_s = py_run(p, z, r)
    assert_same(ref_out, whole_out, "output")
    assert_same(ref_s, whole_s, "state")


@pytest.mark.parametrize("method", sorted(K.METHODS))
def test_bit_identical(method):
    """The C keeps the Python's operations in their order, so with IEEE doubles and no
    fused multiply-add (-ffp-contract=off) the numbers are the same bits; a failure here
    means an operation was reordered or the build flags changed."""
    for n, sigma, lam in ((1, 3.0, 1.0), (3, 5.0, 0.99), (6, 0.0, 0.98)):
        p = params(method, n, sigma, lam)
        z, r = mixed_record(100 + n, n_each=150)
        ref_out, ref_s = py_run(p, z, r)
        out, s = c_step_run(p, z, r)
        assert out == ref_out and s == ref_s


@pytest.mark.parametrize("method", ["motion", "shakf"])
def test_traced_run_equals_python_sample_by_sample(method):
    """C.run(..., trace_index, trace) (gd_run_trace, the offline form's forward and
    backward runs of batch.run_offline): every output, every traced state value
    (the motion bank's output variance M_PVAR, kept when P_MO_VAR is set) and the
    final state bit for bit equal to the plain-Python kernels stepped one sample
    at a time; with and without restarts."""
    p = K.make_params(3, method, sample_rate_hz=FS)
    p[K.P_MO_VAR] = 1.0
    ti = K.layout(3)[6] - K.N_EXT + K.M_PVAR if method == "motion" else K.S_R
    z, r = mixed_record(7, n_each=150)
    for rs in (r, [False] * len(z)):
        s = K.init_state(p)
        ref_out, ref_tr = [], []
        for zi, ri in zip(z, rs):
            ref_out.append(K.step(p, s, zi, ri))
            ref_tr.append(s[ti])
        sa = np.array(K.init_state(p))
        out, tr = np.empty(len(z)), np.empty(len(z))
        C.run(np.asarray(p), sa, np.asarray(z), np.asarray(rs, dtype=np.bool_), out, ti, tr)
        assert out.tolist() == ref_out and tr.tolist() == ref_tr and sa.tolist() == s
        assert len(set(ref_tr)) > 10                  # the traced value moves (not a constant)
    with pytest.raises(ValueError, match="trace_index"):
        C.run(np.asarray(p), sa, np.asarray(z), None, out, len(sa), tr)
    with pytest.raises(ValueError, match="trace has"):
        C.run(np.asarray(p), sa, np.asarray(z), None, out, ti, np.empty(3))


@pytest.mark.parametrize("method,n", [("shakf", 9), ("kf", 12), ("lowpass", 3)])
def test_run_any_method_loop_equals_step(method, n):
    """gd_run's loop for what has no loop of its own (AR orders above the specialised
    1..8, lowpass: gdcore.c run_steps_), with restarts and without: outputs and state
    bit for bit equal to the C step sample by sample, and to the plain-Python kernels
    (hostile records: spikes to 1e300, a 1e7 offset, restarts)."""
    p = params(method, n, 3.0, 0.99)
    z, r = mixed_record(zlib.crc32(repr((method, n)).encode()), n_each=40)
    ref_out, ref_s = check_against_python(p, z, r)
    step_out, step_s = c_step_run(p, z, r)
    assert c_batch(p, z, r) == (step_out, step_s)
    zc, _ = hostile("ar", 600, random.Random(n))
    pa, sa, out = np.asarray(p), np.array(K.init_state(p)), np.empty(len(zc))
    C.run(pa, sa, np.asarray(zc), None, out)
    assert (out.tolist(), sa.tolist()) == c_step_run(p, zc, [False] * len(zc))
    assert len(set(out.tolist())) > 100 and out.tolist() != zc        # it filtered


def test_run_without_restarts_and_numpy_state():
    p = params("shakf", 3, 5.0, 1.0)
    z, _ = hostile("ar", 500, random.Random(2))
    pa = np.asarray(p)
    sa = np.asarray(K.init_state(p))
    out = np.empty(len(z))
    C.run(pa, sa, np.asarray(z), None, out)
    ref_out, ref_s = py_run(p, z, [False] * len(z))
    assert out.tolist() == ref_out and sa.tolist() == ref_s


def test_restart_equals_python():
    p = params("sh_classic", 5, 3.0, 0.99)
    z, r = mixed_record(4, n_each=40)
    _, s = py_run(p, z, r)
    sc = array.array("d", s)
    K.restart(p, s)
    C.restart(array.array("d", p), sc)
    assert list(sc) == s


@pytest.mark.slow
@settings(derandomize=True, deadline=None, database=None, max_examples=400)
@given(method=st.sampled_from(sorted(K.METHODS)), n=st.integers(1, 6),
       sigma=st.sampled_from([0.0, 2.0, 3.0, 5.0]), lam=st.sampled_from([1.0, 0.999, 0.95]),
       run=st.integers(1, 30),
       segments=st.lists(st.tuples(st.sampled_from(KINDS), st.integers(1, 120),
                                   st.integers(0, 2 ** 16), st.booleans()),
                         min_size=1, max_size=4),
       scale=st.sampled_from([1e-9, 1e-3, 1.0, 1e3, 1e7]))
def test_hypothesis_records(method, n, sigma, lam, run, segments, scale):
    p = params(method, n, sigma, lam, run=run)
    z, r = [], []
    for kind, length, seed, restart in segments:
        zk, rk = hostile(kind, length, random.Random(seed))
        rk[0] = rk[0] or restart
        z += [v * scale if abs(v) < 1e100 else v for v in zk]
        r += rk
    check_against_python(p, z, r)


@settings(derandomize=True, deadline=None, database=None, max_examples=200)
@given(z=st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=1,
                  max_size=150),
       method=st.sampled_from(sorted(K.METHODS)), n=st.integers(1, 4),
       sigma=st.sampled_from([0.0, 5.0]))
def test_hypothesis_any_finite_floats(z, method, n, sigma):
    """Arbitrary finite doubles (up to 1.8e308, subnormals) sample by sample."""
    check_against_python(params(method, n, sigma, 1.0), z, [False] * len(z))


# -------------------------------------------------------- wrong buffers
def _bufs(method="shakf", n=3):
    p = params(method, n, 5.0, 1.0)
    return p, array.array("d", p), array.array("d", K.init_state(p))


def test_wrong_sizes_raise_value_error():
    p, pa, sa = _bufs()
    for bad_s in (sa[:-1], sa + array.array("d", [0.0]), array.array("d")):
        with pytest.raises(ValueError, match="s has the wrong length"):
            C.step(pa, bad_s, 1.0, False)
        with pytest.raises(ValueError):
            C.restart(pa, bad_s)
        with pytest.raises(ValueError):
            C.run(pa, bad_s, array.array("d", [1.0]), None, array.array("d", [0.0]))
    with pytest.raises(ValueError, match="p is too short"):
        C.step(pa[:-1], sa, 1.0, False)
    with pytest.raises(ValueError, match="p is too short"):
        C.step(array.array("d"), sa, 1.0, False)
    # the order decides the length of s: a state of another order is refused
    p5 = array.array("d", params("shakf", 5, 5.0, 1.0))
    with pytest.raises(ValueError, match="wrong length"):
        C.step(p5, sa, 1.0, False)
    for order in (0.0, -1.0, float("nan"), float("inf"), 1e12):
        bad = array.array("d", p)
        bad[K.P_ORDER] = order
        with pytest.raises(ValueError, match="P_ORDER"):
            C.step(bad, sa, 1.0, False)
    for nsec in (-1.0, 5.0, float("nan"), 1e9):
        bad = array.array("d", p)
        bad[K.P_LP_NSEC] = nsec
        with pytest.raises(ValueError, match="P_LP_NSEC"):
            C.step(bad, sa, 1.0, False)
    # motion: the bank's and the history's sizes (the batch loop holds them in fixed arrays)
    pm, pma, sma = _bufs("motion")
    for field, values in ((K.P_MO_NF, (0.0, 17.0, 2.5, float("nan"))),
                          (K.P_MO_NCA, (-1.0, 4.0, 1.5, float("nan"))),     # 13 CV + 4 CA > MO_MAX_NF
                          (K.P_MO_NLAG, (0.0, 9.0, 1e9, 6.5, float("nan")))):
        for v in values:
            bad = array.array("d", pm)
            bad[field] = v
            name = {K.P_MO_NF: "P_MO_NF", K.P_MO_NCA: "P_MO_NCA"}.get(field, "P_MO_NLAG")
            with pytest.raises(ValueError, match=name):
                C.step(bad, sma, 1.0, False)
            with pytest.raises(ValueError, match=name):
                C.run(bad, sma, array.array("d", [1.0] * 50), None, array.array("d", [0.0] * 50))
    assert list(sma) == K.init_state(pm)
    z = array.array("d", [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="out has"):
        C.run(pa, sa, z, None, array.array("d", [0.0] * 2))
    with pytest.raises(ValueError, match="restarts has"):
        C.run(pa, sa, z, bytes(4), array.array("d", [0.0] * 3))
    assert list(sa) == K.init_state(p)       # nothing was touched


def test_wrong_types_raise_type_error():
    p, pa, sa = _bufs()
    with pytest.raises(TypeError):
        C.step(p, sa, 1.0, False)                          # a list is not a buffer
    with pytest.raises(TypeError):
        C.step(pa, list(sa), 1.0, False)
    with pytest.raises(TypeError):
        C.step(np.asarray(p, dtype=np.float32), sa, 1.0, False)
    with pytest.raises(TypeError):
        C.step(pa, memoryview(bytes(sa)).cast("d"), 1.0, False)   # read-only state
    s2 = np.zeros(2 * len(sa))
    with pytest.raises((TypeError, ValueError)):           # numpy: ValueError
        C.step(pa, s2[::2], 1.0, False)                    # not contiguous
    with pytest.raises(TypeError):
        C.step(pa, sa, "1.0", False)
    with pytest.raises(TypeError):
        C.step(pa, sa, 1.0)
    with pytest.raises(TypeError):
        C.run(pa, sa, array.array("d", [1.0]), array.array("i", [0]), array.array("d", [0.0]))
    assert list(sa) == K.init_state(p)


def test_step_accepts_numpy_and_ints():
    p, pa, sa = _bufs("motion", 2)
    sn = np.asarray(K.init_state(p))
    for i, zi in enumerate([1, 2.5, np.float64(3.0), 4]):
        a = C.step(pa, sa, zi, i == 2)
        b = C.step(np.asarray(p), sn, zi, np.bool_(i == 2))
        assert a == b
    assert list(sa) == sn.tolist()


def test_motion_params_of_the_native_fmu_equal_python():
    """gd_motion_params (C, used by the native FMU) writes the same floats as
    kernels.motion_params (bit for bit) at several sample rates."""
    import ctypes
    lib = ctypes.CDLL(C.__file__)
    for fs in (50.0, 200.0, 400.0, 1000.0, 8000.0):
        buf = (ctypes.c_double * K.N_PARAMS)()
        lib.gd_motion_params(buf, ctypes.c_double(fs))
        ref = K.make_params(3, "motion", sample_rate_hz=fs)
        assert list(buf)[K.P_MO_NF:] == ref[K.P_MO_NF:], fs


@pytest.mark.parametrize("n,sigma,lam", [(1, 3.0, 1.0), (3, 5.0, 0.99)])
def test_rigid_option_c_equals_python_bit_for_bit(n, sigma, lam):
    """max_motion_hz (a Butterworth ahead of the motion bank, its delays in
    the state): the C step, the C batch and the traced run (the offline form's passes) equal
    the plain-Python kernels bit for bit, outputs and states, on a record with restarts,
    steps and spikes, and on hostile records (spikes up to 1e300, a 1e7 offset, constant,
    alternating)."""
    p = K.make_params(n, "motion", sample_rate_hz=FS, lam=lam, outlier_sigma=sigma, max_motion_hz=8.0)
    assert p[K.P_LP_NSEC] == K.MAX_MOTION_ORDER / 2 and p[K.P_LP_CUTOFF] == 16.0
    z, r = mixed_record(300 + n, n_each=150)
    ref_out, ref_s = py_run(p, z, r)
    for run in (c_step_run, c_batch):
        out, s = run(p, z, r)
        assert out == ref_out and s == ref_s, run.__name__
    lpd = K.layout(n)[6] - K.N_EXT + K.M_LPD
    assert all(v != 0.0 for v in ref_s[lpd:lpd + K.MAX_MOTION_ORDER])   # the low-pass's delays are in the state
    p[K.P_MO_VAR] = 1.0
    ti = K.layout(n)[6] - K.N_EXT + K.M_PVAR
    s = K.init_state(p)
    ref_tr = []
    ref_out = []
    for zi, ri in zip(z, r):
        ref_out.append(K.step(p, s, zi, ri))
        ref_tr.append(s[ti])
    sa, out, tr = np.array(K.init_state(p)), np.empty(len(z)), np.empty(len(z))
    C.run(np.asarray(p), sa, np.asarray(z), np.asarray(r, dtype=np.bool_), out, ti, tr)
    assert out.tolist() == ref_out and tr.tolist() == ref_tr and sa.tolist() == s
    for kind in ("spikes", "offset", "constant", "oscillating", "quantised", "restarts"):
        zh, rh = hostile(kind, 400, random.Random(n))
        check_against_python(p, zh, rh)
    # the offline form's bank: no low-pass, a given noise level (P_MO_RFIX)
    p[K.P_LP_NSEC] = 0.0
    p[K.P_MO_RFIX] = 0.0123
    ref_out, ref_s = py_run(p, z, r)
    assert c_step_run(p, z, r) == (ref_out, ref_s) and c_batch(p, z, r) == (ref_out, ref_s)
    assert ref_s[K.layout(n)[6] - K.N_EXT + K.M_R] == 0.0123


@pytest.mark.parametrize("card,fs", [("paper_fog", 200.0), ("icm20602", 400.0), ("kvh1750", 1000.0)])
def test_motion_batch_bank_equals_python_on_sensor_records(card, fs):
    """gd_run's motion loop keeps the bank outside the state (one array per value, the
    history twice over, for speed): outputs and final state bit for bit equal to the
    plain-Python kernels and to the per-sample C step, on simulated sensor records (past the
    warm-up and the growing memory, through a step, a fast sinusoid near fs/4, a lone spike,
    restarts, a NaN sample that heals), whole and split at arbitrary points."""
    import gyrodenoise as gd
    n = int(6 * fs)                                       # 6 s; warm-up 1 s after each restart
    z = gd.simulate(card, n, seed=5).rate_deg_s.copy()
    t = np.arange(n) / fs
    z += 20.0 * (t > 2.5) + 3.0 * np.sin(2 * np.pi * 0.24 * fs * t) * (t > 4.5)
    i_spike, i_nan = int(3.3 * fs), int(3.6 * fs)
    z[i_spike] += 400.0
    z[i_nan] = float("nan")
    r = [False] * n
    r[int(1.2 * fs)] = True
    p = K.make_params(3, "motion", sample_rate_hz=fs)
    ref_out, ref_s = py_run(p, z.tolist(), r)
    assert ref_out[i_nan] != ref_out[i_nan]             # a NaN in is a NaN out (then it heals)

    def same(a, b):                                       # bit for bit, a NaN equal to a NaN
        return np.array_equal(np.asarray(a[0]), np.asarray(b[0]), equal_nan=True) and a[1] == b[1]
    assert same(c_batch(p, z, r), (ref_out, ref_s))
    assert same(c_step_run(p, z.tolist(), r), (ref_out, ref_s))
    assert ref_s[K.S_NHEAL] >= 1
    tail = slice(n - int(fs), n)                          # the bank runs again in the last second
    assert np.mean(np.asarray(ref_out)[tail] != z[tail]) > 0.9
    s, got = None, []
    cuts = [0, 1, 99, int(1.2 * fs) + 1, i_nan, i_nan + 1, n]
    for a, b in zip(cuts[:-1], cuts[1:]):
        o_, s = c_batch(p, z[a:b], r[a:b], s)
        got += o_
    assert same((got, s), (ref_out, ref_s))


def test_spectral_floor_line_test_and_huber_clip_equal_python():
    """motion's spectral floor at 200 Hz, 30 s: a 3-sigma tone at 0.45 fs (the line test trips:
    M_LON on) and a burst of 30x the noise (the floor's Huber clip acts: the floor differs with
    the clip off). Outputs, the recorded M_LON and M_SR after every sample and the final state
    equal the plain-Python kernels bit for bit (C.record; the motion tests run these branches
    through the C core only, so a change to the Python alone showed nowhere else)."""
    fs, n = 200.0, 6000
    p = K.make_params(2, "motion", sample_rate_hz=fs)
    o = K.ext_offset(p)
    idx = [o + K.M_LON, o + K.M_SR]
    rng = random.Random(13)
    z = [rng.gauss(0.0, 1.0) for _ in range(n)]
    for i in range(1500, 2500):
        z[i] += 3.0 * np.sin(2.0 * np.pi * 0.45 * i)
    for i in range(3500, 3700):
        z[i] *= 30.0

    def python(p):
        s, out, rec = K.init_state(p), [], []
        for zi in z:
            out.append(K.step(p, s, zi, False))
            rec.append([s[j] for j in idx])
        return out, rec, s
    ref_out, ref_rec, ref_s = python(p)
    sa, out, rec = np.array(K.init_state(p)), np.empty(n), np.empty((len(idx), n))
    C.record(np.asarray(p), sa, np.asarray(z), out, np.asarray(idx, dtype=np.float64), rec)
    assert_same(ref_out, out.tolist(), "output")
    assert_same([r[0] for r in ref_rec], rec[0].tolist(), "M_LON")
    assert_same([r[1] for r in ref_rec], rec[1].tolist(), "M_SR")
    assert_same(ref_s, sa.tolist(), "state")
    assert 500 < sum(r[0] for r in ref_rec) < 1100                  # the line test tripped
    unclipped = list(p)
    unclipped[K.P_MO_HUBER] = 1e300
    assert [r[1] for r in python(unclipped)[1]] != [r[1] for r in ref_rec]   # the clip acted


@pytest.mark.parametrize("kind", KINDS)
def test_motion_batch_equals_step_on_hostile_records(kind):
    """The motion batch loop (bank outside the state) on every hostile kind (spikes up to
    1e300, a 1e7 offset, constant, alternating, restarts...): equal to the per-sample C step
    bit for bit, outputs and state, with and without the output variance (P_MO_VAR)."""
    z, r = hostile(kind, 700, random.Random(23))
    for var in (0.0, 1.0):
        p = params("motion", 2, 0.0, 1.0)
        p[K.P_MO_VAR] = var
        assert c_batch(p, z, r) == c_step_run(p, z, r)


def test_record_equals_step_and_reading_the_state():
    """C.record (gd_run_record, the offline smoother's bank runs): every output and every
    recorded state value bit for bit equal to the plain-Python kernels stepped one sample at
    a time and read after each sample (rows: one per recorded value); bad indices refused."""
    p = K.make_params(3, "motion", sample_rate_hz=FS)
    o = K.ext_offset(p)
    idx = [o + K.M_BANK, o + K.M_BANK + 6, o + K.M_NW, o + K.M_R, K.S_CONV, K.S_ZREF]
    z, _ = mixed_record(11, n_each=150)
    s = K.init_state(p)
    ref_out, ref_rec = [], []
    for zi in z:
        ref_out.append(K.step(p, s, zi, False))
        ref_rec.append([s[j] for j in idx])
    sa = np.array(K.init_state(p))
    out, rec = np.empty(len(z)), np.empty((len(idx), len(z)))
    C.record(np.asarray(p), sa, np.asarray(z), out, np.asarray(idx, dtype=np.float64), rec)
    assert out.tolist() == ref_out and rec.T.tolist() == ref_rec and sa.tolist() == s
    with pytest.raises(ValueError, match="idx"):
        C.record(np.asarray(p), sa, np.asarray(z), out, np.asarray([len(sa)], dtype=np.float64),
                 np.empty(len(z)))
    with pytest.raises(ValueError, match="rec"):
        C.record(np.asarray(p), sa, np.asarray(z), out, np.asarray(idx, dtype=np.float64), np.empty(3))
