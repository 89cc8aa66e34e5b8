"""The text report and the plot of a gap run."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from gyrodenoise.modelgap.settings import COMPONENTS, GAP_METRIC, N_BLOCKS

if TYPE_CHECKING:
    from gyrodenoise.modelgap.curve import AllanCurve
    from gyrodenoise.modelgap.metric import Layout, Signature
    from gyrodenoise.modelgap.workflow import GapResult


# ------------------------------------------------------------------ report and plot
def format_report(res: GapResult, source: str = "MEASURED") -> str:
    """A short text report (a minute to read)."""
    lay, _ = _evidence(res)
    out = [f"gyrodenoise gap: {source} ({lay.n} samples, {lay.fs:g} Hz, {lay.n / lay.fs / 60:.1f} min), "
           f"{len(res.seeds)} simulated seeds per card, engine {res.engine}",
           f"gap metric: {GAP_METRIC}",
           f"scatter threshold (1.5 x max leave-one-out gap of the simulations): {res.threshold:.3g}",
           ""]
    for i, it in enumerate(res.iterations):
        step = [e for e in res.effects_added if e.get("iteration", 0) == i - 1]
        label = ("input card" if i == 0 else "after " + describe_edits(step) if step else
                 "the same card compared again (the comparison's stop bands changed: see the notes)")
        comp = ", ".join(f"{c} {it['components'][c]:.3g}" for c in COMPONENTS)
        out.append(f"[{i}] {label}: gap {it['card_gap']:.3g}  ({comp})")
        w = it["where"]
        bits = []
        if w["allan_tau_s"]:
            bits.append("Allan deviation at tau " + ", ".join(_tau_range(a, b) for a, b in w["allan_tau_s"])
                        + (" (measured above)" if all(s > 0 for s in w["allan_sign"]) else
                           " (measured below)" if all(s < 0 for s in w["allan_sign"]) else ""))
        if w["psd_lines"]:
            bits.append("PSD line(s) at " + ", ".join(f"{d['frequency_hz']:.4g} Hz" for d in w["psd_lines"][:3]))
        elif w["psd_bands_hz"]:
            bits.append(f"PSD in {len(w['psd_bands_hz'])} band(s) {w['psd_bands_hz'][0][0]:.3g}-"
                        f"{w['psd_bands_hz'][-1][1]:.3g} Hz")
        if abs(w["mean_z"]) > 3:
            bits.append(f"record mean (z = {w['mean_z']:.1f})")
        if w["trend_blocks"]:
            bits.append(f"block means {w['trend_blocks'][:6]}{'...' if len(w['trend_blocks']) > 6 else ''} "
                        f"of {N_BLOCKS} (trend)")
        out.append("    disagrees (|z| > 3): " + ("; ".join(bits) if bits else "nowhere"))
        if it["candidates"]:
            tried = ", ".join(f"{c['name']}{'+' + '+'.join(w['name'] for w in c['with']) if c['with'] else ''} "
                              f"{_short(c['params'])} -> {c['gap']:.3g} [{c['score']:.3g}]"
                              for c in it["candidates"] if c["gap"] is not None and c["score"] is not None)
            if it.get("deterministic_first"):
                out.append("    record mean offset >> block-mean wander: a deterministic bias, explained first")
            out.append(f"    candidates (gap after [choice score; this card {it['robust_gap']:.3g}]): {tried}")
        if it.get("pairs"):
            tried = ", ".join(f"{c['name']} + {' + '.join(w['name'] for w in c['with'])} -> {c['gap']:.3g} "
                              f"[{c['score']:.3g}]" for c in it["pairs"] if c["gap"] is not None)
            out.append(f"    pairs (no single effect shrank the gap enough): {tried}")
        for e in res.effects_added:
            if e.get("iteration") == i:
                out.append(f"    => {'re-fit' if e['refit'] else 'add'} {e['name']} {_short(e['params'])}")
        if it.get("stop"):
            out.append(f"    stop: {it['stop']}")
    for m_ in res.named:
        out.append(f"named: {m_}")
    for m_ in res.limitations:
        out.append(f"limitation: {m_}")
    out.append("")
    if res.effects_added:
        verdict = "added (in the order found; the last entry of a term is its value in the card): " + \
            ", ".join(f"{e['name']}{' (re-fit)' if e['refit'] else ''}" for e in res.effects_added)
        if not res.within_scatter:
            verdict += f"; {_not_within(res)} ({res.iterations[-1].get('stop')})"
    elif res.within_scatter:
        verdict = "nothing missing (within the simulations' scatter)"
    else:
        verdict = (f"nothing added: {res.iterations[-1].get('stop')}, but {_not_within(res)}: "
                   f"the card does not explain the record")
    out.append(f"gap {res.gap_before:.3g} -> {res.gap_after:.3g}; " + verdict)
    return "\n".join(out)


def _tau_range(a: float, b: float) -> str:
    """'0.01 s' for one Allan point, '0.04-0.08 s' for a run of them."""
    return f"{a:.3g} s" if f"{a:.3g}" == f"{b:.3g}" else f"{a:.3g}-{b:.3g} s"


def _not_within(res: GapResult) -> str:
    """Why the final card is not within the scatter: the gap above the threshold, or (the gap
    below it) the components above their own thresholds, named with both numbers."""
    if not res.gap_after <= res.threshold:
        return f"still above the scatter threshold {res.threshold:.3g}"
    comp = res.iterations[-1].get("components", {})
    over = [f"{c} {comp[c]:.3g} > {res.component_threshold[c]:.3g}" for c in COMPONENTS
            if c in comp and c in res.component_threshold and not comp[c] <= res.component_threshold[c]]
    return (f"the gap is below the scatter threshold ({res.gap_after:.3g} <= {res.threshold:.3g}) but not "
            f"within the scatter: component(s) above their own threshold ({', '.join(over) or 'none'})")


def _evidence(res: GapResult) -> tuple[Layout, Signature]:
    """The layout and the measured signatures of a result of `gap`."""
    if res.layout is None or res.measured is None:
        raise ValueError("a GapResult without its layout and measured signatures (not from gap)")
    return res.layout, res.measured


def describe_edits(effects: Iterable[Mapping[str, Any]]) -> str:
    """'added A, B; re-fitted C; removed D' for entries of ``GapResult.effects_added`` (a
    term whose re-fit is zero is removed; a name is listed once per kind of edit)."""
    kinds: dict[str, list[str]] = {"added": [], "re-fitted": [], "removed": []}
    for e in effects:
        kind = "removed" if e.get("params") is None else "re-fitted" if e.get("refit") else "added"
        if e["name"] not in kinds[kind]:
            kinds[kind].append(e["name"])
    return "; ".join(f"{k} {', '.join(v)}" for k, v in kinds.items() if v) or "nothing"


def _short(params: Mapping[str, float] | None) -> str:
    if params is None:
        return "(removed)"
    return "{" + ", ".join(f"{k}={v:.4g}" for k, v in params.items()) + "}"


def plot_gap(res: GapResult, path: str | os.PathLike[str], title: str = "") -> str | os.PathLike[str]:
    """PNG: measured Allan deviation vs the simulated band (mean +- 1 sigma of one
    simulation) for the input card and after each added effect; a PSD panel when a
    sinusoid was added."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    lay, sig = _evidence(res)
    spectral = any(e["name"] == "sinusoid" for e in res.effects_added)
    fig, axes = plt.subplots(1, 2 if spectral else 1, figsize=(13 if spectral else 7.5, 5.5), squeeze=False)
    ax = axes[0, 0]
    tau = lay.tau_s
    ad_m = np.exp(sig["allan"]) * 3600.0
    ax.errorbar(tau, ad_m, yerr=ad_m * sig["allan_rel_err"], fmt="ko", ms=3, label="measured (1 sigma)", zorder=5)
    cmap = plt.get_cmap("viridis")
    n_it = len(res.iterations)
    for i, it in enumerate(res.iterations):
        ref = it["_ref"]
        mu, sd = ref.mean["allan"], ref.sigma["allan"]
        col = "tab:red" if i == 0 else cmap(0.15 + 0.7 * i / max(n_it - 1, 1))
        added = [e["name"] for e in res.effects_added if e.get("iteration", 0) < i]
        label = "input card" if i == 0 else (f"+ {len(added)} changes" if len(added) > 3 else
                                             "+ " + " + ".join(added))
        ax.fill_between(tau, np.exp(mu - sd) * 3600, np.exp(mu + sd) * 3600, color=col, alpha=0.25)
        ax.loglog(tau, np.exp(mu) * 3600, "-", color=col, label=f"{label} (gap {it['card_gap']:.3g})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    if res.stop_bands:
        title = (title + "\n" if title else "") + "record and simulations through the band-stop " + ", ".join(
            f"{lo:.3g}-{hi:.3g} Hz" for lo, hi, *_ in res.stop_bands)
    _allan_axes(ax, title or "measured vs simulated (band: 1 sigma of one simulation)")
    if spectral:
        ax = axes[0, 1]
        f = lay.freq_hz
        ax.loglog(f, sig["psd_bins"] * 3600.0 ** 2, color="k", lw=0.6, label="measured", zorder=3)
        for i in (0, n_it - 1):
            ref = res.iterations[i]["_ref"]
            col = "tab:red" if i == 0 else cmap(0.85)
            ax.loglog(f, ref.mean["psd_bins"] * 3600.0 ** 2, color=col, lw=1.0,
                      label="input card (mean of seeds)" if i == 0 else "final card (mean of seeds)")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("PSD ((deg/h)^2/Hz), Welch")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    return _save(fig, path)


def _allan_axes(ax: Any, title: str) -> None:
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel("Allan deviation (deg/h)")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)


def _save(fig: Any, path: str | os.PathLike[str]) -> str | os.PathLike[str]:
    import matplotlib.pyplot as plt
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_curve(curve: AllanCurve, model_deg_s: np.ndarray, simulated_deg_s: np.ndarray, path: str | os.PathLike[str],
               title: str = "") -> str | os.PathLike[str]:
    """PNG: a published Allan curve with its bounds, the fitted card's exact curve and
    its simulated curve (mean of the seeds), in deg/h."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    t = curve.tau_s
    lo = np.where(np.isfinite(curve.lo_deg_s), curve.lo_deg_s, curve.adev_deg_s * 1e-3) * 3600
    ax.fill_between(t, lo, curve.hi_deg_s * 3600, color="0.8", label="published 95 % bounds")
    ax.loglog(t, curve.adev_deg_s * 3600, "ko", ms=3, label="published ADEV")
    ax.loglog(t, model_deg_s * 3600, "-", color="tab:blue", label="fitted card (exact)")
    ax.loglog(t, simulated_deg_s * 3600, "--", color="tab:red", label="fitted card (simulated, mean of seeds)")
    _allan_axes(ax, title or curve.label)
    return _save(fig, path)
