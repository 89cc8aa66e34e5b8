"""Ground-truth benchmark report: what the filters really do.

    python benchmarks/report.py --out docs/reports/benchmark [--quick] [--seed 0]

Simulates the paper's FOG (models/paper_fog.toml, 200 Hz) and an ICM-20602-like
MEMS gyro (models/icm20602.toml, 1 kHz) with known true rate, runs every
method on the same records and writes ``report.md`` and PNG figures into the
folder named by ``--out``; the report is stamped with the commit and the command.
Progress goes to stderr. Nothing here is a timed test; the per-sample costs are
measured in this one process.

Methods: raw; the project's conventional KF, modified SHAKF (the paper) and
classic Sage-Husa (Eq. 22/26 unmodified) on the online improved AR(3) model;
ArduPilot's first-order low-pass at 20 Hz; PX4's 2nd-order Butterworth at
30 Hz; an offline RTS smoother and the VB-AKF of Huang et al. (2018), both on
the AR model identified by the KF run (benchmarks.reference_filters).

Dynamic metrics use the *incremental response*: the output for (noise + true
motion) minus the output for the same noise alone. For the linear filters this
is exactly the noise-free response; for the adaptive ones it is the response
they give to that motion with that noise, which is what a user gets.
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

import gyrodenoise as gd
from benchmarks import reference_filters as RF
from benchmarks.provenance import stamp
from gyrodenoise.core import kernels as K
from gyrodenoise.units import TERM_SYMBOLS
from gyrodenoise.analysis.experiments import compare, filter_record, paper_std, rise_time, rmse
from gyrodenoise.simulator import load_card, simulate

METHODS = ["raw", "kf", "shakf", "sh_classic", "shakf_gate", "lp20", "bw30", "rts", "vbakf"]
ADAPTIVE = ["kf", "shakf", "sh_classic", "shakf_gate", "vbakf"]   # depend on the motion's onset
PAPER_KW = {"outlier_sigma": 0.0}    # the paper's filters: the kernels' outlier gate off
LABEL = {
    "raw": "raw",
    "kf": "KF, AR(3) (conventional)",
    "shakf": "modified SHAKF (the paper)",
    "sh_classic": "classic Sage-Husa (Eq. 22/26)",
    "shakf_gate": "SHAKF + outlier gate (project default)",
    "lp20": "1st-order LP 20 Hz (ArduPilot)",
    "bw30": "2nd-order Butterworth 30 Hz (PX4)",
    "rts": "RTS smoother, AR(3) (offline)",
    "vbakf": "VB-AKF, AR(3) (Huang 2018)",
}
COLOR = {"raw": "0.6", "kf": "tab:green", "shakf": "tab:red", "sh_classic": "tab:purple", "shakf_gate": "tab:pink",
         "lp20": "tab:blue", "bw30": "tab:cyan", "rts": "tab:orange", "vbakf": "tab:brown"}
CARDS = {"fog": "paper_fog", "mems": "icm20602"}
CARD_LABEL = {"fog": "paper FOG, 200 Hz", "mems": "ICM-20602-like MEMS, 1 kHz"}
PAPER_TABLE1 = {  # Sun et al. (2016), Table 1
    "raw": {"N": 4.2026e-6, "B": 7.1221e-4, "K": 0.0335, "R": 0.5401, "Q": 1.1565e-5},
    "ar_fit": {"N": 3.9168e-6, "B": 7.0438e-4, "K": 0.0334, "R": 0.5390, "Q": 1.1195e-5},
    "kf": {"N": 3.2547e-6, "B": 6.1221e-4, "K": 0.0246, "R": 0.4286, "Q": 9.4795e-6},
    "shakf": {"N": 2.0632e-6, "B": 3.5235e-4, "K": 0.0162, "R": 0.2636, "Q": 5.4532e-6},
}
PAPER_TABLE2 = {  # rate: (raw, KF, SHAKF) "MSE" (a std, Eq. 41), deg/s
    5: (0.1068, 0.0362, 0.0184), 15: (0.2461, 0.0932, 0.0396), 25: (0.1629, 0.1086, 0.0280),
    35: (0.0844, 0.0637, 0.0145), 50: (0.0538, 0.0445, 0.0093)}
STEP_DEG_S = 10.0
RAMP_DEG_S2 = 2.0
RAMP_S = 10.0
SINE_AMP_DEG_S = 10.0
SINE_OFFSET_SAMPLES = 0.37
SINE_FADE_S = 1.0


def log(msg):
    print(f"[report] {msg}", file=sys.stderr, flush=True)


# ------------------------------------------------------------------ methods
def apply(method, z, fs, model=None):
    """Run one method over a record (restart at sample 0); returns the output."""
    z = np.asarray(z, dtype=float)
    if method == "raw":
        return z.copy()
    if method in ("kf", "shakf", "sh_classic"):
        return filter_record(z, fs, method, **PAPER_KW)[0]
    if method == "shakf_gate":
        return filter_record(z, fs, "shakf")[0]
    if method == "lp20":
        return RF.lowpass1(z, fs, 20.0)[0]
    if method == "bw30":
        return RF.butter2(z, fs, 30.0)[0]
    if method == "rts":
        return RF.smooth_record(z, fs, model=model)
    if method == "vbakf":
        return RF.vbakf_record(z, fs, model=model)
    raise ValueError(method)


def apply_all(z, fs, methods=METHODS):
    model = RF.record_ar_model(z, fs, "kf", **PAPER_KW)
    return {m: apply(m, z, fs, model) for m in methods}


def warmup_samples(fs):
    return int(K.make_params(sample_rate_hz=fs)[K.P_WARMUP])


# ------------------------------------------------------------------ static
def static_section(key, cfg, seed):
    card = load_card(CARDS[key])
    fs = card.sample_rate_hz
    n = int(cfg["static_s"][key] * fs)
    log(f"{key}: static record, {n} samples")
    rec = simulate(card, n, seed=seed)
    outs = apply_all(rec.rate_deg_s, fs)
    start = warmup_samples(fs)
    res = {m: gd.allan(y[start:], fs) for m, y in outs.items()}
    rows = {m: dict(r.terms) for m, r in res.items()}
    bounds = {m: dict(r.bounds) for m, r in res.items()}
    std = {m: paper_std(y[start:]) for m, y in outs.items()}
    out = {"n": n, "fs": fs, "rows": rows, "bounds": bounds, "std": std, "allan": res,
           "ratio": {m: {t: (rows[m][t] / rows["raw"][t] if rows["raw"][t] > 0 else None)
                         for t in TERM_SYMBOLS} for m in METHODS}}
    if key == "fog":
        log("fog: paper Table 1 via experiments.compare")
        cmp = compare(rec, **PAPER_KW)
        out["compare"] = {k: cmp[k] for k in ("rows", "bounds", "ar_fit_accuracy", "ratio_to_raw", "ar_model")}
    return out


def kr_section(cfg, seed):
    """The earlier observation: K and R after SHAKF ~2x higher than raw on 600 s
    FOG records. Re-measure over several seeds and test the explanation."""
    card = load_card("paper_fog")
    fs = card.sample_rate_hz
    n = int(600 * fs)
    start = warmup_samples(fs)
    rows = []
    for i in range(cfg["kr_seeds"]):
        rec = simulate(card, n, seed=seed + 300 + i)
        z = rec.rate_deg_s
        y = filter_record(z, fs, "shakf", **PAPER_KW)[0]
        # explanation under test: once q has decayed the output is the model mean
        # c / (1 - sum phi), i.e. the RLS intercept: a running mean of the record
        run_mean = np.cumsum(z) / np.arange(1, n + 1)
        a_raw, a_sh = gd.allan(z[start:], fs), gd.allan(y[start:], fs)
        a_mean = gd.allan(run_mean[start:], fs)
        dev = float(np.sqrt(np.mean((y[start:] - run_mean[start:]) ** 2)))
        rows.append({"seed": seed + 300 + i,
                     "K": (a_raw.terms["K"], a_sh.terms["K"], a_mean.terms["K"]),
                     "R": (a_raw.terms["R"], a_sh.terms["R"], a_mean.terms["R"]),
                     "kb": (a_raw.bounds["K"], a_sh.bounds["K"]), "rb": (a_raw.bounds["R"], a_sh.bounds["R"]),
                     "rms_to_running_mean": dev, "raw_std": float(np.std(z[start:])),
                     "sh_std": float(np.std(y[start:]))})
    return rows


# ---------------------------------------------------------------- Table 2
def table2_section(key, cfg, seed):
    card = load_card(CARDS[key])
    fs = card.sample_rate_hz
    n = int(cfg["table2_s"][key] * fs)
    start = warmup_samples(fs)
    rows = []
    for i, w in enumerate(cfg["rates"]):
        log(f"{key}: constant rate {w:g} deg/s")
        rec = simulate(card, n, seed=seed + 10 + i, true_rate_deg_s=w)
        outs = apply_all(rec.rate_deg_s, fs)
        rows.append({"rate": w,
                     "std": {m: paper_std(y[start:]) for m, y in outs.items()},
                     "rmse": {m: rmse(y[start:], rec.true_rate_deg_s[start:]) for m, y in outs.items()}})
    return rows


# ----------------------------------------------------------------- dynamics
def _sine_fit(y, t, f):
    b = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)])
    s, c, _ = np.linalg.lstsq(b, y, rcond=None)[0]
    return math.hypot(s, c), math.atan2(c, s)      # y ~ g sin(w t + phase)


def bandwidth_hz(freqs, gains):
    """First frequency where the gain falls below 1/sqrt(2), log-interpolated.
    Returns (value, qualifier) with qualifier "<", "=", or ">"."""
    lim = 1 / math.sqrt(2)
    if gains[0] < lim:
        return freqs[0], "<"
    for i in range(1, len(freqs)):
        if gains[i] < lim:
            lf0, lf1 = math.log(freqs[i - 1]), math.log(freqs[i])
            g0, g1 = gains[i - 1], gains[i]
            return math.exp(lf0 + (g0 - lim) / (g0 - g1) * (lf1 - lf0)), "="
    return freqs[-1], ">"


def dynamics_section(key, cfg, seed):
    card = load_card(CARDS[key])
    fs = card.sample_rate_hz
    pre = cfg["pre_s"]
    out = {"pre_s": pre}
    # -- step and ramp on one noise record
    n = int((pre + cfg["step_post_s"]) * fs)
    log(f"{key}: step and ramp ({n} samples)")
    z0 = simulate(card, n, seed=seed + 200).rate_deg_s
    t = np.arange(n) / fs
    after = t >= pre
    y0 = apply_all(z0, fs)
    step = np.where(after, STEP_DEG_S, 0.0)
    ys = apply_all(z0 + step, fs)
    ramp = np.clip((t - pre) * RAMP_DEG_S2, 0.0, RAMP_DEG_S2 * RAMP_S)
    yr = apply_all(z0 + ramp, fs)
    in_ramp = after & (t < pre + RAMP_S)
    late_ramp = (t >= pre + RAMP_S / 2) & (t < pre + RAMP_S)
    step_res, ramp_res, step_curves = {}, {}, {}
    win = after & (t < pre + 10.0)
    for m in METHODS:
        resp = ys[m] - y0[m]
        step_curves[m] = resp[after][: int(min(cfg["step_post_s"], 300.0) * fs)]
        rt = rise_time(resp, t, pre, STEP_DEG_S)
        step_res[m] = {"rise_90_s": rt,
                       "overshoot_pct": float(max(0.0, resp[after].max() / STEP_DEG_S - 1.0) * 100.0),
                       "rmse_10s": rmse(ys[m][win], step[win])}
        rresp = yr[m] - y0[m]
        ramp_res[m] = {"rmse": rmse(yr[m][in_ramp], ramp[in_ramp]),
                       "lag_s": float(np.mean(ramp[late_ramp] - rresp[late_ramp]) / RAMP_DEG_S2)}
    out.update(step=step_res, ramp=ramp_res, step_curves=step_curves, step_post_s=cfg["step_post_s"])
    # -- sinusoids
    freqs = [f for f in cfg["freqs"] if f < 0.45 * fs]
    gains = {m: [] for m in METHODS}
    phases = {m: [] for m in METHODS}
    srmse = {m: [] for m in METHODS}
    gab = {m: [] for m in ADAPTIVE}
    seg_len = {f: max(10.0 / f, 10.0) for f in freqs}
    n_max = int((pre + max(seg_len.values())) * fs)
    zs = simulate(card, n_max, seed=seed + 201).rate_deg_s
    base = apply_all(zs, fs)          # causal methods: a prefix is the shorter run
    for f in freqs:
        nf = int((pre + seg_len[f]) * fs)
        log(f"{key}: sinusoid {f:g} Hz ({nf} samples)")
        tt = np.arange(nf) / fs
        # phase time offset by a fraction of a sample so that no sample falls on an
        # exact zero crossing (the sweep frequencies divide fs), faded in over 1 s
        ts = tt - pre + SINE_OFFSET_SAMPLES / fs
        env = 0.5 * (1.0 - np.cos(np.pi * np.clip((tt - pre) / SINE_FADE_S, 0.0, 1.0)))
        truth = np.where(tt >= pre, SINE_AMP_DEG_S * env * np.sin(2 * np.pi * f * ts), 0.0)
        ysn = apply_all(zs[:nf] + truth, fs)
        # the adaptive filters depend on how the motion starts: the same sinusoid, switched on at once
        truth_ab = np.where(tt >= pre, SINE_AMP_DEG_S * np.sin(2 * np.pi * f * ts), 0.0)
        yab = apply_all(zs[:nf] + truth_ab, fs, ADAPTIVE)
        model0 = RF.record_ar_model(zs[:nf], fs, "kf", **PAPER_KW)
        meas = tt >= pre + seg_len[f] / 2
        for m in METHODS:
            y_noise = RF.smooth_record(zs[:nf], fs, model=model0) if m == "rts" else base[m][:nf]
            g, ph = _sine_fit((ysn[m] - y_noise)[meas], ts[meas], f)
            gains[m].append(g / SINE_AMP_DEG_S)
            phases[m].append(ph)
            srmse[m].append(rmse(ysn[m][meas], truth[meas]))
            if m in ADAPTIVE:
                gab[m].append(_sine_fit((yab[m] - y_noise)[meas], ts[meas], f)[0] / SINE_AMP_DEG_S)
    bw = {m: bandwidth_hz(freqs, gains[m]) for m in METHODS}
    delay = {}
    for m in METHODS:
        i1 = freqs.index(1.0) if 1.0 in freqs else 0
        g, ph = gains[m][i1], phases[m][i1]
        delay[m] = (-ph / (2 * np.pi * freqs[i1])) if g > 0.1 else None
    out.update(freqs=freqs, gains=gains, phases=phases, sine_rmse=srmse, bandwidth=bw, delay_1hz_s=delay,
               gains_abrupt=gab, bandwidth_abrupt={m: bandwidth_hz(freqs, gab[m]) for m in ADAPTIVE})
    return out


# -------------------------------------------------------------------- cost
def cost_section(cfg, seed):
    n = cfg["cost_n"]
    z = simulate("paper_fog", n, seed=seed + 400).rate_deg_s
    fs = 200.0
    apply_all(z[:5000], fs)                  # compile / warm up every path
    out = {}
    for m in METHODS:
        if m == "raw":
            continue
        best = float("inf")
        for _ in range(cfg["cost_repeat"]):
            t0 = time.perf_counter()
            if m in ("rts", "vbakf"):        # includes identifying the model they run on
                apply(m, z, fs, RF.record_ar_model(z, fs, "kf", **PAPER_KW))
            else:
                apply(m, z, fs)
            best = min(best, time.perf_counter() - t0)
        out[m] = best / n * 1e9
    return out


# ------------------------------------------------------------------ figures
def figures(outdir, R):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    files = []
    for key in CARDS:
        st = R["static"][key]
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for m in METHODS:
            a = st["allan"][m]
            ax.loglog(a.tau_s, a.adev_deg_h, color=COLOR[m], label=LABEL[m], lw=2 if m in ("raw", "shakf") else 1)
        files.append(_finish(plt, fig, ax, outdir / f"allan_{key}.png", "tau, s", "Allan deviation, deg/h",
                             f"Static record, {CARD_LABEL[key]}", "lower left"))

        dy = R["dyn"][key]
        fig, ax = plt.subplots(figsize=(7, 4.5))
        fs = st["fs"]
        for m in METHODS:
            c = dy["step_curves"][m]
            idx = np.unique(np.geomspace(1, c.size, 1500).astype(int)) - 1    # log-spaced samples
            ax.semilogx((idx + 1) / fs, c[idx], color=COLOR[m], label=LABEL[m], lw=1)
        ax.axhline(STEP_DEG_S, color="k", lw=0.5)
        files.append(_finish(plt, fig, ax, outdir / f"step_{key}.png", "time after the step, s (log)",
                             "incremental response, deg/s",
                             f"{STEP_DEG_S:g} deg/s step after {dy['pre_s']:g} s at rest, {CARD_LABEL[key]}",
                             "center left"))

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for m in METHODS:
            ax.loglog(dy["freqs"], np.maximum(dy["gains"][m], 1e-4), "o-", ms=3, color=COLOR[m], label=LABEL[m])
        ax.axhline(1 / math.sqrt(2), color="k", lw=0.5, ls="--")
        files.append(_finish(plt, fig, ax, outdir / f"gain_{key}.png", "frequency, Hz",
                             "gain (incremental response / true sinusoid)",
                             f"Gain from sinusoid sweeps, {CARD_LABEL[key]}", "lower left"))

    fig, ax = plt.subplots(figsize=(7, 5))
    for key, mk in (("fog", "o"), ("mems", "s")):
        st, dy = R["static"][key], R["dyn"][key]
        for m in METHODS:
            bw, q = dy["bandwidth"][m]
            red = st["std"]["raw"] / st["std"][m]
            ax.scatter(bw, red, marker=mk, color=COLOR[m], s=45,
                       label=LABEL[m] if key == "fog" else None)
            if q != "=":
                ax.annotate(q, (bw, red), textcoords="offset points", xytext=(5, 3), fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    files.append(_finish(plt, fig, ax, outdir / "tradeoff.png",
                         "-3 dB bandwidth, Hz (from sinusoid sweeps; < / > = beyond the sweep)",
                         "static noise reduction (raw std / output std)",
                         "The price of lower noise: circles FOG 200 Hz, squares MEMS 1 kHz"))
    return files


def _finish(plt, fig, ax, path, xlabel, ylabel, title, legend_loc=None):
    """Label the axes, draw the grid and the legend, write the PNG ``path`` and close the
    figure; returns the file's name."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc=legend_loc)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


# ------------------------------------------------------------------ report
def _g(v, fmt=".3g"):
    if v is None:
        return "-"
    if isinstance(v, float) and not math.isfinite(v):
        return "-"
    return format(v, fmt)


def _bw(b):
    v, q = b
    return f"{q} {v:.3g}" if q != "=" else f"{v:.3g}"


def _rise(r, post):
    return f"> {post:g}" if r is None else _g(r)


def headline(R, key):
    st, t2, dy, cost = R["static"][key], R["table2"][key], R["dyn"][key], R["cost"]
    i10 = [r["rate"] for r in t2].index(10.0)
    lines = ["| method | static std ratio | N ratio | B ratio | RMSE at 10 deg/s, deg/s | step 90 % rise, s "
             "| delay at 1 Hz, ms | -3 dB bandwidth, Hz | cost, ns/sample |",
             "|---|---|---|---|---|---|---|---|---|"]
    for m in METHODS:
        d = dy["delay_1hz_s"][m]
        lines.append(
            f"| {LABEL[m]} | {_g(st['std'][m] / st['std']['raw'])} | {_g(st['ratio'][m]['N'])} "
            f"| {_g(st['ratio'][m]['B'])} | {_g(t2[i10]['rmse'][m])} "
            f"| {_rise(dy['step'][m]['rise_90_s'], dy['step_post_s'])} "
            f"| {_ms(d)} | {_bw(dy['bandwidth'][m])} "
            f"| {_g(cost.get(m), '.0f') if m != 'raw' else '0'} |")
    return "\n".join(lines)


def write_report(outdir, R, figs, args, elapsed):
    fog, mems = R["static"]["fog"], R["static"]["mems"]
    L = []
    w = L.append
    w("# Ground-truth benchmark: what the filters really do\n")
    w(stamp(args.argv) + "\n")
    w("> **Note.** The low-passes here are *fixed* (ArduPilot 20 Hz, PX4 30 Hz) references for the paper's "
      "filters, not tuned ones, and this report does not rank `motion`. For every method against filters "
      "tuned per run see [the tuned report](../tuned/report.md) (`python benchmarks/tuned.py`).\n")
    w(f"Seed {args.seed} "
      f"({'quick' if args.quick else 'full'} run, {elapsed:.0f} s on {platform.machine()}, "
      f"Python {platform.python_version()}). Every number below comes from simulated gyros whose true "
      "rate is known (gyrodenoise's simulator and the model cards `paper_fog` and `icm20602`), so "
      "errors are measured against truth, not against the noise of the output.\n")
    w("Methods: **raw**; the project's **KF** (conventional, fixed Q/R), **modified SHAKF** (the paper, "
      "Section 3.2.3) and **classic Sage-Husa** (Eq. 22 and 26 unmodified), all three on the online "
      "improved AR(3) model; **ArduPilot's first-order low-pass at 20 Hz** (alpha = dt/(dt+RC)); "
      "**PX4's 2nd-order Butterworth at 30 Hz** (LowPassFilter2p, bilinear with pre-warping); and, "
      "beyond the paper, an **offline RTS smoother** and the **VB-AKF of Huang et al. (2018)**, both "
      "on the AR(3) model identified by the KF run (`benchmarks/reference_filters.py`). Filtering "
      "starts at a gyro restart at t = 0; the AR filters pass the raw sample through during their "
      "1 s warm-up, which every statistic below skips.\n")
    for key in CARDS:
        w(f"## Headline: {CARD_LABEL[key]}\n")
        w(headline(R, key) + "\n")
    w("Columns: *static std ratio* = output std / raw std on the static record (lower = less noise); "
      "*N, B ratio* = Allan coefficients of the output / of raw (Table 1 style); *RMSE at 10 deg/s* "
      "against the true rate on a constant-rate record (Table 2 style); *step rise* = 90 % rise time "
      f"of the incremental response to a {STEP_DEG_S:g} deg/s step applied after "
      f"{R['dyn']['fog']['pre_s']:g} s at rest (\"> T\" = not reached within the T s recorded); "
      "*delay at 1 Hz* = phase delay of the incremental response to a 1 Hz sinusoid (- where its "
      "gain is below 0.1); *-3 dB bandwidth* = where the gain of the faded-in sinusoid sweep first "
      "falls below 1/sqrt(2), log-interpolated between sweep frequencies (\"<\"/\">\" = below/above "
      "the sweep; the adaptive filters' gains depend on how the motion starts, see Dynamics); *cost* = wall time per sample on the same FOG record in this run, compiled paths "
      "after warm-up (RTS and VB-AKF include the KF run that identifies their model).\n")
    w("![noise vs bandwidth](tradeoff.png)\n")

    # -- claims
    w("## The paper's claims on ground truth\n")
    w(claims(R) + "\n")

    # -- Table 1
    w("## Table 1 reproduction: static FOG, five Allan terms\n")
    w(f"Static record of {fog['n'] / fog['fs'] / 3600:.2g} h at {fog['fs']:g} Hz (the paper: 2 h). Terms in "
      "the spec's units (N deg/sqrt(h), B deg/h, K deg/h^1.5, R deg/h^2, Q deg); `(ub)` marks an upper "
      "bound: the record cannot resolve that term. Ratio = method / raw.\n")
    w(terms_table(fog) + "\n")
    cmp = fog["compare"]
    w("The paper's own Table 1 (its raw N is 4.2e-6 deg/sqrt(h), 1400x below the 0.006 its Section 4.1 "
      "states; the card uses 0.006), and its ratios to raw:\n")
    w("| | N | B | K | R | Q |\n|---|---|---|---|---|---|")
    for m in ("ar_fit", "kf", "shakf"):
        w(f"| paper {m} / raw | " + " | ".join(_g(PAPER_TABLE1[m][t] / PAPER_TABLE1['raw'][t])
                                               for t in TERM_SYMBOLS) + " |")
    w("| ours ar_fit / raw | " + " | ".join(_g(cmp["ratio_to_raw"]["ar_fit"][t]) for t in TERM_SYMBOLS) + " |")
    w("\nAR-fit accuracy (1 - |fit - raw| / raw, the paper's \"fitting accuracy\", claimed >= 93.2 %): "
      + ", ".join(f"{t} {_g(100 * v, '.1f') if v is not None else '-'} %" for t, v in cmp["ar_fit_accuracy"].items())
      + f"; identified AR(3): phi = {', '.join(_g(v, '.4f') for v in cmp['ar_model']['phi'])}, "
      f"c = {_g(cmp['ar_model']['c_deg_s'])} deg/s.\n")
    w("![Allan FOG](allan_fog.png)\n")
    w(f"### The same for the MEMS gyro ({mems['n'] / mems['fs']:g} s at {mems['fs']:g} Hz)\n")
    w(terms_table(mems) + "\n")
    w("![Allan MEMS](allan_mems.png)\n")

    # -- K/R observation
    w("## SHAKF and the K, R terms on 600 s records\n")
    w(kr_text(R["kr"]) + "\n")

    # -- Table 2
    w("## Table 2 reproduction: constant rates\n")
    w("The paper's statistic (its \"MSE\", Eq. 41, is a standard deviation about the mean) and the RMSE "
      "against the true rate, after the warm-up. Each rate is its own record (restart at t = 0) of "
      f"{R['cfg']['table2_s']['fog']:g} s (FOG) / {R['cfg']['table2_s']['mems']:g} s (MEMS).\n")
    for key in CARDS:
        w(f"### {CARD_LABEL[key]}\n")
        w(table2_md(R["table2"][key]) + "\n")
    w("The paper's Table 2 (deg/s): " + "; ".join(
        f"{r:g} deg/s: raw {v[0]}, KF {v[1]}, SHAKF {v[2]}" for r, v in PAPER_TABLE2.items())
      + ". Its raw scatter (0.05-0.25 deg/s) is 40-170x the FOG's own noise at 200 Hz "
      f"({fog['std']['raw']:.2g} deg/s here): the turntable's rate jitter dominates there, which a "
      "simulated constant rate does not have.\n")

    # -- dynamics
    w("## Dynamics: steps, ramps, sinusoids\n")
    w(f"One noise record per card; the gyro rests for {R['dyn']['fog']['pre_s']:g} s after its restart, "
      f"then: a {STEP_DEG_S:g} deg/s step; a ramp of {RAMP_DEG_S2:g} deg/s^2 for {RAMP_S:g} s; "
      f"sinusoids of {SINE_AMP_DEG_S:g} deg/s amplitude (faded in over {SINE_FADE_S:g} s; sampled "
      f"{SINE_OFFSET_SAMPLES:g} sample off the zero crossings, which the sweep frequencies would otherwise hit "
      "exactly), each for max(10 periods, 10 s), gain and phase fitted over the second half. All on the incremental response (output with motion minus output "
      "for the same noise alone).\n")
    for key in CARDS:
        w(f"### {CARD_LABEL[key]}\n")
        w(dyn_md(R["dyn"][key]) + "\n")
        w(f"![step {key}](step_{key}.png) ![gain {key}](gain_{key}.png)\n")

    # -- cost
    w("## Per-sample cost (same run, same record)\n")
    w("| method | ns/sample |\n|---|---|")
    for m, v in R["cost"].items():
        w(f"| {LABEL[m]} | {v:.0f} |")
    w(f"\n{R['cfg']['cost_n']} FOG samples, best of {R['cfg']['cost_repeat']}. KF/SHAKF: the C core's batch "
      "loop (gyrodenoise/core/gdcore.c); LP and Butterworth: scipy.signal.lfilter (C); RTS and VB-AKF: numba loops "
      "over small numpy matrices (they allocate per sample and could be made several times faster), "
      "plus the recorded KF run they use.\n")

    # -- notes
    w("## Method notes and caveats\n")
    w(notes(R) + "\n")
    w("## Reproduce\n")
    w("```\npython benchmarks/report.py --out docs/reports/benchmark" + (" --quick" if args.quick else "")
      + f" --seed {args.seed}\n```\n")
    w(f"Figures: {', '.join(figs)}.\n")
    (outdir / "report.md").write_text("\n".join(L), encoding="utf-8")


def terms_table(st):
    lines = ["| method | " + " | ".join(TERM_SYMBOLS) + " | " + " | ".join(f"{t} ratio" for t in TERM_SYMBOLS) + " |",
             "|---|" + "---|" * 10]
    for m in METHODS:
        vals = [(_g(st["rows"][m][t]) + (" (ub)" if st["bounds"][m][t] == "upper_bound" else ""))
                for t in TERM_SYMBOLS]
        rat = [_g(st["ratio"][m][t]) for t in TERM_SYMBOLS]
        lines.append(f"| {LABEL[m]} | " + " | ".join(vals) + " | " + " | ".join(rat) + " |")
    return "\n".join(lines)


def table2_md(rows):
    hdr = "| rate, deg/s | " + " | ".join(f"{m} std / RMSE" for m in METHODS) + " |"
    lines = [hdr, "|---|" + "---|" * len(METHODS)]
    for r in rows:
        lines.append(f"| {r['rate']:g} | " + " | ".join(f"{_g(r['std'][m])} / {_g(r['rmse'][m])}"
                                                      for m in METHODS) + " |")
    return "\n".join(lines)


def dyn_md(dy):
    lines = ["| method | step rise 90 %, s | overshoot, % | step RMSE first 10 s, deg/s | ramp RMSE, deg/s "
             "| ramp lag, s | delay at 1 Hz, ms | -3 dB bandwidth, Hz |", "|---|---|---|---|---|---|---|---|"]
    for m in METHODS:
        s, r, d = dy["step"][m], dy["ramp"][m], dy["delay_1hz_s"][m]
        lines.append(f"| {LABEL[m]} | {_rise(s['rise_90_s'], dy['step_post_s'])} | {_g(s['overshoot_pct'], '.1f')} "
                     f"| {_g(s['rmse_10s'])} | {_g(r['rmse'])} | {_g(0.0 if abs(r['lag_s']) < 1e-9 else r['lag_s'])} "
                     f"| {_ms(d)} | {_bw(dy['bandwidth'][m])} |")
    lines.append("")
    lines.append("Gain per sweep frequency (incremental response / true amplitude):\n")
    lines.append("| method | " + " | ".join(f"{f:g} Hz" for f in dy["freqs"]) + " |")
    lines.append("|---|" + "---|" * len(dy["freqs"]))
    for m in METHODS:
        lines.append(f"| {m} | " + " | ".join(_g(g, ".2f") for g in dy["gains"][m]) + " |")
    lines.append("")
    lines.append("The same sinusoids switched on at once (no fade-in), for the filters whose model adapts to "
                 "the motion (the RLS re-identifies phi and c in all of them; the Sage-Husa and VB filters "
                 "also adapt q, R):\n")
    lines.append("| method | " + " | ".join(f"{f:g} Hz" for f in dy["freqs"]) + " | -3 dB, Hz |")
    lines.append("|---|" + "---|" * (len(dy["freqs"]) + 1))
    for m in ADAPTIVE:
        lines.append(f"| {m} | " + " | ".join(_g(g, ".2f") for g in dy["gains_abrupt"][m])
                     + f" | {_bw(dy['bandwidth_abrupt'][m])} |")
    return "\n".join(lines)


def kr_text(rows):
    out = ["| seed | K raw | K SHAKF | K running mean | R raw | R SHAKF | R running mean | "
           "rms(SHAKF - running mean) / raw std |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        kb = "(ub)" if r["kb"][1] == "upper_bound" else ""
        rb = "(ub)" if r["rb"][1] == "upper_bound" else ""
        out.append(f"| {r['seed']} | {_g(r['K'][0])}{'(ub)' if r['kb'][0] == 'upper_bound' else ''} "
                   f"| {_g(r['K'][1])}{kb} | {_g(r['K'][2])} | {_g(r['R'][0])}"
                   f"{'(ub)' if r['rb'][0] == 'upper_bound' else ''} | {_g(r['R'][1])}{rb} | {_g(r['R'][2])} "
                   f"| {_g(r['rms_to_running_mean'] / r['raw_std'])} |")
    kr = np.array([r["K"][1] / r["K"][0] for r in rows])
    rr = np.array([r["R"][1] / r["R"][0] for r in rows])
    dev = np.array([r["rms_to_running_mean"] / r["raw_std"] for r in rows])
    out.append("")
    seen = "reproduced" if np.median(kr) > 1.5 and np.median(rr) > 1.5 else "not reproduced"
    out.append(f"Over {len(rows)} seeds of 600 s (paper's filter, gate off) the SHAKF/raw ratio is K "
               f"{np.median(kr):.2g} (median; range {kr.min():.2g}-{kr.max():.2g}) and R {np.median(rr):.2g} "
               f"({rr.min():.2g}-{rr.max():.2g}): the earlier observation of K and R ~2x *higher* after SHAKF is "
               f"**{seen}** here as a rule. What holds on every seed is the mechanism: once the Sage-Husa q has "
               "decayed, the SHAKF output is the AR model's mean c / (1 - sum phi), i.e. the RLS intercept, which "
               "with forgetting factor 1 is a running (expanding-window) mean of the record. The SHAKF output "
               f"stays within {np.median(dev):.2g} raw standard deviations (median) of the plain running mean of "
               "the raw record, and the running mean's own K and R are in the table. A running mean removes the "
               "white noise (N collapses) but keeps a slow wander - the record's own low-frequency content, "
               "averaged over a growing window - which the five-term fit can only express as K and R. On "
               "600 s records (taus up to 300 s) these terms are barely resolved (many are upper bounds, `ub`), "
               "so their ratio swings with the record's low-frequency content: above 1 on some records, below 1 "
               "on others. Neither is a change of the sensor's rate random walk or rate ramp: the filter cannot "
               "remove drift that it cannot tell from rate, it can only smooth it.")
    return "\n".join(out)


def _verdict(ok_all, ok_any):
    return "**holds**" if ok_all else ("**partly**" if ok_any else "**does not hold**")


def claims(R):
    fog, mems = R["static"]["fog"], R["static"]["mems"]
    dyf, dym = R["dyn"]["fog"], R["dyn"]["mems"]
    t2f = R["table2"]["fog"]
    r_sh = fog["ratio"]["shakf"]
    half = {t: (r_sh[t] is not None and r_sh[t] <= 0.5) for t in TERM_SYMBOLS}
    ub = {t: fog["bounds"]["raw"][t] == "upper_bound" or fog["bounds"]["shakf"][t] == "upper_bound"
          for t in TERM_SYMBOLS}
    better = [t for t in TERM_SYMBOLS if fog["rows"]["shakf"][t] < fog["rows"]["kf"][t]]
    std_sh = np.array([r["std"]["shakf"] / r["std"]["raw"] for r in t2f])
    std_kf = np.array([r["std"]["kf"] / r["std"]["raw"] for r in t2f])
    rm_sh = np.array([r["rmse"]["shakf"] / r["rmse"]["raw"] for r in t2f])
    acc = fog["compare"]["ar_fit_accuracy"]
    acc_ok = [t for t, v in acc.items() if v is not None and v >= 0.932]
    rates_txt = ", ".join(f"{r['rate']:g}" for r in t2f)
    post = dyf["step_post_s"]
    sh_step, raw_step = dyf["step"]["shakf"], dyf["step"]["raw"]
    dyn_bad = (sh_step["rmse_10s"] > raw_step["rmse_10s"]
               or dyf["ramp"]["shakf"]["rmse"] > dyf["ramp"]["raw"]["rmse"])
    rows = ["| # | the paper says | measured on ground truth | verdict |", "|---|---|---|---|"]
    rows.append(
        "| 1 | After the modified SHAKF all five Allan coefficients are less than half of the raw ones "
        "(Table 1, Section 4.2) | SHAKF / raw: " + ", ".join(
            f"{t} {_g(r_sh[t])}{' (ub)' if ub[t] else ''}" for t in TERM_SYMBOLS)
        + " | " + _verdict(all(half[t] and not ub[t] for t in TERM_SYMBOLS), any(half.values()))
        + (" (ratios marked ub compare upper bounds, not measured terms)" if any(ub.values()) else "") + " |")
    rows.append(
        f"| 2 | SHAKF halves bias instability (0.000712 -> 0.000352 deg/h) | B ratio {_g(r_sh['B'])}"
        f"{'; B is only an upper bound on this record' if ub['B'] else ''}. With the card's N (the "
        f"paper's stated 0.006 deg/sqrt(h)) the B plateau 0.664 B sinks below the ARW slope only at tau = "
        f"{_b_visible_h():.3g} h, so no record of hours can resolve this B, raw or filtered | "
        + _verdict(half["B"] and not ub["B"], half["B"]) + " |")
    rows.append(
        f"| 3 | SHAKF is better than the KF on static data (up to 42.5 % per term) | SHAKF below KF for "
        f"{len(better)} of 5 terms ({', '.join(better) or 'none'}) | "
        + _verdict(len(better) == 5, len(better) > 0) + " |")
    rows.append(
        f"| 4 | The online improved AR(3) model fits every noise term with >= 93.2 % accuracy | "
        f"{len(acc_ok)} of 5 terms >= 93.2 % (" + ", ".join(
            f"{t} {100 * v:.0f} %" for t, v in acc.items() if v is not None) + ") | "
        + _verdict(len(acc_ok) == 5, len(acc_ok) > 0) + " |")
    t2_ok = bool(np.all(std_sh < std_kf) and np.all(std_kf < 1))
    rows.append(
        f"| 5 | At constant rates ({rates_txt} deg/s) the SHAKF's scatter (Eq. 41) is far below raw "
        f"and KF (Table 2: SHAKF/raw 0.16-0.24) | SHAKF/raw std {_g(std_sh.min())}-{_g(std_sh.max())}, "
        f"KF/raw {_g(std_kf.min())}-{_g(std_kf.max())}; RMSE against truth SHAKF/raw "
        f"{_g(rm_sh.min())}-{_g(rm_sh.max())} | " + _verdict(t2_ok, bool(np.any(std_sh < 1))) + " |")
    rows.append(
        f"| 6 | Hence the SHAKF suits moving-base (dynamic) conditions | a {STEP_DEG_S:g} deg/s step after "
        f"{dyf['pre_s']:g} s at rest: 90 % rise {_rise(sh_step['rise_90_s'], post)} s (raw "
        f"{_rise(raw_step['rise_90_s'], post)} s), RMSE over the first 10 s {_g(sh_step['rmse_10s'])} deg/s "
        f"(raw {_g(raw_step['rmse_10s'])}); {RAMP_DEG_S2:g} deg/s^2 ramp RMSE "
        f"{_g(dyf['ramp']['shakf']['rmse'])} (raw {_g(dyf['ramp']['raw']['rmse'])}); -3 dB bandwidth "
        f"{_bw(dyf['bandwidth']['shakf'])} Hz (FOG), {_bw(dym['bandwidth']['shakf'])} Hz (MEMS) | "
        + ("**does not hold**" if dyn_bad else "**holds**") + " |")
    L = ["\n".join(rows), ""]
    L.append("Why: the std reduction of "
             f"{_g(fog['std']['raw'] / fog['std']['shakf'], '.0f')}x on the static FOG record is what any filter "
             "with very little bandwidth gives. On data without motion the Sage-Husa process-noise estimate q "
             "(Eq. 26) decays towards 0, so the filter comes to trust its AR model of a constant, and its output "
             "becomes the model's mean, a running mean of the record (see the K, R section). The Table-2 "
             "statistic is a standard deviation about the record's own mean, so it rewards exactly that, and a "
             "rate that never changes cannot reveal the lag. Against truth, with motion, the same filter "
             "misses real rotation. The paper's raw Table-1 N is also 1400x below the N its Section 4.1 states, "
             "and its Table 2 raw scatter is mostly turntable jitter (see below), so its numbers cannot be "
             "matched one for one; the ratios can.")
    L.append("")
    L.append(f"Classic Sage-Husa (Eq. 22/26, the form the paper modified): its R estimate (v^2 - HPH') can go "
             f"negative and is clipped at the floor; static std ratio {_g(fog['std']['sh_classic'] / fog['std']['raw'])} "
             f"(modified {_g(fog['std']['shakf'] / fog['std']['raw'])}), FOG bandwidth "
             f"{_bw(dyf['bandwidth']['sh_classic'])} Hz.")
    L.append("")
    L.append(f"The project's default SHAKF adds an innovation gate (not in the paper; 5 sigma, re-opening by a "
             f"restart after 20 rejected samples): a {STEP_DEG_S:g} deg/s step is then followed in "
             f"{_rise(dyf['step']['shakf_gate']['rise_90_s'], post)} s on the FOG and "
             f"{_rise(dym['step']['shakf_gate']['rise_90_s'], dym['step_post_s'])} s on the MEMS (the output "
             "passes the raw rate through the re-identification warm-up), at static std ratio "
             f"{_g(fog['std']['shakf_gate'] / fog['std']['raw'])}. Whether smoother motion re-opens it depends "
             f"on the noise level: on the {RAMP_DEG_S2:g} deg/s^2 ramp its RMSE is "
             f"{_g(dyf['ramp']['shakf_gate']['rmse'])} deg/s on the FOG (raw {_g(dyf['ramp']['raw']['rmse'])}) and "
             f"{_g(dym['ramp']['shakf_gate']['rmse'])} deg/s on the MEMS (raw {_g(dym['ramp']['raw']['rmse'])}); "
             "its sweep gains are in the tables. The gate rescues abrupt motion, not the filter's lock.")
    L.append("")
    L.append("**What a user would pick instead**\n")
    L.append(f"- For a live control loop: the 2nd-order Butterworth or the 1st-order LP: fixed, known bandwidth "
             f"({_bw(dym['bandwidth']['bw30'])} Hz and {_bw(dym['bandwidth']['lp20'])} Hz on the MEMS), delay "
             f"at 1 Hz {_ms(dym['delay_1hz_s']['bw30'])} ms and {_ms(dym['delay_1hz_s']['lp20'])} ms, static std "
             f"ratio {_g(mems['std']['bw30'] / mems['std']['raw'])} and {_g(mems['std']['lp20'] / mems['std']['raw'])}, "
             f"{_g(R['cost']['bw30'], '.0f')} and {_g(R['cost']['lp20'], '.0f')} ns per sample, and nothing that "
             "adapts itself into a lock after a quiet start.")
    L.append(f"- For flight-log post-processing: the RTS smoother on the KF's model: static std ratio "
             f"{_g(fog['std']['rts'] / fog['std']['raw'])} (FOG) / {_g(mems['std']['rts'] / mems['std']['raw'])} "
             f"(MEMS), delay at 1 Hz {_ms(dyf['delay_1hz_s']['rts'])} ms (FOG), bandwidth "
             f"{_bw(dyf['bandwidth']['rts'])} / {_bw(dym['bandwidth']['rts'])} Hz: a zero-lag KF, but no more "
             "noise reduction than the model's split of process and measurement noise allows.")
    L.append(f"- The VB-AKF (Huang 2018, the paper's tuning tau = 3): static std ratio "
             f"{_g(fog['std']['vbakf'] / fog['std']['raw'])} (FOG). On a gyro at rest the AR state model cannot "
             "tell process noise from measurement noise, and the variational estimate of R drifts low, so the "
             f"filter follows the raw signal at rest; after a step the large innovations inflate R and it needs "
             f"{_rise(dyf['step']['vbakf']['rise_90_s'], dyf['step_post_s'])} s (FOG) to follow. It is sound where "
             "the split is identifiable "
             "(`test_vbakf_learns_measurement_noise_from_a_wrong_nominal`): the failure is the state model's, "
             "and the paper's filters share it - their Q/R split is a choice, not an estimate.")
    return "\n".join(L)


def _b_visible_h():
    """Hours of averaging at which the paper FOG's ARW slope N/sqrt(tau) falls to
    its bias-instability plateau 0.664 B (Eq. 40), from the model card."""
    card = load_card("paper_fog")
    n_deg_rts = card.terms["angle_random_walk"]["N"] / 60.0
    b_deg_s = card.terms["bias_instability"]["B"] / 3600.0
    return (n_deg_rts / (math.sqrt(2 * math.log(2) / math.pi) * b_deg_s)) ** 2 / 3600.0


def _ms(v):
    if v is None:
        return "-"
    v = v * 1e3
    return "0" if abs(v) < 1e-6 else _g(v)


def notes(R):
    return "\n".join([
        "- Sample rates and cutoffs: the FOG card is 200 Hz, so the 20 Hz LP and the 30 Hz Butterworth "
        "are at 0.2 and 0.3 of Nyquist: the Butterworth's pre-warped design keeps its -3 dB point exactly "
        "at 30 Hz; ArduPilot's alpha = dt/(dt+RC) puts the LP's true -3 dB point at "
        f"{RF.lowpass1_cutoff_3db_hz(200.0, 20.0):.1f} Hz at 200 Hz and "
        f"{RF.lowpass1_cutoff_3db_hz(1000.0, 20.0):.1f} Hz at 1 kHz (tested). A cutoff at or above "
        "Nyquist is refused (ValueError), not clipped.",
        "- The five-term Allan fit (Eq. 40) assumes an unfiltered sensor. A low-pass output's Allan curve "
        "falls below N/sqrt(tau) for tau up to a few filter time constants and then rejoins it; the fit "
        "can trade that bend for a B or Q term, so the B, Q (and sometimes N) ratios of the LP, Butterworth "
        "and KF rows are partly fit artefacts, not sensor properties (compare the curves in allan_*.png). "
        "The std ratio and the RMSE against truth have no such problem.",
        "- The MEMS card (models/icm20602.toml) takes N from the ICM-20602 datasheet (4 mdps/sqrt(Hz)); "
        "its B, K and the 1 kHz rate are assumptions stated in the card.",
        "- RTS smoother: forward KF on the state [z_k..z_{k-2}] with c_k as a known input (as the kernels "
        "tie c to the RLS estimate), phi_k, c_k, q, r taken sample by sample from the recorded KF run, "
        "then the Rauch-Tung-Striebel backward pass. Tested: the smoother equals the dense joint-Gaussian "
        "posterior mean to 1e-9; its forward pass equals the project's KF output to 1e-10 deg/s.",
        "- VB-AKF: Algorithm 1 of Huang et al. (2018) with inverse-Wishart priors on P_{k|k-1} "
        "(tau = 3) and an inverse-Gamma (1-D inverse-Wishart) on R (rho = 1 - exp(-4)), 10 fixed-point "
        "iterations per sample, nominal Q and R from the KF run. Tested on an AR(1)-plus-noise case: with "
        "tau = 100 it learns R within 10 % from a nominal 4x too small or too large; with tau = 3 it "
        "underestimates R (the loose P prior absorbs part of it) - documented in the tests.",
        "- Incremental responses are exact for the linear filters and the RTS smoother on a fixed model; "
        "for the adaptive filters (and for RTS/VB, whose model is re-identified on each record) they "
        "are the response *with that noise*; the AR model identified with motion differs from the one "
        "without, which is part of what a user gets.",
        "- The kernels' innovation gate (outlier_sigma) is off (outlier_sigma = 0) for the KF, "
        "SHAKF, classic Sage-Husa, RTS and VB-AKF rows - the paper's filters - and on, at the project "
        "default, for the 'SHAKF + outlier gate' row. Rerun the command after kernel changes; a full run "
        "takes about 4 minutes on 2 shared cores.",
        "- Bandwidth of the AR-model filters is not a fixed property: the online RLS re-identifies the "
        "AR(3) model on a steady sinusoid (a sinusoid is exactly AR(2)-predictable), after which the KF, "
        "whose q is frozen at its warm-up level, passes it at any frequency. The sweep gains are for "
        "steady sinusoids after that re-identification; the step and ramp columns show the transient.",
        "- The adaptive filters' sweep gains depend on how the motion starts (compare the faded-in and the "
        "switched-on tables): their q, R and AR model are re-estimated from the motion itself, so a "
        "single bandwidth number describes them less well than it describes the fixed low-pass filters. "
        "The lowest sweep frequencies also have the longest segments (10 periods: 200 s at 0.05 Hz), long "
        "enough for the Sage-Husa estimator to raise q again; there the SHAKF's gain near 1 measures that "
        "re-adaptation after tens of seconds of persistent error, not a pass band.",
        "- Per-sample costs are wall times on 2 cores shared with other jobs; compare them within one run.",
    ])


# ------------------------------------------------------------------- main
def config(quick):
    if quick:
        return {"static_s": {"fog": 600.0, "mems": 120.0}, "table2_s": {"fog": 60.0, "mems": 20.0},
                "rates": [5.0, 10.0, 15.0, 25.0, 35.0, 50.0], "pre_s": 30.0, "step_post_s": 60.0,
                "freqs": [0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 80.0, 200.0, 400.0],
                "kr_seeds": 2, "cost_n": 200_000, "cost_repeat": 2}
    return {"static_s": {"fog": 3600.0, "mems": 600.0}, "table2_s": {"fog": 300.0, "mems": 60.0},
            "rates": [5.0, 10.0, 15.0, 25.0, 35.0, 50.0], "pre_s": 120.0, "step_post_s": 300.0,
            "freqs": [0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 80.0, 200.0,
                      400.0],
            "kr_seeds": 5, "cost_n": 1_000_000, "cost_repeat": 2}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="folder for report.md and the PNG figures")
    ap.add_argument("--quick", action="store_true", help="shorter records (~1 min; for checking the pipeline)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    args.argv = sys.argv[1:] if argv is None else list(argv)
    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    cfg = config(args.quick)
    R = {"cfg": cfg}
    R["cost"] = cost_section(cfg, args.seed)
    R["static"] = {k: static_section(k, cfg, args.seed) for k in CARDS}
    R["kr"] = kr_section(cfg, args.seed)
    R["table2"] = {k: table2_section(k, cfg, args.seed) for k in CARDS}
    R["dyn"] = {k: dynamics_section(k, cfg, args.seed) for k in CARDS}
    log("figures")
    figs = figures(outdir, R)
    elapsed = time.perf_counter() - t0
    write_report(outdir, R, figs, args, elapsed)
    log(f"wrote {outdir / 'report.md'} and {len(figs)} figures in {elapsed:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
