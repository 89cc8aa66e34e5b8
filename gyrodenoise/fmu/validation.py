"""The fmpy-scripted validation run: SimulatedFog -> FogDenoiser, one
communication step per sample, checked against the core's batch path
(``gyrodenoise fmu run``). No maths here: the FMUs and this module only call
the core."""

from __future__ import annotations

from pathlib import Path

from gyrodenoise.errors import InputError
from gyrodenoise.core.kernels import DEFAULT_METHOD
from gyrodenoise.fmu.build import FMUS
from gyrodenoise.fmu.host import FmuInstance, _stepper


def _resolve_card(card):
    from gyrodenoise.simulator import load_card
    return load_card(card)


def _fmu_paths(fmu_dir):
    d = Path(fmu_dir)
    paths = {n: d / f"{n}.fmu" for n in FMUS}
    missing = [str(p) for p in paths.values() if not p.is_file()]
    if missing:
        raise InputError(f"{', '.join(missing)}: not found (run 'gyrodenoise fmu build --out {d}')")
    return paths


def _restart_mask(n, fs, restart_at_s):
    import numpy as np
    rs = np.zeros(n, dtype=bool)
    if restart_at_s is not None:
        k = int(round(restart_at_s * fs))
        if not 0 < k < n:
            raise InputError(f"--restart-at {restart_at_s} s is outside the run (0, {n / fs} s)")
        rs[k] = True
    return rs


def _denoiser_params(method, ar_order, fs, extra=None):
    p = {"method": method, "ar_order": int(ar_order), "sample_period": 1.0 / fs}
    p.update(extra or {})
    return p


def compare_with_core(measured, filtered, true_rate, restarts, card, seed, method, ar_order,
                      denoiser_kw=None):
    """Check an FMU run against the core: the simulator's batch record for the
    same card and seed, and ``gyrodenoise.denoise`` on the FMU's own raw samples.
    Returns the differences and the Allan terms of raw, FMU-filtered and
    batch-filtered records with their reduction ratios."""
    import numpy as np
    from gyrodenoise.analysis.allan import allan
    from gyrodenoise.denoiser import denoise
    from gyrodenoise.simulator import simulate
    fs = card.sample_rate_hz
    n = len(measured)
    rec = simulate(card, n, seed=seed, true_rate_deg_s=true_rate, restarts=restarts)
    ref = denoise(measured, fs, method=method, ar_order=ar_order, restarts=restarts,
                     **(denoiser_kw or {}))
    d_meas = float(np.max(np.abs(np.asarray(measured) - rec.rate_deg_s)))
    d_filt = float(np.max(np.abs(np.asarray(filtered) - ref)))
    a_raw = allan(np.asarray(measured), fs).terms
    a_fmu = allan(np.asarray(filtered), fs).terms
    a_ref = allan(ref, fs).terms

    def ratios(a, b):
        return {k: (a[k] / b[k] if b[k] > 0 else None) for k in a}

    red_fmu, red_ref = ratios(a_raw, a_fmu), ratios(a_raw, a_ref)
    rel = max((abs(a_fmu[k] - a_ref[k]) / max(abs(a_ref[k]), 1e-300) for k in a_ref
               if a_ref[k] or a_fmu[k]), default=0.0)
    return {
        "max_abs_diff_measured_vs_simulate_deg_s": d_meas,
        "max_abs_diff_filtered_vs_denoise_deg_s": d_filt,
        "allan": {"raw": a_raw, "fmu_filtered": a_fmu, "batch_filtered": a_ref},
        "reduction_fmu": red_fmu, "reduction_batch": red_ref,
        "allan_max_rel_diff": float(rel),
    }


def validation_run(fmu_dir="build", duration_s=600.0, rate_deg_s=0.0, restart_at_s=None,
                   seed=0, card="paper_fog", method=DEFAULT_METHOD, ar_order=3, tol=1e-9,
                   keep_arrays=False, denoiser_kw=None):
    """SimulatedFog -> FogDenoiser through fmpy ``FMU2Slave``, one step per sample.

    SimulatedFog takes sample 0 at fmi2ExitInitializationMode (``true_rate`` and
    ``restart`` of sample 0 set before it); each step k: its ``measured_rate`` (sample
    k) goes into FogDenoiser's ``raw_rate`` (with the same ``restart``), which steps,
    then SimulatedFog gets sample k+1's ``true_rate`` and ``restart`` and steps (the
    sample at the end of its step). The result is compared with the core
    (:func:`compare_with_core`); ``ok`` is true when both outputs agree within
    ``tol`` and the Allan reductions agree.
    """
    import time
    import numpy as np
    card_obj = _resolve_card(card)
    fs = card_obj.sample_rate_hz
    h = 1.0 / fs
    n = int(round(duration_s * fs))
    if n < 2:
        raise InputError(f"--duration {duration_s} s gives fewer than 2 samples at {fs} Hz")
    paths = _fmu_paths(fmu_dir)
    restarts = _restart_mask(n, fs, restart_at_s)
    truth = np.full(n, float(rate_deg_s))
    fog = FmuInstance(paths["SimulatedFog"], "fog")
    den = FmuInstance(paths["FogDenoiser"], "denoiser")
    try:
        tl, rl = truth.tolist(), restarts.tolist()
        # sample 0 is taken at fmi2ExitInitializationMode from the inputs set before it
        fog.initialize(card=card_obj.text, seed=int(seed), true_rate=tl[0], restart=rl[0])
        den.initialize(**_denoiser_params(method, ar_order, fs, denoiser_kw))
        fog_step = _stepper(fog, "true_rate", "restart", "measured_rate")
        den_step = _stepper(den, "raw_rate", "restart", "filtered_rate")
        measured = np.empty(n)
        filtered = np.empty(n)
        t0 = time.perf_counter()
        z = fog.get("measured_rate")
        for k in range(n):
            t = k * h
            measured[k] = z
            filtered[k] = den_step(z, rl[k], t, h)
            if k + 1 < n:
                # the sensor's step from t_k produces sample k+1 (at its end) from truth[k+1]
                z = fog_step(tl[k + 1], rl[k + 1], t, h)
        elapsed = time.perf_counter() - t0
        converged = den.get("converged")
        readouts = {name: den.get(name) for name in
                    [f"phi_{i}" for i in range(1, int(ar_order) + 1)] + ["c", "R_hat", "innovation"]}
        errors = fog.errors() + den.errors()
    finally:
        fog.free()
        den.free()
    res = {"case": {"duration_s": n / fs, "n_samples": n, "sample_rate_hz": fs,
                    "true_rate_deg_s": float(rate_deg_s), "restart_at_s": restart_at_s,
                    "seed": int(seed), "card": card_obj.name, "method": method,
                    "ar_order": int(ar_order)},
           "elapsed_s": elapsed, "two_fmu_steps_per_s": n / elapsed,
           "converged_at_end": bool(converged), "final_readouts": readouts,
           "fmu_errors": [m[2] for m in errors]}
    res.update(compare_with_core(measured, filtered, truth, restarts, card_obj, seed, method,
                                 ar_order, denoiser_kw))
    res["tolerance_deg_s"] = tol
    res["ok"] = bool(res["max_abs_diff_measured_vs_simulate_deg_s"] <= tol
                     and res["max_abs_diff_filtered_vs_denoise_deg_s"] <= tol
                     and res["allan_max_rel_diff"] <= 1e-6 and not errors)
    if keep_arrays:
        res["arrays"] = {"measured": measured, "filtered": filtered, "true_rate": truth,
                         "restarts": restarts}
    return res
