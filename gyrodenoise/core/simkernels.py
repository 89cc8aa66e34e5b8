"""The simulated gyro in plain Python: the executable specification of ``gdsim.c``.

The same functions as ``gyrodenoise/core/gdsim.c`` (model, generator, buffers: see
``gdsim.h``), operation for operation, over the same flat float buffers, so that
the C and this give the same numbers (tested). gyrodenoise.simulate
runs the C (through the extension ``gyrodenoise.core._gdcore``) and falls back to
this where the extension is not built.

The card vector (:func:`card_vector`) carries a model card's numbers in the
card's units into both: ``[sample_rate_hz, Q, N, B, K, R, bias, bias_rep, tr_amp,
tr_tau, n_gm, n_sin, gm_sigma x16, gm_tau x16, sin_amp x16, sin_f x16,
sin_phase_deg x16, n_agm, agm_sigma x16, agm_tau x16]`` (the angle Gauss-Markov
block last; the extension also takes the older 92-number vector without it).
"""

from __future__ import annotations

import math

MAX_REPEAT = 16
CARD_LEN = 12 + 5 * MAX_REPEAT + 1 + 2 * MAX_REPEAT
AGM_AT = 12 + 5 * MAX_REPEAT          # card vector: n_agm, agm_sigma x16 (deg), agm_tau x16 (s)
STREAM_KEY = (0, 0x5851F42D4C957F2D, 0xD1B54A32D192ED03)   # noise, turn-on bias, angle Gauss-Markov
FLICKER_F_LO_HZ = 1.0e-5
FLICKER_POLES_PER_DECADE = 3

# parameters p[] and state s[] (gdsim.h)
PS_T, PS_NBANK, PS_NSIN, PS_Q, PS_ARW, PS_BIAS0, PS_BIASREP, PS_TRAMP, PS_TRTAU, PS_RAMP = range(10)
PS_SEED_HI, PS_SEED_LO, PS_BANK = 10, 11, 12
SS_RNG, SS_RNG_RESTART, SS_WPREV, SS_K, SS_KR, SS_BIAS, SS_X = 0, 8, 16, 17, 18, 19, 20

M64 = (1 << 64) - 1


def card_vector(card):
    """The card vector of a :class:`gyrodenoise.simulator.ModelCard` (card units)."""
    t = card.terms

    def val(term, field, default=0.0):
        return float(t[term][field]) if term in t else default

    gms, sins = card.term_list("gauss_markov"), card.term_list("sinusoid")
    agms = card.term_list("angle_gauss_markov")
    if len(gms) > MAX_REPEAT or len(sins) > MAX_REPEAT or len(agms) > MAX_REPEAT:
        raise ValueError(f"at most {MAX_REPEAT} gauss_markov, {MAX_REPEAT} sinusoid and {MAX_REPEAT} "
                         f"angle_gauss_markov terms")
    v = [float(card.sample_rate_hz), val("quantization", "Q"), val("angle_random_walk", "N"),
         val("bias_instability", "B"), val("rate_random_walk", "K"), val("rate_ramp", "R"),
         val("constant_bias", "value"), float(t.get("constant_bias", {}).get("repeatability", 0.0)),
         val("turn_on_transient", "amplitude"), val("turn_on_transient", "tau", 1.0),
         float(len(gms)), float(len(sins))]
    cols = ([g["sigma"] for g in gms], [g["tau"] for g in gms], [s["amplitude"] for s in sins],
            [s["frequency"] for s in sins], [s.get("phase_deg", 0.0) for s in sins])
    for col in cols:
        v += [float(x) for x in col] + [0.0] * (MAX_REPEAT - len(col))
    v.append(float(len(agms)))
    for col in ([g["sigma"] for g in agms], [g["tau"] for g in agms]):
        v += [float(x) for x in col] + [0.0] * (MAX_REPEAT - len(col))
    return v


# ------------------------------------------------------------------ generator
def _rotl(x, k):
    return ((x << k) | (x >> (64 - k))) & M64


def _splitmix64(x):
    """(new x, output)."""
    x = (x + 0x9E3779B97F4A7C15) & M64
    z = x
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & M64
    return x, z ^ (z >> 31)


def _load(s, at):
    return [(int(s[at + 2 * i]) << 32) | int(s[at + 2 * i + 1]) for i in range(4)]


def _store(w, s, at):
    for i in range(4):
        s[at + 2 * i] = float(w[i] >> 32)
        s[at + 2 * i + 1] = float(w[i] & 0xFFFFFFFF)


def _next_u64(w):
    result = (_rotl((w[1] * 5) & M64, 7) * 9) & M64
    t = (w[1] << 17) & M64
    w[2] ^= w[0]
    w[3] ^= w[1]
    w[1] ^= w[2]
    w[0] ^= w[3]
    w[2] ^= t
    w[3] = _rotl(w[3], 45)
    return result


def _uniform(w):
    return float(_next_u64(w) >> 11) * (1.0 / 9007199254740992.0)


def _normal(w):
    """Standard normal, Marsaglia's polar method (the second deviate discarded)."""
    while True:
        u = 2.0 * _uniform(w) - 1.0
        v = 2.0 * _uniform(w) - 1.0
        q = u * u + v * v
        if not (q >= 1.0 or q == 0.0):
            return u * math.sqrt(-2.0 * math.log(q) / q)


def _seed_stream(seed, stream, s, at):
    x = int(seed) ^ STREAM_KEY[stream]
    w = []
    for _ in range(4):
        x, out = _splitmix64(x)
        w.append(out)
    _store(w, s, at)


# ----------------------------------------------------------------- parameters
def _n_flicker(v):
    if not v[3] > 0:
        return 0
    n_dec = math.log10(0.5 * v[0] / FLICKER_F_LO_HZ)
    return max(1, int(math.ceil(n_dec * FLICKER_POLES_PER_DECADE)))


def n_bank(v):
    n_gm = int(v[10])
    return _n_flicker(v) + sum(1 for i in range(n_gm) if v[12 + i] > 0) + (1 if v[4] > 0 else 0)


def _n_agm(v):
    if len(v) <= AGM_AT:        # a card vector from before the angle Gauss-Markov term
        return 0
    return sum(1 for i in range(int(v[AGM_AT])) if v[AGM_AT + 1 + i] > 0)


def n_params(v):
    return PS_BANK + 3 * n_bank(v) + 3 * int(v[11]) + 1 + 3 * _n_agm(v)


def _agm_at(p):
    """Index in p of the angle Gauss-Markov count (its terms follow)."""
    return PS_BANK + 3 * int(p[PS_NBANK]) + 3 * int(p[PS_NSIN])


def n_state(p):
    na = int(p[_agm_at(p)])
    return SS_X + int(p[PS_NBANK]) + (8 + na if na > 0 else 0)


def params(v, seed):
    """The parameter buffer (list) of card vector ``v`` and ``seed`` (0 <= seed < 2**53)."""
    deg_h, deg_rth, deg_h15, deg_h2 = 1.0 / 3600.0, 1.0 / 60.0, 1.0 / 3600.0 ** 1.5, 1.0 / 3600.0 ** 2.0
    fs, Q, N, B, K, R, bias, bias_rep, tr_amp, tr_tau = v[:10]
    n_gm, n_sin = int(v[10]), int(v[11])
    T = 1.0 / fs
    bank = []
    nf = _n_flicker(v)
    if nf > 0:
        Bs = B * deg_h
        f_hi = 0.5 * fs
        delta = math.log(f_hi / FLICKER_F_LO_HZ) / nf
        var = Bs * Bs * delta / math.pi
        for j in range(nf):
            fj = FLICKER_F_LO_HZ * math.exp((j + 0.5) * delta)
            aj = math.exp(-2.0 * math.pi * fj * T)
            bank += [aj, math.sqrt(var * (1.0 - aj * aj)), math.sqrt(var)]
    for i in range(n_gm):
        sigma, tau = v[12 + i], v[12 + MAX_REPEAT + i]
        if sigma > 0:
            aj = math.exp(-T / tau)
            s = sigma * deg_h
            bank += [aj, s * math.sqrt(1.0 - aj * aj), s]
    if K > 0:
        bank += [1.0, K * deg_h15 * math.sqrt(T), 0.0]
    seed = int(seed)
    p = [T, float(len(bank) // 3), float(n_sin), Q, N * deg_rth / math.sqrt(T), bias * deg_h,
         bias_rep * deg_h, tr_amp * deg_h, tr_tau, R * deg_h2, float(seed >> 32), float(seed & 0xFFFFFFFF)]
    p += bank
    base = 12 + 2 * MAX_REPEAT
    for i in range(n_sin):
        p += [v[base + i] * deg_h, v[base + MAX_REPEAT + i],
              v[base + 2 * MAX_REPEAT + i] * (math.pi / 180.0)]
    p.append(float(_n_agm(v)))
    for i in range(int(v[AGM_AT]) if len(v) > AGM_AT else 0):    # angle Gauss-Markov, angles in deg
        sigma, tau = v[AGM_AT + 1 + i], v[AGM_AT + 1 + MAX_REPEAT + i]
        if sigma > 0:
            aj = math.exp(-T / tau)
            p += [aj, sigma * math.sqrt(1.0 - aj * aj), sigma]
    return p


# ---------------------------------------------------------------------- model
def _draw_bias(p, s):
    if p[PS_BIASREP] == 0.0:
        return p[PS_BIAS0]
    w = _load(s, SS_RNG_RESTART)
    value = p[PS_BIAS0] + p[PS_BIASREP] * _normal(w)
    _store(w, s, SS_RNG_RESTART)
    return value


def reset(p, s=None):
    """The state at the start (a new list, or ``s`` filled in place)."""
    if s is None:
        s = [0.0] * n_state(p)
    seed = int(p[PS_SEED_HI]) * 4294967296 + int(p[PS_SEED_LO])
    _seed_stream(seed, 0, s, SS_RNG)
    _seed_stream(seed, 1, s, SS_RNG_RESTART)
    w = _load(s, SS_RNG)
    for j in range(int(p[PS_NBANK])):
        s[SS_X + j] = p[PS_BANK + 3 * j + 2] * _normal(w)
    s[SS_WPREV] = p[PS_Q] * _normal(w)
    _store(w, s, SS_RNG)
    s[SS_K] = 0.0
    s[SS_KR] = 0.0
    s[SS_BIAS] = _draw_bias(p, s)
    ag, sa = _agm_at(p), SS_X + int(p[PS_NBANK])
    na = int(p[ag])
    if na > 0:      # angle Gauss-Markov: its own generator, stationary start
        _seed_stream(seed, 2, s, sa)
        w = _load(s, sa)
        for j in range(na):
            s[sa + 8 + j] = p[ag + 1 + 3 * j + 2] * _normal(w)
        _store(w, s, sa)
    return s


def step(p, s, true_rate_deg_s=0.0, restart=False):
    """One measured sample (deg/s); ``s`` updated in place."""
    T = p[PS_T]
    nb, ns = int(p[PS_NBANK]), int(p[PS_NSIN])
    if restart and s[SS_K] > 0:
        s[SS_KR] = 0.0
        s[SS_BIAS] = _draw_bias(p, s)
    w = _load(s, SS_RNG)
    w0 = _normal(w)
    w1 = _normal(w)
    noise = p[PS_ARW] * w1
    if p[PS_Q] > 0:
        ang = p[PS_Q] * w0
        noise = noise + (ang - s[SS_WPREV]) / T
        s[SS_WPREV] = ang
    if nb > 0:
        total = 0.0
        for j in range(nb):
            b = PS_BANK + 3 * j
            s[SS_X + j] = p[b] * s[SS_X + j] + p[b + 1] * _normal(w)
            total = total + s[SS_X + j]
        noise = noise + total
    _store(w, s, SS_RNG)
    ag, sa = PS_BANK + 3 * nb + 3 * ns, SS_X + nb
    na = int(p[ag])
    if na > 0:      # angle Gauss-Markov, differenced / T
        total = 0.0
        w = _load(s, sa)
        for j in range(na):
            b = ag + 1 + 3 * j
            th = p[b] * s[sa + 8 + j] + p[b + 1] * _normal(w)
            total = total + (th - s[sa + 8 + j]) / T
            s[sa + 8 + j] = th
        _store(w, s, sa)
        noise = noise + total
    t = s[SS_K] * T
    tr = s[SS_KR] * T
    det = s[SS_BIAS] + p[PS_RAMP] * t
    if p[PS_TRAMP] != 0.0:
        det = det + p[PS_TRAMP] * math.exp(-tr / p[PS_TRTAU])
    for j in range(ns):
        b = PS_BANK + 3 * nb + 3 * j
        det = det + p[b] * math.sin(2.0 * math.pi * p[b + 1] * t + p[b + 2])
    s[SS_K] = s[SS_K] + 1.0
    s[SS_KR] = s[SS_KR] + 1.0
    return float(true_rate_deg_s) + noise + det


def run(p, s, n, truth=None, restarts=None):
    """``n`` samples (list); ``s`` updated in place."""
    return [step(p, s, 0.0 if truth is None else truth[i], False if restarts is None else bool(restarts[i]))
            for i in range(n)]
