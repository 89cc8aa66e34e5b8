"""PNG figures (matplotlib, Agg): Allan curves, series with zoom, AR parameter
convergence after a restart (paper Figs 4-5), residual PSD (Fig 2)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from gyrodenoise.analysis.allan import AllanResult
    from gyrodenoise.simulator import ModelCard, Record

PathLike = str | os.PathLike[str]

COLORS = {"raw": "tab:blue", "ar_fit": "tab:gray", "kf": "tab:green", "shakf": "tab:red", "motion": "tab:purple"}
LABELS = {"raw": "raw", "ar_fit": "AR-fitted sequence", "kf": "KF", "shakf": "modified SHAKF", "motion": "motion"}


def _plt() -> Any:
    from gyrodenoise._extras import require
    require("report", "matplotlib", what="the figures (or --no-plots)")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(plt: Any, fig: Any, path: PathLike) -> None:
    """Check that every panel shows data, then write the PNG; the figure is closed either way."""
    try:
        check_drawn(fig, Path(path).name)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
    finally:
        plt.close(fig)


def allan_figure(results: Mapping[str, AllanResult], path: PathLike, title: str = "") -> PathLike:
    """Allan deviation with 1-sigma bars and the fitted Eq. (40) per series."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    for name, r in results.items():
        col = COLORS.get(name)
        ax.errorbar(r.tau_s, r.adev_deg_h, yerr=r.adev_err_deg_h, fmt="o", ms=3, color=col,
                    label=LABELS.get(name, name), alpha=0.8)
        ax.loglog(r.tau_s, r.model_adev_deg_h(), "--", color=col, lw=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel("Allan deviation (deg/h)")
    ax.set_title(title or "Allan deviation; dashed: five-term fit of Eq. (40)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    _save(plt, fig, path)
    return path


def series_figure(time_s: np.ndarray, series: Mapping[str, np.ndarray], path: PathLike, zoom_s: float = 2.0,
                  truth: np.ndarray | None = None) -> PathLike:
    """Raw vs filtered over the whole record and a zoom of ``zoom_s`` seconds."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6.5))
    step = max(1, len(time_s) // 20000)
    for name, y in series.items():
        a1.plot(time_s[::step] / 60.0, y[::step], lw=0.6, color=COLORS.get(name), label=LABELS.get(name, name))
    a1.set_xlabel("time (min)")
    a1.set_ylabel("rate (deg/s)")
    a1.legend(loc="upper right")
    a1.set_title("raw and filtered rate (decimated for display)")
    mid = len(time_s) // 2
    n = int(zoom_s / (time_s[1] - time_s[0]))
    sl = slice(mid, mid + n)
    for name, y in series.items():
        a2.plot(time_s[sl], y[sl], lw=0.8, color=COLORS.get(name), label=LABELS.get(name, name))
    if truth is not None:
        a2.plot(time_s[sl], truth[sl], "k--", lw=1, label="true rate")
    a2.set_xlabel("time (s)")
    a2.set_ylabel("rate (deg/s)")
    a2.set_title(f"zoom: {zoom_s:g} s at mid-record")
    a2.legend(loc="upper right")
    _save(plt, fig, path)
    return path


def convergence_figure(time_s: np.ndarray, theta: np.ndarray, path: PathLike,
                       warmup_s: float | None = None) -> PathLike:
    """phi_1..phi_n and c of the online RLS after a restart (paper Figs 4-5)."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    n = theta.shape[1] - 1
    for j in range(n):
        a1.plot(time_s, theta[:, j], lw=1, label=f"phi_{j + 1}")
    a1.set_ylabel("AR parameter")
    a1.legend()
    a1.set_title("online RLS identification after a restart (paper Fig. 4)")
    a2.plot(time_s, theta[:, n], color="k", lw=1)
    a2.set_ylabel("c (deg/s)")
    a2.set_xlabel("time since restart (s)")
    a2.set_title("constant term c (paper Fig. 5)")
    if warmup_s:
        for a in (a1, a2):
            a.axvline(warmup_s, color="gray", ls=":", lw=1)
    _save(plt, fig, path)
    return path


def octave_band_spread(f_hz: npt.ArrayLike, pxx: npt.ArrayLike) -> float:
    """Ratio of the highest to the lowest mean PSD over octave bands from 8 frequency
    bins up to (not including) Nyquist: 1 for white noise, up to the estimate's
    scatter (each band averages at least 8 bins)."""
    f_hz, pxx = np.asarray(f_hz)[1:-1], np.asarray(pxx)[1:-1]
    lo = 8.0 * f_hz[0]
    levels = []
    while lo < f_hz[-1]:
        band = (f_hz >= lo) & (f_hz < 2.0 * lo)
        levels.append(pxx[band].mean())
        lo *= 2.0
    return float(max(levels) / min(levels))


def psd_figure(residual: np.ndarray, sample_rate_hz: float, path: PathLike) -> PathLike:
    """Welch PSD of the AR one-step prediction residual (paper Fig. 2)."""
    from scipy.signal import welch
    plt = _plt()
    f, pxx = welch(residual, fs=sample_rate_hz, nperseg=min(len(residual), 8192))
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    ax.loglog(f[1:], pxx[1:] * 3600.0 ** 2, lw=0.8)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("PSD ((deg/h)^2/Hz)")
    ax.set_title(f"PSD of the AR fitting residual (paper Fig. 2): octave-band levels span "
                 f"{octave_band_spread(f, pxx):.2g}x (white noise: ~1x)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    from matplotlib.ticker import LogLocator
    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    _save(plt, fig, path)
    return path


def demo_figures(card: ModelCard, rec: Record, res: Mapping[str, Any], outdir: PathLike, ar_order: int = 3,
                 seed: int = 0, **kw: Any) -> list[PathLike]:
    """All demo figures into ``outdir``; returns their paths.

    The AR figures (Figs 2, 4, 5) show the paper's model, identified by the
    modified SHAKF's RLS (`gyrodenoise.analysis.experiments.ar_identification`), with
    the same filter options ``kw`` as the tables. Every figure is checked before it
    is written (`check_drawn`): an empty figure is an error, not a PNG.
    """
    from gyrodenoise.analysis.experiments import ar_identification
    outdir = Path(outdir)
    figs = [allan_figure(res["_allan"], outdir / "allan.png",
                         f"Allan deviation, {card.name} (dashed: fit of Eq. 40)")]
    s = res["_series"]
    figs.append(series_figure(rec.time_s, {k: s[k] for k in ("raw", "kf", "shakf", "motion")}, outdir / "series.png"))
    fs = rec.sample_rate_hz
    theta, residual_deg_s, warmup_s = ar_identification(rec.rate_deg_s, fs, ar_order, **kw)
    figs.append(convergence_figure(rec.time_s[:theta.shape[0]], theta, outdir / "ar_convergence.png",
                                   warmup_s=warmup_s))
    figs.append(psd_figure(residual_deg_s, fs, outdir / "residual_psd.png"))
    return figs


class EmptyFigureError(RuntimeError):
    """A figure would show nothing (no finite, varying curve in some panel)."""


def check_drawn(fig: Any, name: str) -> None:
    """Raise `EmptyFigureError` unless every panel of ``fig`` shows data.

    A panel shows data when at least one of its lines has two or more finite
    points (positive ones on a logarithmic y axis) whose y values are not all
    equal: a flat line at 0 (an AR model that was never identified) or a log
    plot of zeros is empty.
    """
    for i, ax in enumerate(fig.axes):
        log_y = ax.get_yscale() == "log"
        shown = False
        for line in ax.get_lines():
            y = np.asarray(line.get_ydata(), dtype=float)
            y = y[np.isfinite(y)]
            if log_y:
                y = y[y > 0]
            if y.size >= 2 and np.ptp(y) > 0:
                shown = True
                break
        if not shown:
            title = ax.get_title() or f"panel {i + 1}"
            raise EmptyFigureError(f"{name}: '{title}' shows no data (every curve empty, flat or non-positive)")
