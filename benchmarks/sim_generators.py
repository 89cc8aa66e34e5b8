"""The C sensor model (gdsim.c, xoshiro256** + polar normals) against the numpy
simulator it replaces (PCG64 + numpy normals, kept at commit OLD_REV), over many seeds:
is the C generator faithful to the card, and were the model-gap tests that failed
after the switch fragile (issue 22)?

    .venv/bin/python benchmarks/sim_generators.py [--seeds 40] [--gap-seeds 16] [--old-rev REV]

Prints, per generator:
1. the deterministic terms with every noise off: max |old - new| (should be ~1e-16);
2. normal deviates (ARW-only record / its std): mean, var, skewness, excess kurtosis,
   lag-1..3 autocorrelation, pooled over seeds, with the standard errors of a white
   N(0, 1) sample;
3. per noise term: mean over seeds of AVAR(tau) / analytic AVAR at three taus, and
   the scatter of AVAR(tau) over seeds (the workflow's threshold is made of it);
4. the hidden-sinusoid record of tests/test_gap.py (ARW N = 0.1 + 3 deg/h at 1.3 Hz):
   amplitude and phase of the 1.3 Hz line by least squares, mean and std over seeds;
5. the gap workflow on that record for measurement seeds 1001.. (``--gap-seeds``):
   gap_before / threshold and whether the sinusoid is found, the workflow's own
   simulations run with the same generator as the record;
6. the same on ``--set-records`` records (seeds 1001..) for six sets of five
   simulation seeds (1-5, 11-15, ... 51-55: the workflow's own seeds are 1-5): how
   much the outcome depends on which five simulations form the reference;
7. with ``--amplitudes``: how often the C's workflow finds other sinusoid amplitudes.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import gyrodenoise.simulator as SIM  # noqa: E402
from gyrodenoise.analysis.allan import adev  # noqa: E402
from gyrodenoise.core import simkernels as SK  # noqa: E402
from gyrodenoise.core import _gdcore as C  # noqa: E402

OLD_REV = "64ed6f5"   # main before gd.simulate called gdsim.c


def load_old(rev):
    """The numpy simulator module of commit ``rev``."""
    text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:gyrodenoise/simulator.py"],
                          check=True, capture_output=True, text=True).stdout
    text = text.replace("from .errors import InputError", "from gyrodenoise.errors import InputError")
    tmp = Path(tempfile.mkdtemp()) / "oldsim.py"
    tmp.write_text(text)
    spec = importlib.util.spec_from_file_location("oldsim", tmp)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["oldsim"] = mod
    spec.loader.exec_module(mod)
    mod.ModelCard = SIM.ModelCard   # take this tree's parsed cards as they are
    return mod


def c_simulate_fn():
    """simulate(card, n, seed, true_rate_deg_s=None, restarts=None) -> Record, through gdsim.c."""
    def simulate(card, n, seed=0, true_rate_deg_s=None, restarts=None):
        card = SIM.load_card(card)
        v = np.array(SK.card_vector(card))
        p = np.zeros(C.sim_n_params(v))
        C.sim_params(v, float(seed), p)
        s = np.zeros(C.sim_n_state(p))
        C.sim_reset(p, s)
        out = np.zeros(int(n))
        rs = None if restarts is None else np.ascontiguousarray(restarts, dtype=bool)
        C.sim_run(p, s, None, rs, out)
        if true_rate_deg_s is not None:
            out = out + true_rate_deg_s
        return SIM.Record(rate_deg_s=out, sample_rate_hz=card.sample_rate_hz, restarts=rs)
    return simulate


def card(terms, fs=100.0):
    return SIM.parse_card(f"[sensor]\nsample_rate_hz = {fs}\n[terms]\n{terms}\n")


DET = card("constant_bias = { value = 10.0 }\nrate_ramp = { R = 50.0 }\n"
           "turn_on_transient = { amplitude = 5.0, tau = 3.0 }\n"
           "[[terms.sinusoid]]\namplitude = 3.0\nfrequency = 1.3\nphase_deg = 20.0\n")
TERMS = {   # name: (card, analytic AVAR(tau) in deg^2/s^2, taus)
    "ARW N=0.1": (card("angle_random_walk = { N = 0.1 }"), lambda t: (0.1 / 60) ** 2 / t, (0.1, 10.0, 300.0)),
    "Q=3e-4": (card("quantization = { Q = 3.0e-4 }"), lambda t: 3 * 3.0e-4 ** 2 / t ** 2, (0.01, 0.1, 1.0)),
    "RRW K=20": (card("rate_random_walk = { K = 20.0 }"), lambda t: (20.0 / 3600 ** 1.5) ** 2 * t / 3,
                 (1.0, 10.0, 100.0)),
    "GM 6 deg/h 2 s": (card("[[terms.gauss_markov]]\nsigma = 6.0\ntau = 2.0"), None, (0.5, 2.0, 20.0)),
}


def gm_avar(tau, sigma, tc):
    """AVAR of a first-order Gauss-Markov process (continuous approximation)."""
    q = tau / tc
    return sigma ** 2 / q ** 2 * (2 * q - 3 + 4 * math.exp(-q) - math.exp(-2 * q))


def stats_normals(sim, n_seeds, n=100_000):
    z = np.concatenate([sim(TERMS["ARW N=0.1"][0], n, seed=s).rate_deg_s / (0.1 / 60 / math.sqrt(0.01))
                        for s in range(n_seeds)])
    m, v = z.mean(), z.var()
    zc = (z - m) / math.sqrt(v)
    ac = [float(np.mean(zc[:-k] * zc[k:])) for k in (1, 2, 3)]
    return {"mean": m, "var": v, "skew": float(np.mean(zc ** 3)), "exkurt": float(np.mean(zc ** 4) - 3),
            "ac1": ac[0], "ac2": ac[1], "ac3": ac[2], "N": z.size}


def avar_ratios(sim, name, n_seeds, n=200_000):
    c, ana, taus = TERMS[name]
    if ana is None:
        ana = lambda t: gm_avar(t, 6.0 / 3600, 2.0)  # noqa: E731
    m = np.array([int(round(t * 100)) for t in taus])
    r = np.array([adev(sim(c, n, seed=s).rate_deg_s, 100.0, m=m)[1] ** 2 for s in range(n_seeds)])
    a = np.array([ana(t) for t in taus])
    return r.mean(axis=0) / a, r.std(axis=0) / math.sqrt(n_seeds) / a, r.std(axis=0, ddof=1) / r.mean(axis=0)


def sine_fit(sim, n_seeds, n=180_000):
    c = card("angle_random_walk = { N = 0.1 }\n[[terms.sinusoid]]\namplitude = 3.0\nfrequency = 1.3")
    t = np.arange(n) / 100.0
    A = np.column_stack([np.sin(2 * np.pi * 1.3 * t), np.cos(2 * np.pi * 1.3 * t), np.ones(n)])
    amp, ph = [], []
    for s in range(n_seeds):
        coef = np.linalg.lstsq(A, sim(c, n, seed=1001 + s).rate_deg_s, rcond=None)[0]
        amp.append(math.hypot(coef[0], coef[1]) * 3600)
        ph.append(math.degrees(math.atan2(coef[1], coef[0])))
    return np.mean(amp), np.std(amp), np.mean(ph), np.std(ph)


def gap_runs(sim, gap_seeds, effect, sim_seeds=5, params=None):
    sys.path.insert(0, str(ROOT / "tests"))
    import test_gap as TG
    import gyrodenoise as gd
    old_sim = SIM.simulate
    SIM.simulate = sim
    try:
        rows = []
        for k in range(gap_seeds):
            name, base, hidden, _ = [h for h in TG.HIDDEN if h[0] == effect][0]
            y = TG._measured(base, [(name, params or hidden)], seed=1001 + k)
            res = gd.gap(y, TG.FS, SIM.parse_card(base), seeds=sim_seeds, engine="native", quiet=True)
            rows.append((1001 + k, res.gap_before, res.threshold,
                         [e["name"] for e in res.effects_added] == [effect]))
        return rows
    finally:
        SIM.simulate = old_sim


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--gap-seeds", type=int, default=16)
    ap.add_argument("--old-rev", default=OLD_REV)
    ap.add_argument("--set-records", type=int, default=6)
    ap.add_argument("--amplitudes", default="",
                    help="7. hidden sinusoid amplitudes (deg/h, comma-separated) to try at 1.3 Hz, C only, "
                         "on --gap-seeds records with simulation seeds 1-5")
    ap.add_argument("--gap-effects", default="sinusoid,rate_random_walk",
                    help="hidden effects of tests/test_gap.py to run the workflow on")
    a = ap.parse_args(argv)
    old = load_old(a.old_rev)
    gens = {"numpy (old)": old.simulate, "gdsim.c": c_simulate_fn()}
    det = {k: f(DET, 20_000, seed=3).rate_deg_s for k, f in gens.items()}
    print(f"1. deterministic terms, 20000 samples: max |old - C| = "
          f"{np.max(np.abs(det['numpy (old)'] - det['gdsim.c'])):.3g} deg/s "
          f"(max |y| {np.max(np.abs(det['gdsim.c'])):.3g})")
    for k, f in gens.items():
        st = stats_normals(f, a.seeds)
        se = 1 / math.sqrt(st["N"])
        print(f"2. {k:12s} normals N={st['N']}: mean {st['mean']:+.5f} var {st['var']:.5f} "
              f"skew {st['skew']:+.5f} exkurt {st['exkurt']:+.5f} ac1..3 {st['ac1']:+.5f} {st['ac2']:+.5f} "
              f"{st['ac3']:+.5f} (1 se: mean/ac {se:.5f}, var {se * math.sqrt(2):.5f}, skew "
              f"{se * math.sqrt(6):.5f}, kurt {se * math.sqrt(24):.5f})")
    for name in TERMS:
        for k, f in gens.items():
            r, e, sd = avar_ratios(f, name, a.seeds)
            print(f"3. {name:15s} {k:12s} AVAR/analytic at tau {TERMS[name][2]}: "
                  + " ".join(f"{x:.3f}+-{y:.3f}" for x, y in zip(r, e))
                  + "; scatter over seeds (rel sd): " + " ".join(f"{x:.3f}" for x in sd))
    for k, f in gens.items():
        am, asd, pm, psd = sine_fit(f, a.seeds)
        print(f"4. {k:12s} 1.3 Hz line (card 3 deg/h, phase 0): amplitude {am:.3f} +- {asd:.3f} deg/h, "
              f"phase {pm:+.2f} +- {psd:.2f} deg over {a.seeds} seeds")
    for effect in ([e for e in a.gap_effects.split(",") if e] if a.gap_seeds else []):
        for k, f in gens.items():
            rows = gap_runs(f, a.gap_seeds, effect)
            g = np.array([r[1] for r in rows])
            th = np.array([r[2] for r in rows])
            print(f"5. {k:12s} hidden {effect}, seeds 1001-{1000 + a.gap_seeds}: found alone {sum(r[3] for r in rows)}"
                  f"/{len(rows)}; gap_before/threshold: " + " ".join(f"{x / y:.2f}" for x, y in zip(g, th)))
            print(f"   gap_before mean {g.mean():.2f} sd {g.std(ddof=1):.2f}; threshold mean {th.mean():.2f} "
                  f"sd {th.std(ddof=1):.2f}")
    for k, f in gens.items():
        for start in ((1, 11, 21, 31, 41, 51) if a.set_records else ()):
            rows = gap_runs(f, a.set_records, "sinusoid", list(range(start, start + 5)))
            print(f"6. {k:12s} hidden sinusoid, simulation seeds {start}-{start + 4}: gap_before mean "
                  f"{np.mean([r[1] for r in rows]):.2f}, threshold {rows[0][2]:.2f}, found alone "
                  f"{sum(r[3] for r in rows)}/{len(rows)}", flush=True)

    for amp in [float(x) for x in a.amplitudes.split(",") if x]:
        rows = gap_runs(gens["gdsim.c"], a.gap_seeds, "sinusoid", 5, {"amplitude": amp, "frequency": 1.3})
        print(f"7. gdsim.c      hidden sinusoid {amp:g} deg/h at 1.3 Hz, records 1001-{1000 + a.gap_seeds}: "
              f"found alone {sum(r[3] for r in rows)}/{len(rows)}", flush=True)


if __name__ == "__main__":
    main()
