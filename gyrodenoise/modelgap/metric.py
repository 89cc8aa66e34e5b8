"""Noise signatures of a record and the gap metric (z-scores against seeded simulations)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from gyrodenoise.analysis.spectrum import nperseg_for_length, segment_count, welch_psd
from gyrodenoise.modelgap.settings import (
    BANDS_PER_DECADE,
    COMPONENT_FLOOR,
    COMPONENTS,
    MIN_CLUSTERS,
    N_BLOCKS,
)

#: the signatures of one record: component -> array (and ``avar``, ``psd_bins``, ``std``, ...)
Signature: TypeAlias = "dict[str, Any]"


# ------------------------------------------------------------------ signatures
@dataclass
class Layout:
    """Where the signatures are evaluated (shared by the record and its simulations)."""
    n: int
    fs: float
    m: np.ndarray
    nperseg: int
    band_edges: np.ndarray      # indices into the Welch bins (bins 1..), len n_bands + 1

    @classmethod
    def for_record(cls, n: int, fs: float) -> Layout:
        """The layout of a record of ``n`` samples at ``fs`` Hz."""
        m_max = n // MIN_CLUSTERS
        m = 2 ** np.arange(0, int(math.floor(math.log2(max(m_max, 1)))) + 1)
        nper = nperseg_for_length(n)
        n_bins = nper // 2          # bins 1..nper/2 (DC dropped)
        f = np.arange(1, n_bins + 1) * fs / nper
        edges_f = np.logspace(math.log10(f[0]), math.log10(f[-1]) + 1e-9,
                              int(math.ceil(math.log10(f[-1] / f[0]) * BANDS_PER_DECADE)) + 1)
        idx = np.unique(np.searchsorted(f, edges_f))
        idx[-1] = n_bins
        return cls(n=n, fs=float(fs), m=m.astype(np.int64), nperseg=nper, band_edges=idx)

    @property
    def tau_s(self) -> np.ndarray:
        return self.m / self.fs

    @property
    def freq_hz(self) -> np.ndarray:
        return np.arange(1, self.nperseg // 2 + 1) * self.fs / self.nperseg

    @property
    def n_segments(self) -> int:
        return max(1, segment_count([self.n], self.nperseg))


def signature(y: npt.ArrayLike, layout: Layout) -> Signature:
    """The five signatures of a record (see the module docstring)."""
    from gyrodenoise.analysis.allan import adev
    y = np.asarray(y, dtype=float)
    tau, ad, err, _ = adev(y, layout.fs, m=layout.m)
    psd = welch_psd(y, layout.fs, layout.nperseg)[1]
    if psd is None:
        raise ValueError(f"a record of {len(y)} samples holds no Welch segment of {layout.nperseg}")
    p = psd[1:layout.nperseg // 2 + 1]
    e = layout.band_edges
    band = np.array([p[e[i]:e[i + 1]].mean() for i in range(len(e) - 1)])
    nb = layout.n // N_BLOCKS
    blocks = y[:nb * N_BLOCKS].reshape(N_BLOCKS, nb).mean(axis=1)
    mean = float(y.mean())
    return {"avar": ad * ad, "allan": np.log(ad), "allan_rel_err": err / ad, "psd_bins": p,
            "psd": np.log(band), "line": np.log(p), "mean": np.array([mean]),
            "trend": blocks - mean, "std": float(y.std())}


def _floors(sig: Signature, layout: Layout) -> dict[str, np.ndarray]:
    """Analytic 1-sigma of one record's signatures (lower bounds for the scatter)."""
    nbins = np.diff(layout.band_edges).astype(float)
    k_eff = 1.8 * layout.n_segments     # Welch, Hann, 50 % overlap: ~1.8 K equivalent segments
    nb = layout.n // N_BLOCKS
    return {"allan": sig["allan_rel_err"],
            "psd": 1.0 / np.sqrt(k_eff * nbins),
            "line": np.full(layout.nperseg // 2, 1.0 / math.sqrt(k_eff)),
            "mean": np.array([sig["std"] / math.sqrt(layout.n)]),
            "trend": np.full(N_BLOCKS, sig["std"] / math.sqrt(nb))}


@dataclass
class Reference:
    """Mean and scatter of the signatures of S simulated records."""
    layout: Layout
    sigs: list[Signature]
    mean: dict[str, np.ndarray] = field(init=False)
    sigma: dict[str, np.ndarray] = field(init=False)

    def __post_init__(self) -> None:
        S = len(self.sigs)
        self.mean, self.sigma = {}, {}
        fl = [_floors(s, self.layout) for s in self.sigs]
        for c in COMPONENTS + ("avar",):
            arr = np.array([s[c] for s in self.sigs])
            self.mean[c] = arr.mean(axis=0)
            if c == "avar":
                continue
            sd = arr.std(axis=0, ddof=1) if S > 1 else np.zeros_like(arr[0])
            if c == "trend":   # blocks are exchangeable: pool their scatter (S x 16 values, not S)
                sd = np.full_like(sd, math.sqrt(float(np.mean(sd ** 2))))
            floor = np.mean([f[c] for f in fl], axis=0)
            self.sigma[c] = np.maximum(sd, floor) * math.sqrt(1.0 + 1.0 / S)
        self.mean["psd_bins"] = np.mean([s["psd_bins"] for s in self.sigs], axis=0)


def zscores(sig: Signature, ref: Reference) -> dict[str, np.ndarray]:
    """z per component of a measured signature against a reference."""
    return {c: (sig[c] - ref.mean[c]) / ref.sigma[c] for c in COMPONENTS}


def gap_components(z: Mapping[str, np.ndarray]) -> dict[str, float]:
    """The five components of the gap (each ~1 when consistent)."""
    nl = len(z["line"])
    return {"allan": float(np.mean(z["allan"] ** 2)),
            "psd": float(np.mean(z["psd"] ** 2)),
            "line": float(np.max(z["line"] ** 2) / (2.0 * math.log(max(nl, 3)))),
            "mean": float(z["mean"][0] ** 2),
            "trend": float(np.mean(z["trend"] ** 2))}


def gap_value(comp: Mapping[str, float]) -> float:
    """The gap: the mean of the five components."""
    return float(np.mean([comp[c] for c in COMPONENTS]))


def loo_gaps(ref: Reference) -> list[tuple[float, dict[str, float]]]:
    """(gap, components) of each simulated record against the other simulations."""
    out: list[tuple[float, dict[str, float]]] = []
    S = len(ref.sigs)
    if S < 3:
        return out
    for j in range(S):
        r = Reference(ref.layout, [s for i, s in enumerate(ref.sigs) if i != j])
        comp = gap_components(zscores(ref.sigs[j], r))
        out.append((gap_value(comp), comp))
    return out


def where_disagree(z: Mapping[str, np.ndarray], layout: Layout, limit: float = 3.0) -> dict[str, Any]:
    """Tau ranges, PSD bands and blocks where |z| > limit, and PSD lines (bins whose
    own contribution to the line component exceeds COMPONENT_FLOOR) as plain dicts."""
    def ranges(x: np.ndarray, mask: np.ndarray) -> list[list[float]]:
        out: list[list[float]] = []
        start = None
        for i, flag in enumerate(list(mask) + [False]):
            if flag and start is None:
                start = i
            if not flag and start is not None:
                out.append([float(x[start]), float(x[i - 1])])
                start = None
        return out
    f = layout.freq_hz
    e = layout.band_edges
    band_lo = f[e[:-1]]
    band_hi = f[np.minimum(e[1:], len(f)) - 1]
    za = z["allan"]
    zl = z["line"]
    top = np.argsort(-zl)[:5]
    lines = [{"frequency_hz": float(f[i]), "z": float(zl[i])} for i in top
             if zl[i] > 0 and zl[i] ** 2 / (2.0 * math.log(len(zl))) > COMPONENT_FLOOR]
    psd_bands = [[float(band_lo[i]), float(band_hi[i]), float(z["psd"][i])]
                 for i in np.flatnonzero(np.abs(z["psd"]) > limit)]
    return {"allan_tau_s": ranges(layout.tau_s, np.abs(za) > limit),
            "allan_sign": [int(np.sign(za[i])) for i in np.flatnonzero(np.abs(za) > limit)],
            "psd_bands_hz": psd_bands, "psd_lines": lines,
            "mean_z": float(z["mean"][0]),
            "trend_blocks": [int(i) for i in np.flatnonzero(np.abs(z["trend"]) > limit)]}
