"""Soak test: a long run of the batch SHAKF and of the FogDenoiser FMU.

    python benchmarks/soak.py                  # 24 h batch + 1 h FMU at 200 Hz
    python benchmarks/soak.py --hours 1 --fmu-hours 0.05   # quick look

Not part of the test run. The simulated paper_fog gyro (at a constant true rate)
is generated in chunks with :class:`gyrodenoise.simulator.SimStream` (so the
whole record never sits in memory) and filtered chunk by chunk with the
compiled batch loop, carrying the filter state across chunks (a split run
equals one run; tests/core/test_properties.py checks that). Per hour it prints:

* ``R_hat`` and ``q_hat`` (the SHAKF's measurement- and process-noise
  estimates) at the end of the hour, and R_hat relative to the true white-noise
  variance of the card (angle random walk + quantization: (N/60)^2 fs +
  2 (Q fs)^2, (deg/s)^2);
* the RMS error of the output against the true rate, and that of the raw;
* the gate's rejected samples and re-openings, the Eq. (32) restarts;
* the process's resident memory (VmRSS from /proc/self/status).

Then the same card runs through FogDenoiser.fmu (built into a temporary folder,
or ``--fmu-dir``), one FMI step per sample, checked against the batch core on
the same samples, with RSS per chunk. Final table: finite output, R_hat drift
(last hour / first full hour), memory growth after the first hour.
"""
import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

from gyrodenoise.core import kernels as K
from gyrodenoise.core.batch import run
from gyrodenoise.simulator import SimStream, load_card
from gyrodenoise.units import TERM_BY_SYMBOL


def rss_mb():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def white_variance(card):
    """Variance of the card's white rate noise (ARW + quantization), (deg/s)^2."""
    fs = card.sample_rate_hz
    var = 0.0
    if "angle_random_walk" in card.terms:
        var += (card.terms["angle_random_walk"]["N"] / TERM_BY_SYMBOL["N"].to_spec) ** 2 * fs
    if "quantization" in card.terms:
        var += 2.0 * (card.terms["quantization"]["Q"] * fs) ** 2
    return var


def soak_batch(card, hours, rate, seed, chunk_s, kw):
    fs = card.sample_rate_hz
    n_total = int(round(hours * 3600 * fs))
    chunk = int(round(chunk_s * fs))
    per_hour = int(round(3600 * fs))
    stream = SimStream(card, seed=seed)
    p = K.make_params(method="shakf", sample_rate_hz=fs, **kw)
    st = K.init_state(p)
    white = white_variance(card)
    print(f"batch SHAKF soak: {hours:g} h of '{card.name}' at {fs:g} Hz = {n_total} samples, "
          f"true rate {rate:g} deg/s, seed {seed}, chunks of {chunk_s:g} s")
    print(f"true white-noise variance (ARW + quantization): {white:.4e} (deg/s)^2")
    print(f"{'hour':>4} {'R_hat':>11} {'R/white':>8} {'q_hat':>11} {'rms out':>10} {'rms raw':>10} "
          f"{'mean out-true':>14} {'rejected':>9} {'reopened':>9} {'eq32':>7} {'RSS MB':>8} {'s':>6}")
    done = 0
    all_finite = True
    hour_rows = []
    acc_out = acc_raw = acc_bias = 0.0
    acc_n = 0
    t0 = time.perf_counter()
    skip = int(p[K.P_WARMUP])
    rss0 = rss_mb()
    while done < n_total:
        m = min(chunk, n_total - done, per_hour - done % per_hour)
        z = stream.run(m, true_rate_deg_s=np.full(m, rate))
        out, st = run(p, st, z)
        all_finite &= bool(np.all(np.isfinite(out)))
        lo = max(0, skip - done)
        e = out[lo:] - rate
        acc_out += float(np.sum(e * e))
        acc_bias += float(np.sum(e))
        acc_raw += float(np.sum((z[lo:] - rate) ** 2))
        acc_n += m - lo
        done += m
        if done % per_hour == 0 or done == n_total:
            row = {"hour": math.ceil(done / per_hour), "R": st[K.S_R], "q": st[K.S_Q],
                   "rms_out": math.sqrt(acc_out / max(acc_n, 1)),
                   "rms_raw": math.sqrt(acc_raw / max(acc_n, 1)),
                   "bias": acc_bias / max(acc_n, 1),
                   "rej": int(st[K.S_NREJ]), "reopen": int(st[K.S_NREOPEN]),
                   "eq32": int(st[K.S_NRESET]), "rss": rss_mb(), "t": time.perf_counter() - t0}
            hour_rows.append(row)
            print(f"{row['hour']:>4} {row['R']:11.4e} {row['R'] / white:8.3f} {row['q']:11.4e} "
                  f"{row['rms_out']:10.3e} {row['rms_raw']:10.3e} {row['bias']:14.3e} {row['rej']:>9} "
                  f"{row['reopen']:>9} {row['eq32']:>7} {row['rss']:8.1f} {row['t']:6.0f}", flush=True)
            acc_out = acc_raw = acc_bias = 0.0
            acc_n = 0
    return {"n": n_total, "finite": all_finite, "rows": hour_rows, "white": white, "rss0": rss0,
            "elapsed_s": time.perf_counter() - t0}


def soak_fmu(card, hours, rate, seed, fmu_dir, kw, chunk_s=300.0):
    from gyrodenoise import fmu as F
    fs = card.sample_rate_hz
    h = 1.0 / fs
    n_total = int(round(hours * 3600 * fs))
    chunk = int(round(chunk_s * fs))
    inst = F.FmuInstance(Path(fmu_dir) / "FogDenoiser.fmu", "soak")
    params = {"sample_period": h, "method": "shakf", "ar_order": 3}
    params.update(kw)
    stream = SimStream(card, seed=seed)
    p = K.make_params(method="shakf", sample_rate_hz=fs, **kw)
    st = K.init_state(p)
    print(f"\nFogDenoiser.fmu soak: {hours:g} h = {n_total} FMI steps, checked against the batch core")
    print(f"{'min':>6} {'steps/s':>9} {'max|fmu-core|':>14} {'R_hat':>11} {'n_rejected':>10} {'RSS MB':>8}")
    rows = []
    max_diff = 0.0
    finite = True
    try:
        inst.initialize(**params)
        step = F._stepper(inst, "raw_rate", "restart", "filtered_rate")
        done = 0
        t_all = 0.0
        while done < n_total:
            m = min(chunk, n_total - done)
            z = stream.run(m, true_rate_deg_s=np.full(m, rate))
            ref, st = run(p, st, z)
            y = np.empty(m)
            zl = z.tolist()
            t0 = time.perf_counter()
            for k in range(m):
                y[k] = step(zl[k], False, (done + k) * h, h)
            dt = time.perf_counter() - t0
            t_all += dt
            finite &= bool(np.all(np.isfinite(y)))
            d = float(np.max(np.abs(y - ref)))
            max_diff = max(max_diff, d)
            done += m
            row = {"min": done / fs / 60, "sps": m / dt, "diff": d, "R": inst.get("R_hat"),
                   "rej": inst.get("n_rejected"), "rss": rss_mb()}
            rows.append(row)
            print(f"{row['min']:6.1f} {row['sps']:9.0f} {d:14.3e} {row['R']:11.4e} {row['rej']:>10} "
                  f"{row['rss']:8.1f}", flush=True)
        errors = inst.errors()
    finally:
        inst.free()
    return {"n": n_total, "finite": finite, "max_diff": max_diff, "rows": rows, "errors": errors,
            "steps_per_s": n_total / t_all if t_all else float("nan")}


def main(argv=None):
    ap = argparse.ArgumentParser(description="Long soak of the batch SHAKF and the FogDenoiser FMU.")
    ap.add_argument("--hours", type=float, default=24.0, help="batch soak length, h (default 24)")
    ap.add_argument("--fmu-hours", type=float, default=1.0, help="FMU soak length, h (default 1; 0 = skip)")
    ap.add_argument("--rate", type=float, default=2.0, help="constant true rate, deg/s (default 2)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--card", default="paper_fog")
    ap.add_argument("--chunk-s", type=float, default=600.0, help="batch chunk length, s (default 600)")
    ap.add_argument("--outlier-sigma", type=float, default=5.0, help="gate k (default 5; 0 = off)")
    ap.add_argument("--fmu-dir", default=None, help="folder with FogDenoiser.fmu (default: build one)")
    args = ap.parse_args(argv)
    card = load_card(args.card)
    kw = {"outlier_sigma": args.outlier_sigma}
    b = soak_batch(card, args.hours, args.rate, args.seed, args.chunk_s, kw)
    f = None
    if args.fmu_hours > 0:
        with tempfile.TemporaryDirectory() as tmp:
            fmu_dir = args.fmu_dir
            if fmu_dir is None:
                from gyrodenoise import fmu as F
                F.build_all(tmp)
                fmu_dir = tmp
            f = soak_fmu(card, args.fmu_hours, args.rate, args.seed + 1, fmu_dir, kw)
    rows = b["rows"]
    first = rows[1] if len(rows) > 2 else rows[0]     # first full hour after the warm-up hour
    last = rows[-1]
    print("\n== soak figures")
    print(f"batch: {b['n']} samples ({args.hours:g} h at {card.sample_rate_hz:g} Hz) in {b['elapsed_s']:.0f} s "
          f"(simulation included); output finite: {b['finite']}")
    print(f"batch: R_hat last/first-full hour {last['R'] / first['R']:.3f}; R_hat/white: min "
          f"{min(r['R'] for r in rows) / b['white']:.3f}, max {max(r['R'] for r in rows) / b['white']:.3f}; "
          f"q_hat range {min(r['q'] for r in rows):.3e}..{max(r['q'] for r in rows):.3e} (deg/s)^2")
    print(f"batch: hourly RMS error of the output {min(r['rms_out'] for r in rows):.3e}.."
          f"{max(r['rms_out'] for r in rows):.3e} deg/s (raw {first['rms_raw']:.3e}); gate rejected "
          f"{last['rej']} samples, re-opened {last['reopen']} times; Eq. (32) restarts {last['eq32']}")
    print(f"batch: RSS at start {b['rss0']:.1f} MB, after hour 1 {rows[0]['rss']:.1f} MB, at end "
          f"{last['rss']:.1f} MB (growth after hour 1: {last['rss'] - rows[0]['rss']:+.1f} MB)")
    if f is not None:
        rr = f["rows"]
        print(f"FMU: {f['n']} steps at {f['steps_per_s']:.0f} steps/s; output finite: {f['finite']}; "
              f"max |FMU - batch core| {f['max_diff']:.2e} deg/s; FMU errors logged: {len(f['errors'])}")
        print(f"FMU: RSS after the first chunk {rr[0]['rss']:.1f} MB, at end {rr[-1]['rss']:.1f} MB "
              f"(growth {rr[-1]['rss'] - rr[0]['rss']:+.1f} MB)")
    ok = b["finite"] and (f is None or (f["finite"] and f["max_diff"] <= 1e-9 and not f["errors"]))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
