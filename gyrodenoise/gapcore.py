"""The model-gap workflow: what is a model card missing to behave like a real gyro?

Given a measured rate record and a model card, the workflow

1. simulates the card ``S`` times (seeds 1..S) at the record's sample rate and
   length, through ``SimulatedFog.fmu`` (engine ``"fmu"``) or the core simulator
   (engine ``"native"``; the two are bit-identical, see ``tests/test_fmu.py``);
2. compares five noise *signatures* of the record with the simulations
   (:func:`signature`, :func:`zscores`, :data:`GAP_METRIC`);
3. proposes candidate effects from the vocabulary of the spec, fits each
   candidate's parameters to the record (:func:`propose`), screens each by
   re-simulation and keeps the one that shrinks the gap most for its number of
   parameters;
4. adds it to the card text (:func:`edit_card`) and repeats until the gap is
   within the simulations' own scatter (leave-one-out threshold) or nothing
   improves it.

Signatures and the gap metric
-----------------------------
For one record ``y`` (deg/s):

* ``allan``: log overlapping Allan deviation at octave cluster sizes
  ``m = 1, 2, 4, ...`` with at least 16 clusters;
* ``psd``: log Welch PSD (Hann, 50 % overlap) averaged in log-spaced bands,
  10 per decade;
* ``line``: the Welch PSD bin by bin (for spectral lines);
* ``mean``: the record mean;
* ``trend``: the means of 16 equal blocks minus the record mean.

Each measured quantity gets a score ``z = (measured - mean of the S
simulations) / (sigma sqrt(1 + 1/S))``, with ``sigma`` the scatter of one
simulated record: the larger of the seeds' standard deviation and an analytic
floor (Allan: IEEE 952 C.1 error; PSD: chi-square of the Welch average; means:
white-noise standard error). The gap is the average of five components, each
about 1 when the card explains the record: mean z^2 over Allan taus, mean z^2
over PSD bands, max z^2 over PSD bins divided by 2 ln(number of bins), z^2 of
the mean, mean z^2 over the block means.

Choosing a candidate
--------------------
The gap measures how far the record is from a card; choosing WHICH effect to
add uses a different number, the candidate's *score*: the gap with every
point's ``z^2`` capped at 25 (:func:`robust_gap`; points that neither the card
nor any candidate brings within ``|z| <= 5`` count 0), plus the Gaussian
log-likelihood price of a wider simulated scatter that the record does not ask
for (:func:`widening`: per point ``ln(sigma_new^2 / sigma_old^2) - ln(max(z^2,
1))`` when positive), times ``1 + 0.05``
per parameter. A candidate is accepted when its score is below 0.8 times the
current card's capped gap. Before any stochastic candidate, a record mean far
off the card's (``|z| > 3`` and more than 5 times the rms wander of the block
means, :func:`deterministic_offset`) is explained by a constant bias. Why: on a
long real record (docs/GAP.md, ADIS16405) the plain gap rewarded a large rate
random walk, whose wider scatter shrank the z of a deterministic mean offset,
and was dominated by short-tau points (a sensor's internal low-pass filter)
that no term can fix.

Analytic Allan variances used to fit candidates (avar adds for independent
terms): Eq. (40) of the paper for Q, N, B, K, R, and for a first-order
Gauss-Markov process of stationary std ``sigma`` and correlation time ``T``
(IEEE Std 952-1997, Annex C; El-Sheimy et al. 2008)::

    avar(tau) = 2 sigma^2 T / tau * (1 - T / (2 tau) * (3 - 4 exp(-tau/T) + exp(-2 tau/T)))

which tends to ``2 sigma^2 tau / (3 T)`` for ``tau << T`` and to ``2 sigma^2 T / tau``
for ``tau >> T`` and peaks near ``tau = 1.89 T``.
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

GAP_METRIC = ("gap = average of 5 components, each ~1 when the card explains the record: "
              "mean z^2 over octave-spaced Allan deviations (log), mean z^2 over log-spaced Welch PSD "
              "bands (log), max z^2 over PSD bins / 2 ln(n_bins), z^2 of the record mean, mean z^2 over "
              "16 block means minus the record mean; z = (measured - mean of S simulations of the card) "
              "/ (scatter of one simulation * sqrt(1 + 1/S))")

COMPONENTS = ("allan", "psd", "line", "mean", "trend")
N_BLOCKS = 16
MIN_CLUSTERS = 16
BANDS_PER_DECADE = 10
MIN_SAMPLES = 4096
COMPONENT_FLOOR = 3.0         # a component above max(3, 1.5 x its leave-one-out max) is a disagreement
# parameters per candidate (for the penalty)
N_PARAMS = {"quantization": 1, "angle_random_walk": 1, "bias_instability": 1, "rate_random_walk": 1,
            "rate_ramp": 1, "constant_bias": 1, "turn_on_transient": 2, "gauss_markov": 2,
            "sinusoid": 3}
PENALTY_PER_PARAM = 0.05      # score = gap * (1 + PENALTY_PER_PARAM * n_params)
MIN_IMPROVEMENT = 0.8         # accept a candidate only when it brings the gap below 0.8x
Z2_CAP = 25.0                 # selection: each point's z^2 counts at most 25 (|z| = 5)
OFFSET_RATIO = 5.0            # mean offset > 5x the block-mean wander (and |z| > 3): a deterministic bias
WIDEN_COMPONENTS = ("allan", "psd", "mean", "trend")   # scatter-widening penalty (log-likelihood term)
ALLAN_SHAPES = ("quantization", "angle_random_walk", "bias_instability", "rate_random_walk")
# card field, s-based value -> card units
CARD_FIELD = {"quantization": ("Q", 1.0), "angle_random_walk": ("N", 60.0),
              "bias_instability": ("B", 3600.0), "rate_random_walk": ("K", 3600.0 ** 1.5),
              "rate_ramp": ("R", 3600.0 ** 2)}
BI_FACTOR = 2.0 * math.log(2.0) / math.pi


def _log(msg, quiet=False):
    if not quiet:
        print(msg, file=sys.stderr, flush=True)


# ------------------------------------------------------------------ signatures
def welch_nperseg(n):
    """Welch segment length: a power of two giving at least ~32 segments, <= 2^14."""
    return int(2 ** min(14, max(6, math.floor(math.log2(max(n / 32.0, 64))))))


@dataclass
class Layout:
    """Where the signatures are evaluated (shared by the record and its simulations)."""
    n: int
    fs: float
    m: np.ndarray
    nperseg: int
    band_edges: np.ndarray      # indices into the Welch bins (bins 1..), len n_bands + 1

    @classmethod
    def for_record(cls, n, fs):
        m_max = n // MIN_CLUSTERS
        m = 2 ** np.arange(0, int(math.floor(math.log2(max(m_max, 1)))) + 1)
        nper = welch_nperseg(n)
        n_bins = nper // 2          # bins 1..nper/2 (DC dropped)
        f = np.arange(1, n_bins + 1) * fs / nper
        edges_f = np.logspace(math.log10(f[0]), math.log10(f[-1]) + 1e-9,
                              int(math.ceil(math.log10(f[-1] / f[0]) * BANDS_PER_DECADE)) + 1)
        idx = np.unique(np.searchsorted(f, edges_f))
        idx[-1] = n_bins
        return cls(n=n, fs=float(fs), m=m.astype(np.int64), nperseg=nper, band_edges=idx)

    @property
    def tau_s(self):
        return self.m / self.fs

    @property
    def freq_hz(self):
        return np.arange(1, self.nperseg // 2 + 1) * self.fs / self.nperseg

    @property
    def n_segments(self):
        return max(1, (self.n - self.nperseg) // (self.nperseg // 2) + 1)


def signature(y, layout):
    """The five signatures of a record (see the module docstring)."""
    from scipy.signal import welch
    from .allanvar import adev
    y = np.asarray(y, dtype=float)
    tau, ad, err, _ = adev(y, layout.fs, m=layout.m)
    _, p = welch(y, fs=layout.fs, nperseg=layout.nperseg, noverlap=layout.nperseg // 2,
                 window="hann", detrend="constant", scaling="density")
    p = p[1:layout.nperseg // 2 + 1]
    e = layout.band_edges
    band = np.array([p[e[i]:e[i + 1]].mean() for i in range(len(e) - 1)])
    nb = layout.n // N_BLOCKS
    blocks = y[:nb * N_BLOCKS].reshape(N_BLOCKS, nb).mean(axis=1)
    mean = float(y.mean())
    return {"avar": ad * ad, "allan": np.log(ad), "allan_rel_err": err / ad, "psd_bins": p,
            "psd": np.log(band), "line": np.log(p), "mean": np.array([mean]),
            "trend": blocks - mean, "std": float(y.std())}


def _floors(sig, layout):
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
    sigs: list
    mean: dict = field(init=False)
    sigma: dict = field(init=False)

    def __post_init__(self):
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


def zscores(sig, ref):
    """z per component of a measured signature against a reference."""
    return {c: (sig[c] - ref.mean[c]) / ref.sigma[c] for c in COMPONENTS}


def gap_components(z):
    """The five components of the gap (each ~1 when consistent)."""
    nl = len(z["line"])
    return {"allan": float(np.mean(z["allan"] ** 2)),
            "psd": float(np.mean(z["psd"] ** 2)),
            "line": float(np.max(z["line"] ** 2) / (2.0 * math.log(max(nl, 3)))),
            "mean": float(z["mean"][0] ** 2),
            "trend": float(np.mean(z["trend"] ** 2))}


def gap_value(comp):
    return float(np.mean([comp[c] for c in COMPONENTS]))


def loo_gaps(ref):
    """(gap, components) of each simulated record against the other simulations."""
    out = []
    S = len(ref.sigs)
    if S < 3:
        return out
    for j in range(S):
        r = Reference(ref.layout, [s for i, s in enumerate(ref.sigs) if i != j])
        comp = gap_components(zscores(ref.sigs[j], r))
        out.append((gap_value(comp), comp))
    return out


def where_disagree(z, layout, limit=3.0):
    """Tau ranges, PSD bands and blocks where |z| > limit, and PSD lines (bins whose
    own contribution to the line component exceeds COMPONENT_FLOOR) as plain dicts."""
    def ranges(x, mask):
        out, start = [], None
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


# ------------------------------------------------------------------ cards as text
def _fmt_num(v):
    return f"{float(v):.6g}"


def card_at_rate(text, fs, source="<card>"):
    """Parse a card's text as simulated at ``fs`` Hz (the record's rate).

    The text is re-parsed through :func:`gyrodenoise.simulator.parse_card`
    with ``sensor.sample_rate_hz`` set to ``fs``, so every rate-dependent
    check (a sinusoid above the record's Nyquist frequency) applies at the
    rate the card is actually simulated at; the error names ``source``.
    """
    from dataclasses import replace
    from .simulator import parse_card
    card = parse_card(text, source)
    if card.sample_rate_hz == fs:
        return card
    try:
        at = parse_card(text_at_rate(text, fs), source)
    except InputError as exc:
        raise InputError(f"{exc}, simulated at the record's rate {float(fs):g} Hz (the card says "
                         f"{card.sample_rate_hz:g} Hz)") from None
    if at.sample_rate_hz != float(fs):      # the rate is not on a line of its own: check by hand
        for i, s_ in enumerate(card.term_list("sinusoid")):
            if s_["frequency"] > fs / 2:
                raise InputError(f"terms.sinusoid[{i}].frequency {s_['frequency']:g} Hz is above the "
                                 f"record's Nyquist ({float(fs) / 2:g} Hz; the record is {float(fs):g} Hz, "
                                 f"the card says {card.sample_rate_hz:g} Hz)", source)
        at = replace(card, sample_rate_hz=float(fs))
    return at


def text_at_rate(text, fs):
    """The card text with sensor.sample_rate_hz set to ``fs`` (for the FMU's String parameter)."""
    new, n = re.subn(r"(?m)^(\s*sample_rate_hz\s*=\s*)[^#\n]*", lambda mo: mo.group(1) + repr(float(fs)) + " ",
                     text, count=1)
    return new if n else text


def _table_range(lines, i):
    """(start, end) of the body of the table whose header is line ``i``."""
    header = re.compile(r"^\s*\[")
    end = next((j for j in range(i + 1, len(lines)) if header.match(lines[j])), len(lines))
    return i + 1, end


def _last_content(lines, lo, hi, default):
    return max([j for j in range(lo, hi) if lines[j].strip() and not lines[j].lstrip().startswith("#")],
               default=default)


def _edit_lines(lines, name, params, refit, note):
    """The edit itself (see :func:`edit_card`); returns the new list of lines."""
    from .simulator import REPEATABLE
    if name in REPEATABLE:
        block = ["", f"[[terms.{name}]]                    # {note}"]
        block += [f"{k} = {_fmt_num(v)}" for k, v in params.items()]
        while lines and not lines[-1].strip():
            lines = lines[:-1]
        return lines + block
    what = "re-fitted" if refit else "added"
    # a sub-table [terms.name]: rewrite its keys in place
    sub = next((i for i, ln in enumerate(lines)
                if re.match(rf"^\s*\[\s*terms\s*\.\s*{re.escape(name)}\s*\]\s*(#.*)?$", ln)), None)
    if sub is not None:
        lo, hi = _table_range(lines, sub)
        body, done = [], set()
        for ln in lines[lo:hi]:
            mo = re.match(r"^\s*([A-Za-z0-9_]+)\s*=", ln)
            if mo and mo.group(1) in params:
                body.append(f"{mo.group(1)} = {_fmt_num(params[mo.group(1)])}    # {what}, {note}")
                done.add(mo.group(1))
            elif mo:       # a field the new fit does not set: dropped, as with an inline table
                body.append(f"# {ln.strip()}    # replaced, {note}")
            else:
                body.append(ln)
        last = _last_content(body, 0, len(body), -1)
        body[last + 1:last + 1] = [f"{k} = {_fmt_num(v)}    # {what}, {note}" for k, v in params.items()
                                   if k not in done]
        return lines[:lo] + body + lines[hi:]
    inline = f"{name} = {{ " + ", ".join(f"{k} = {_fmt_num(v)}" for k, v in params.items()) + " }"
    inline += f"    # {what}, {note}"
    pat = re.compile(rf"^\s*{re.escape(name)}\s*=")
    start = next((i for i, ln in enumerate(lines) if re.match(r"^\s*\[\s*terms\s*\]\s*(#.*)?$", ln)), None)
    if start is not None:
        lo, hi = _table_range(lines, start)
        for i in range(lo, hi):
            if pat.match(lines[i]):
                return lines[:i] + [inline] + lines[i + 1:]
        last = _last_content(lines, lo, hi, start)
        return lines[:last + 1] + [inline] + lines[last + 1:]
    # no [terms] table: one before the first [terms.x] / [[terms.x]] table (or at the end)
    first = next((i for i, ln in enumerate(lines) if re.match(r"^\s*\[\[?\s*terms\s*\.", ln)), len(lines))
    return lines[:first] + ["[terms]", inline, ""] + lines[first:]


def _holds(text, name, params, n_before):
    """Does the card text parse as TOML with terms.name holding ``params`` (the last
    instance, one more than ``n_before``, for a repeatable term)?"""
    import tomllib
    from .simulator import REPEATABLE
    try:
        t = tomllib.loads(text).get("terms", {}).get(name)
    except tomllib.TOMLDecodeError:
        return False
    if name in REPEATABLE:
        if not isinstance(t, list) or len(t) != n_before + 1:
            return False
        t = t[-1]
    if not isinstance(t, dict) or set(t) != set(params):
        return False
    return all(math.isclose(float(t[k]), float(v), rel_tol=1e-5, abs_tol=1e-300) for k, v in params.items())


def _n_instances(text, name):
    import tomllib
    try:
        t = tomllib.loads(text).get("terms", {}).get(name)
    except tomllib.TOMLDecodeError:
        return 0
    return 0 if t is None else len(t) if isinstance(t, list) else 1


def edit_card(text, name, params, refit=False, note="fitted by gyrodenoise gap", source="<card>"):
    """Add a term to (or replace a re-fitted term in) the TEXT of a card.

    Comments and order are kept. A non-repeatable term becomes an inline-table
    line in ``[terms]`` (replacing its old line when ``refit``), or, when the
    card writes it as a ``[terms.name]`` sub-table, that sub-table's fields are
    rewritten in place (fields the new fit does not set are commented out). A
    repeatable one (gauss_markov, sinusoid) becomes a new ``[[terms.name]]``
    table at the end. The edited text is checked by parsing it back: the term
    must then hold exactly ``params``; a layout this function cannot edit
    (e.g. a term written as dotted keys ``name.N = ...`` or a repeatable term
    written as an inline array) raises :class:`InputError` naming ``source``
    and the term.
    """
    new = "\n".join(_edit_lines(text.splitlines(), name, params, refit, note)) + "\n"
    if not _holds(new, name, params, _n_instances(text, name)):
        raise InputError(f"cannot rewrite terms.{name} in the way this card writes it (supported: an "
                         f"inline table `{name} = {{ ... }}` in [terms], a [terms.{name}] table, or "
                         f"[[terms.{name}]] tables for gauss_markov/sinusoid); rewrite the card in one "
                         f"of those forms", source)
    return new


# parameters that exercise edit_card on every term of the vocabulary (check_editable)
_TRIAL = {"quantization": {"Q": 1e-4}, "angle_random_walk": {"N": 0.1}, "bias_instability": {"B": 0.1},
          "rate_random_walk": {"K": 0.1}, "rate_ramp": {"R": 1.0}, "constant_bias": {"value": 1.0},
          "turn_on_transient": {"amplitude": 1.0, "tau": 10.0}, "gauss_markov": {"sigma": 1.0, "tau": 1.0},
          "sinusoid": {"amplitude": 1.0, "frequency": 1e-3, "phase_deg": 0.0}}


def check_editable(card):
    """Raise :class:`InputError` up front (naming the card and the term) when
    :func:`edit_card` cannot add or re-fit some term of the vocabulary in the
    way this card is written."""
    from .simulator import parse_card
    for name, params in _TRIAL.items():
        new = edit_card(card.text, name, params, refit=name in card.terms, source=card.source)
        parse_card(new, card.source)


# ------------------------------------------------------------------ simulation
def _fmu_worker(fmu_path, card_text, seed, n, fs, restarts):
    """Simulate one seed through SimulatedFog.fmu; returns the rates, or a one-line
    error message (str) instead of raising: FMU exceptions need not unpickle in the
    parent process, and a raise there would surface as a BrokenProcessPool."""
    try:
        return _fmu_simulate(fmu_path, card_text, seed, n, fs, restarts)
    except Exception as exc:        # noqa: BLE001 - returned as text to the parent
        msg = " ".join(str(exc).split()) or "no message"
        return f"{exc.__class__.__name__}: {msg}"


def _fmu_simulate(fmu_path, card_text, seed, n, fs, restarts):
    """Simulate one seed through SimulatedFog.fmu with fmpy FMU2Slave (one step per sample)."""
    from .fmu import FmuInstance, _stepper
    fog = FmuInstance(fmu_path, f"fog{seed}")
    try:
        fog.initialize(card=card_text, seed=int(seed))
        step = _stepper(fog, "true_rate", "restart", "measured_rate")
        h = 1.0 / fs
        rs = [False] * n if restarts is None else [bool(v) for v in restarts]
        out = np.empty(n)
        for k in range(n):
            out[k] = step(0.0, rs[k], k * h, h)
    finally:
        fog.free()
    return out


def fmu_path_for(fmu_dir=None, quiet=False):
    """SimulatedFog.fmu in ``fmu_dir`` (default build/), built when missing or stale."""
    from . import fmu as F
    d = Path(fmu_dir) if fmu_dir is not None else F.REPO_DIR / "build"
    path = d / "SimulatedFog.fmu"
    why = F.stale_reason(path)
    if why is not None:
        _log(f"gyrodenoise: note: building {path} ({why})", quiet)
        F.build_fmu("SimulatedFog", d)
    return path


class Simulator:
    """Simulate a card text S times at a record's rate and length.

    ``engine="native"`` uses :func:`gyrodenoise.simulator.simulate`;
    ``engine="fmu"`` steps SimulatedFog.fmu through fmpy in ``workers``
    processes (one FMU instance per process).
    """

    def __init__(self, n, fs, seeds, engine="native", restarts=None, fmu_dir=None, workers=None,
                 quiet=False, source="<card>"):
        if engine not in ("native", "fmu"):
            raise InputError(f"unknown engine {engine!r} (use fmu or native)")
        if workers is not None and (isinstance(workers, bool) or int(workers) != workers or workers < 1):
            raise InputError(f"workers must be a whole number >= 1 (or None: one per seed up to the "
                             f"cores), got {workers!r}")
        self.source = source
        self.n, self.fs, self.seeds, self.engine = int(n), float(fs), list(seeds), engine
        self.restarts = None if restarts is None else np.asarray(restarts, dtype=bool)
        self.quiet = quiet
        self.workers = workers
        self.fmu_path = fmu_path_for(fmu_dir, quiet) if engine == "fmu" else None
        self.n_runs = 0

    def run(self, text, engine=None):
        engine = engine or self.engine
        self.n_runs += len(self.seeds)
        if engine == "native":
            from .simulator import simulate
            card = card_at_rate(text, self.fs, self.source)
            return [simulate(card, self.n, seed=s, restarts=self.restarts).rate_deg_s for s in self.seeds]
        import multiprocessing as mp
        import os
        from concurrent.futures import ProcessPoolExecutor
        from concurrent.futures.process import BrokenProcessPool
        card_at_rate(text, self.fs, self.source)          # check it first
        ftext = text_at_rate(text, self.fs)
        workers = self.workers or min(len(self.seeds), os.cpu_count() or 1)
        rs = None if self.restarts is None else self.restarts.tolist()
        _log(f"gyrodenoise: simulating {len(self.seeds)} seeds x {self.n} samples through "
             f"{self.fmu_path.name} ({workers} processes)", self.quiet)
        with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                                 max_tasks_per_child=1) as ex:
            futs = [ex.submit(_fmu_worker, str(self.fmu_path), ftext, s, self.n, self.fs, rs)
                    for s in self.seeds]
            out = []
            try:
                for i, f in enumerate(futs):
                    r = f.result()
                    if isinstance(r, str):
                        raise InputError(f"{self.fmu_path.name} failed on seed {self.seeds[i]}: {r}",
                                         self.source)
                    out.append(r)
                    _log(f"gyrodenoise:   seed {self.seeds[i]} done", self.quiet)
            except BrokenProcessPool as exc:
                raise InputError(f"an FMU worker process died on seed {self.seeds[len(out)]} "
                                 f"({' '.join(str(exc).split())})", self.source) from None
        return out


# ------------------------------------------------------------------ candidates
def gm_avar(tau, sigma, T):
    """Allan variance of a first-order Gauss-Markov process (see module docstring)."""
    x = np.asarray(tau, dtype=float) / T
    small = x < 1e-3
    full = 2.0 * sigma ** 2 * T / np.maximum(tau, 1e-300) * (
        1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * np.maximum(x, 1e-300)))
    approx = 2.0 * sigma ** 2 * np.asarray(tau, dtype=float) / (3.0 * T) * (1.0 - 0.75 * x)
    return np.where(small, approx, full)


SHAPE = {"quantization": lambda t: 3.0 / (t * t), "angle_random_walk": lambda t: 1.0 / t,
         "bias_instability": lambda t: np.full_like(t, BI_FACTOR), "rate_random_walk": lambda t: t / 3.0}


def _deterministic_s(card, n, fs, restarts):
    """The card's deterministic rate (deg/s): bias, ramp, transient, sinusoids (no noise)."""
    t = np.arange(n) / fs
    cb = card.terms.get("constant_bias", {})
    det = np.full(n, cb.get("value", 0.0) / 3600.0)
    rr = card.terms.get("rate_ramp")
    if rr:
        det += rr["R"] / 3600.0 ** 2 * t
    tt = card.terms.get("turn_on_transient")
    if tt:
        det += tt["amplitude"] / 3600.0 * np.exp(-_since_restart(n, fs, restarts) / tt["tau"])
    for s in card.term_list("sinusoid"):
        det += s["amplitude"] / 3600.0 * np.sin(2 * np.pi * s["frequency"] * t + math.radians(s.get("phase_deg", 0.0)))
    return det


def _since_restart(n, fs, restarts):
    k = np.arange(n)
    if restarts is None or not np.any(restarts):
        return k / fs
    last = np.maximum.accumulate(np.where(np.asarray(restarts, bool) & (k > 0), k, 0))
    return (k - last) / fs


@dataclass
class Candidate:
    name: str
    params: dict              # card units
    refit: bool
    why: str
    text: str = ""
    gap: float = float("nan")
    score: float = float("nan")
    widen: float = float("nan")
    robust: float = float("nan")
    z: dict = None
    components: dict = None
    extra: list = field(default_factory=list)   # (name, params, refit) changed along with this one

    @property
    def changes(self):
        return [(self.name, self.params, self.refit)] + list(self.extra)

    @property
    def n_params(self):
        return N_PARAMS[self.name] + sum(N_PARAMS[e[0]] for e in self.extra)

    def to_json(self):
        return {"name": self.name, "params": {k: float(v) for k, v in self.params.items()},
                "refit": self.refit, "why": self.why,
                "with": [{"name": e[0], "params": e[1], "refit": e[2]} for e in self.extra], "gap": _f(self.gap), "robust_gap": _f(self.robust), "widen": _f(self.widen),
                "score": _f(self.score),
                "components": self.components}


def _f(v):
    return None if v is None or not math.isfinite(v) else float(v)


def propose(y, layout, ref, z, card, restarts=None, limit=3.0):
    """Candidate effects with parameters fitted to the record ``y`` (deg/s).

    Allan-shaped terms (Q, N, B, K) and gauss_markov are fitted to the Allan
    variance excess (measured minus mean simulated); rate_ramp,
    constant_bias, turn_on_transient and sinusoid by least squares on the
    record minus the card's deterministic part. A term already in the card is
    re-fitted (its new value replaces the old one) rather than added twice.
    When that joint fit changes the card's own terms, the same new term is
    also proposed fitted alone to the excess over the whole current card (its
    terms held, Allan points where the record is below the card left out),
    and re-simulation chooses between the two.
    """
    from scipy.optimize import minimize_scalar, nnls
    fs, n = layout.fs, layout.n
    tau = layout.tau_s
    avar_m = np.exp(2 * (ref.mean["allan"] + z["allan"] * ref.sigma["allan"]))   # measured
    avar_s = np.exp(2 * ref.mean["allan"])
    sig_avar = 2.0 * np.maximum(avar_m, avar_s) * ref.sigma["allan"]
    w = 1.0 / sig_avar ** 2
    cands = []
    allan_flag = np.any(np.abs(z["allan"]) > limit)
    # --- Allan-shaped terms and Gauss-Markov: fitted JOINTLY with the card's existing
    # Allan-shaped terms (re-fitted), by weighted NNLS on the measured Allan variance
    # minus what the rest of the card contributes
    if allan_flag:
        existing = {nm: (card.terms[nm][CARD_FIELD[nm][0]] / CARD_FIELD[nm][1]) ** 2
                    for nm in ALLAN_SHAPES if nm in card.terms}
        rest = np.maximum(avar_s - sum(v * SHAPE[nm](tau) for nm, v in existing.items()), 0.0)
        target = avar_m - rest
        sw = np.sqrt(w)

        def joint(cols):
            A = np.column_stack(cols) * sw[:, None]
            scale = np.max(np.abs(A), axis=0)
            scale[scale == 0] = 1.0
            coef, rn = nnls(A / scale, target * sw)
            coef = coef / scale
            # z of each coefficient (unconstrained covariance at the solution)
            try:
                cov = np.linalg.inv(A.T @ A)
                zc = coef / np.sqrt(np.maximum(np.diag(cov), 1e-300))
            except np.linalg.LinAlgError:
                zc = np.zeros_like(coef)
            return coef, zc, rn * rn

        def refits(names, coef):
            out = []
            for nm, c in zip(names, coef):
                old = existing[nm]
                if abs(math.sqrt(c) - math.sqrt(old)) > 0.02 * math.sqrt(old):
                    fld, to_card = CARD_FIELD[nm]
                    out.append((nm, {fld: math.sqrt(c) * to_card}, True))
            return out

        def held(col):
            """Fit one new term to the excess over the WHOLE current card, its terms held.

            The joint re-fit lets every Allan point pull on the card's terms, so
            points that no term can explain (a sensor's internal low-pass filter
            at short tau, with 0.1 % errors in a long record) drag a correct
            white-noise line away; re-simulation then decides between the two
            variants. Points where the record is BELOW the card (z < -limit)
            are left out: adding a term only adds Allan variance, so no new
            term can explain them."""
            keep = z["allan"] >= -limit
            a = (col * sw)[keep]
            if not np.any(a > 0):
                return 0.0, 0.0
            c = float(np.dot(a, ((avar_m - avar_s) * sw)[keep]) / np.dot(a, a))
            return c, c * math.sqrt(float(np.dot(a, a)))

        ex_names = list(existing)
        ex_cols = [SHAPE[nm](tau) for nm in ex_names]
        for name in ALLAN_SHAPES:
            fld, to_card = CARD_FIELD[name]
            if name in existing:
                continue
            coef, zc, _ = joint(ex_cols + [SHAPE[name](tau)])
            if coef[-1] <= 0 or zc[-1] < limit:
                continue
            ch = refits(ex_names, coef[:-1])
            cands.append(Candidate(name, {fld: math.sqrt(coef[-1]) * to_card}, False,
                                   f"Allan excess ~ {name} shape (z={zc[-1]:.1f})", extra=ch))
            if ch:      # the same term with the card's own terms held (see held())
                hc, hz = held(SHAPE[name](tau))
                if hc > 0 and hz >= limit:
                    cands.append(Candidate(name, {fld: math.sqrt(hc) * to_card}, False,
                                           f"Allan excess ~ {name} shape, card's terms held (z={hz:.1f})"))
        if ex_names:    # re-fit the existing Allan-shaped terms only
            coef, zc, _ = joint(ex_cols)
            ch = refits(ex_names, coef)
            if ch:
                cands.append(Candidate(ch[0][0], ch[0][1], True, "re-fit of the Allan-shaped terms",
                                       extra=ch[1:]))
        # --- Gauss-Markov bump: grid over the correlation time, then refined
        lo_T = math.log(3.0 / fs)           # T >= 3 samples

        def gm_chi2(logT):
            return joint(ex_cols + [gm_avar(tau, 1.0, math.exp(logT))])[2]
        grid = np.linspace(lo_T, math.log(tau[-1]), 41)
        g0 = grid[int(np.argmin([gm_chi2(g) for g in grid]))]
        opt = minimize_scalar(gm_chi2, bounds=(max(g0 - 0.25, lo_T), g0 + 0.25), method="bounded")
        T = math.exp(float(opt.x))
        coef, zc, _ = joint(ex_cols + [gm_avar(tau, 1.0, T)])
        if coef[-1] > 0 and zc[-1] > limit:
            ch = refits(ex_names, coef[:-1])
            cands.append(Candidate("gauss_markov", {"sigma": math.sqrt(coef[-1]) * 3600.0, "tau": T},
                                   False, f"Allan bump, best correlation time {T:.3g} s (z={zc[-1]:.1f})",
                                   extra=ch))
        if ex_names:    # the bump on top of the card's terms held, its own correlation time
            keep = z["allan"] >= -limit

            def held_chi2(logT):
                col = gm_avar(tau, 1.0, math.exp(logT))
                hc, _ = held(col)
                res = ((avar_m - avar_s - max(hc, 0.0) * col) * sw)[keep]
                return float(np.dot(res, res))
            g0 = grid[int(np.argmin([held_chi2(g) for g in grid]))]
            opt = minimize_scalar(held_chi2, bounds=(max(g0 - 0.25, lo_T), g0 + 0.25), method="bounded")
            Th = math.exp(float(opt.x))
            hc, hz = held(gm_avar(tau, 1.0, Th))
            same = (coef[-1] > 0 and zc[-1] > limit and not refits(ex_names, coef[:-1])
                    and abs(math.log(Th / T)) < 0.05)
            if hc > 0 and hz >= limit and not same:
                cands.append(Candidate("gauss_markov", {"sigma": math.sqrt(hc) * 3600.0, "tau": Th}, False,
                                       f"Allan bump at {Th:.3g} s, card's terms held (z={hz:.1f})"))
    r = np.asarray(y, float) - _deterministic_s(card, n, fs, restarts)
    t = np.arange(n) / fs
    # --- constant bias
    if abs(z["mean"][0]) > limit:
        old = card.terms.get("constant_bias")
        params = dict(old) if old else {}
        params["value"] = (old["value"] if old else 0.0) + float(r.mean()) * 3600.0
        cands.append(Candidate("constant_bias", params, old is not None,
                               f"record mean off by z={z['mean'][0]:.1f}"))
    trend_flag = np.any(np.abs(z["trend"]) > limit) or (allan_flag and z["allan"][-1] > limit)
    if trend_flag:
        # --- ramp
        old = card.terms.get("rate_ramp")
        slope = float(np.dot(r, t) / np.dot(t, t))     # through the origin: the card's ramp is R t
        cands.append(Candidate("rate_ramp", {"R": (old["R"] if old else 0.0) + slope * 3600.0 ** 2},
                               old is not None, "trend over the record (linear)"))
        # --- turn-on transient on block means
        nb = max(1, n // 2000)
        m = n // nb
        tb = _since_restart(n, fs, restarts)[:m * nb].reshape(m, nb)
        rb = r[:m * nb].reshape(m, nb).mean(axis=1)

        def sse(logtau, ret=False):
            e = np.exp(-tb / math.exp(logtau)).mean(axis=1)
            A = np.column_stack([np.ones(m), e])
            coef, *_ = np.linalg.lstsq(A, rb, rcond=None)
            res = float(np.sum((rb - A @ coef) ** 2))
            return (res, coef) if ret else res
        grid = np.linspace(math.log(max(2.0 / fs, 0.5)), math.log(n / fs), 40)
        vals = [sse(g) for g in grid]
        g0 = int(np.argmin(vals))
        lo, hi = grid[max(g0 - 1, 0)], grid[min(g0 + 1, len(grid) - 1)]
        opt = minimize_scalar(sse, bounds=(lo, hi), method="bounded") if hi > lo else None
        lt = float(opt.x) if opt is not None else grid[g0]
        _, coef = sse(lt, ret=True)
        old = card.terms.get("turn_on_transient")
        if abs(coef[1]) > 0 and lt < grid[-1] - 1e-6:
            cands.append(Candidate("turn_on_transient",
                                   {"amplitude": float(coef[1]) * 3600.0, "tau": math.exp(lt)},
                                   old is not None, "decaying trend after start/restarts"))
    # --- spectral line
    zl = z["line"]
    k = int(np.argmax(zl))
    if zl[k] > limit and zl[k] ** 2 > 2.0 * math.log(len(zl)):
        f = layout.freq_hz
        df = f[1] - f[0]
        # the record's own periodogram, zero-padded 4x, within +-1.5 Welch bins of the peak
        nfft = 4 * (1 << int(math.ceil(math.log2(n))))
        spec = np.abs(np.fft.rfft(r - r.mean(), nfft)) ** 2
        ff = np.fft.rfftfreq(nfft, 1.0 / fs)
        sel = np.flatnonzero((ff >= f[k] - 1.5 * df) & (ff <= f[k] + 1.5 * df))
        j = int(sel[np.argmax(spec[sel])])
        dff = ff[1] - ff[0]

        def neg_power(fr):
            ph = 2 * np.pi * fr * t
            return -(np.dot(r, np.cos(ph)) ** 2 + np.dot(r, np.sin(ph)) ** 2)
        opt = minimize_scalar(neg_power, bounds=(max(ff[j] - dff, 1e-9), min(ff[j] + dff, fs / 2)),
                              method="bounded", options={"xatol": 1e-3 * dff})
        fr = float(opt.x)
        A = np.column_stack([np.sin(2 * np.pi * fr * t), np.cos(2 * np.pi * fr * t), np.ones(n)])
        coef, *_ = np.linalg.lstsq(A, r, rcond=None)
        amp = math.hypot(coef[0], coef[1])
        phase = math.degrees(math.atan2(coef[1], coef[0]))
        cands.append(Candidate("sinusoid", {"amplitude": amp * 3600.0, "frequency": fr, "phase_deg": phase},
                               False, f"spectral line at {fr:.4g} Hz (z={zl[k]:.1f})"))
    return cands


# ------------------------------------------------------------------ the workflow
@dataclass
class GapResult:
    """Outcome of :func:`gap`."""
    effects_added: list
    gap_before: float
    gap_after: float
    card_text: str
    iterations: list
    threshold: float
    engine: str
    component_threshold: dict
    seeds: list
    limitations: list = field(default_factory=list)
    layout: Layout = None
    measured: dict = None

    @property
    def within_scatter(self):
        """The final card is within the simulations' scatter (the stop test of the loop)."""
        return bool(self.iterations[-1].get("within_scatter", False))

    def to_json(self):
        """Plain JSON (every float finite or null, see :func:`_finite`)."""
        return _finite({"effects_added": [{"name": e["name"], "params": e["params"], "refit": e["refit"],
                                           "iteration": e["iteration"]}
                                          for e in self.effects_added],
                        "gap_before": self.gap_before, "gap_after": self.gap_after,
                        "gap_metric": GAP_METRIC,
                        "threshold": self.threshold, "component_threshold": self.component_threshold,
                        "engine": self.engine, "seeds": list(self.seeds),
                        "within_scatter": self.within_scatter,
                        "stop": self.iterations[-1].get("stop"),
                        "limitations": list(self.limitations),
                        "iterations": [{k: v for k, v in it.items() if not k.startswith("_")}
                                       for it in self.iterations]})


def _finite(obj):
    """A copy of a JSON-able structure with every float through :func:`_f` (NaN/inf -> None)."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (bool, str)) or obj is None:
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _f(float(obj))
    if isinstance(obj, np.ndarray):
        return _finite(obj.tolist())
    return obj


def _zeroed(changes):
    """Fields that a set of changes would write as 0 (a noise term fitted to nothing)."""
    out = []
    for nm, pr, _ in changes:
        fld = CARD_FIELD.get(nm, (None,))[0]
        for k in ([fld] if fld else []) + (["sigma"] if nm == "gauss_markov" else []) + \
                (["amplitude"] if nm == "sinusoid" else []):
            if k in pr and not float(pr[k]) > 0:
                out.append(f"{nm}.{k}")
    return out


def _points(z):
    """Per-point contributions to the five gap components (component units)."""
    nl = len(z["line"])
    return {"allan": z["allan"] ** 2, "psd": z["psd"] ** 2,
            "line": np.array([np.max(z["line"] ** 2) / (2.0 * math.log(max(nl, 3)))]),
            "mean": z["mean"] ** 2, "trend": z["trend"] ** 2}


def explainable(zs):
    """Mask of the points that at least one of the z sets (the current card and
    its candidates) brings within the cap ``|z| <= 5``."""
    pts = [_points(z) for z in zs]
    return {c: np.any([p[c] < Z2_CAP for p in pts], axis=0) for c in COMPONENTS}


def robust_gap(z, mask=None):
    """The gap used to CHOOSE candidates: every point's ``z^2`` capped at
    :data:`Z2_CAP` (``|z| = 5``), and, given ``mask`` (:func:`explainable`), the
    points that no candidate brings within the cap left out (they count 0).

    A candidate is then judged by how many points it brings into agreement,
    not by how it shifts a disagreement that no term of the vocabulary
    removes (e.g. a sensor's internal low-pass filter at short tau, where a
    1e6-sample record has Allan errors of 0.1 % and z of -100). The divisor
    of each component stays its number of points, so the value stays
    comparable between candidates of one iteration. When every disagreement
    is explainable (the simulated hidden-effect cases) this is the gap with
    a cap.
    """
    pts = _points(z)
    comp = {}
    for c in COMPONENTS:
        v = np.minimum(pts[c], Z2_CAP)
        if mask is not None:
            v = np.where(mask[c], v, 0.0)
        comp[c] = float(np.mean(v))
    return gap_value(comp)


def widening(ref_new, ref_old, z_old):
    """Log-likelihood price of a wider simulated scatter that the record does not ask for.

    ``-2 ln L`` of the measured signatures under a card is ``sum z^2 + sum
    ln(2 pi sigma^2)``: the gap holds the ``z^2`` part only, so a candidate
    that merely widens the simulations' scatter (e.g. a large random walk
    whose wander covers a mean offset) lowers every ``z`` and looks better
    than it is. Per point, the widening ``ln(sigma_new^2 / sigma_old^2)`` is
    charged beyond what the record itself asks for, ``ln(max(z_old^2, 1))``
    (a point off by 4 sigma justifies a scatter up to 4x wider; a point that
    already agrees justifies none). Averaged like the gap: over the points of
    each of ``allan``, ``psd``, ``mean`` and ``trend``, then over the five
    components (``line``, a maximum, counts 0).
    """
    tot = 0.0
    for c in WIDEN_COMPONENTS:
        w = np.log(ref_new.sigma[c] ** 2 / ref_old.sigma[c] ** 2) - np.log(np.maximum(z_old[c] ** 2, 1.0))
        tot += float(np.mean(np.maximum(w, 0.0)))
    return tot / len(COMPONENTS)


def deterministic_offset(sig_m, ref, z, limit=3.0):
    """Is the record mean's disagreement a deterministic offset rather than a wander?

    A slow random process (bias instability, random walk, Gauss-Markov) that
    moves the record mean by ``d`` also moves the block means about one
    another by a similar amount; a constant bias moves the mean and leaves the
    block means alone. True when ``|z_mean| > limit`` and the offset of the
    record mean from the simulations' mean is more than ``OFFSET_RATIO`` times
    the rms of the measured block means about the record mean. Returns
    ``(flag, offset_deg_s, wander_rms_deg_s)``.
    """
    off = float(sig_m["mean"][0] - ref.mean["mean"][0])
    wander = float(np.sqrt(np.mean(sig_m["trend"] ** 2)))
    flag = abs(z["mean"][0]) > limit and abs(off) > OFFSET_RATIO * wander
    return bool(flag), off, wander


def _evaluate(sims, sig_m, layout):
    ref = Reference(layout, [signature(s, layout) for s in sims])
    z = zscores(sig_m, ref)
    comp = gap_components(z)
    return ref, z, comp, gap_value(comp)


def check_record(rate_deg_s, source="MEASURED"):
    """The measured record as a float array, or InputError (one line) when the
    workflow cannot use it: not 1-D finite, too short, or constant."""
    y = np.asarray(rate_deg_s, dtype=float)
    if y.ndim != 1 or not np.all(np.isfinite(y)):
        raise InputError("the record must be a 1-D array of finite rates", source)
    if y.shape[0] < MIN_SAMPLES:
        raise InputError(f"only {y.shape[0]} samples; the gap workflow needs at least {MIN_SAMPLES} "
                         f"(Allan deviation over octaves and a Welch PSD)", source)
    if not np.ptp(y) > 0:
        raise InputError("the record is constant (zero variance): nothing to compare", source)
    return y


def gap(rate_deg_s, sample_rate_hz, card, seeds=6, engine="native", restarts=None, max_effects=4,
        fmu_dir=None, workers=None, source="MEASURED", quiet=True):
    """Find what a model card misses to behave like a measured record.

    Parameters
    ----------
    rate_deg_s : array_like
        Measured rate (deg/s), fixed sample rate.
    sample_rate_hz : float
    card : ModelCard, path or card name
    seeds : int or list of int
        Simulated records per evaluation (int S: seeds 1..S).
    engine : {"native", "fmu"}
        Simulator for the reported gaps; candidates are screened with the
        native engine (bit-identical to the FMU).
    restarts : array_like of bool, optional
    max_effects : int
        Most effects added.

    Returns
    -------
    GapResult
    """
    from .simulator import load_card
    y = check_record(rate_deg_s, source)
    fs = float(sample_rate_hz)
    card0 = load_card(card)
    text = card0.text
    csrc = card0.source
    card_at_rate(text, fs, csrc)        # the card as simulated at the record's rate (Nyquist)
    check_editable(card0)               # every term of the vocabulary can be written into this card
    seed_list = list(range(1, int(seeds) + 1)) if np.isscalar(seeds) else [int(s) for s in seeds]
    if len(seed_list) < 3:
        raise InputError(f"need at least 3 seeds to know the simulation's scatter, got {len(seed_list)}")
    layout = Layout.for_record(y.shape[0], fs)
    sim = Simulator(y.shape[0], fs, seed_list, engine, restarts, fmu_dir, workers, quiet, source=csrc)
    sig_m = signature(y, layout)
    sims = sim.run(text)
    if not np.any([np.std(s_) > 0 for s_ in sims]):
        raise InputError("the card simulates a noise-free gyro (no stochastic term); the gap needs the "
                         "simulations' scatter: add at least an angle_random_walk", card0.source)
    ref, z, comp, g = _evaluate(sims, sig_m, layout)
    loo = loo_gaps(ref)
    threshold = max(1.5, 1.5 * max(g_ for g_, _ in loo)) if loo else 2.0
    comp_threshold = {c: max(COMPONENT_FLOOR, 1.5 * max(cc[c] for _, cc in loo)) if loo else COMPONENT_FLOOR
                      for c in COMPONENTS}
    _log(f"gyrodenoise: gap of the input card {g:.3g} (threshold {threshold:.3g})", quiet)
    if not math.isfinite(g):
        raise InputError(f"the gap of the input card is not finite ({g}): the record's signatures "
                         f"cannot be compared with the card's", source)
    gap_before = g
    effects, iterations, limitations = [], [], []
    while True:
        it = {"card_gap": g, "components": comp, "where": where_disagree(z, layout),
              "_ref": ref, "_z": z, "candidates": []}
        iterations.append(it)
        within = g <= threshold and all(comp[c] <= comp_threshold[c] for c in COMPONENTS)
        it["within_scatter"] = bool(within)
        if within or len(effects) >= max_effects:
            it["stop"] = "within the simulations' scatter" if within else "max_effects reached"
            break
        card = card_at_rate(text, fs, csrc)
        cands = propose(y, layout, ref, z, card, restarts)
        det, off, wander = deterministic_offset(sig_m, ref, z)
        if det and any(c.name == "constant_bias" for c in cands):
            # deterministic signatures first: a mean offset far beyond the block-mean
            # wander is a constant bias, not the wander of a slow random process
            cands = [c for c in cands if c.name == "constant_bias"]
            cands[0].why += (f"; offset {off * 3600:.4g} deg/h = {abs(off) / max(wander, 1e-300):.3g} x the "
                             f"block-mean wander ({wander * 3600:.3g} deg/h rms): deterministic, explained first")
            it["deterministic_first"] = True
        for c in cands:
            zeroed = _zeroed(c.changes)
            if zeroed:
                msg = (f"the card is noisier than the record ({', '.join(zeroed)} would be set to 0); "
                       f"gap only adds or re-fits terms: it cannot remove or reduce gauss_markov/"
                       f"sinusoid terms, and writes no zeroed term as a fit")
                c.why += f" (rejected: {msg})"
                if msg not in limitations:
                    limitations.append(msg)
                continue
            c.text = text
            for nm, pr, rf in c.changes:
                c.text = edit_card(c.text, nm, pr, rf, f"fitted to {Path(str(source)).name}", csrc)
            try:
                card_at_rate(c.text, fs, csrc)
            except InputError as exc:
                c.why += f" (rejected: {exc})"
                continue
            cref, c.z, c.components, c.gap = _evaluate(sim.run(c.text, engine="native"), sig_m, layout)
            c.widen = widening(cref, ref, z)
            if not math.isfinite(c.gap):
                c.why += " (rejected: non-finite gap)"
                c.z = None
        ok = [c for c in cands if c.z is not None]
        mask = explainable([z] + [c.z for c in ok])
        for c in ok:
            c.robust = robust_gap(c.z, mask)
            c.score = (c.robust + c.widen) * (1.0 + PENALTY_PER_PARAM * c.n_params)
        ok = [c for c in ok if math.isfinite(c.score)]      # never accept a non-finite score
        it["candidates"] = [c.to_json() for c in cands]
        best = min(ok, key=lambda c: c.score) if ok else None
        rg = robust_gap(z, mask)
        it["unexplained_points"] = {c_: int(np.sum(~mask[c_])) for c_ in COMPONENTS}
        it["robust_gap"] = rg
        if best is not None and best.score > MIN_IMPROVEMENT * rg and len(ok) >= 2:
            # no single effect shrinks the gap significantly: look one step ahead, pairs
            # of the three best-scoring candidates (two effects that only together
            # explain a signature, e.g. a bias and a ramp that offset each other's mean)
            top = sorted(ok, key=lambda c: c.score)[:3]
            pairs = []
            for i, a in enumerate(top):
                for b in top[i + 1:]:
                    if a.name == b.name or _zeroed(b.changes):
                        continue
                    pc = Candidate(a.name, a.params, a.refit, f"{a.why}; together with {b.name}",
                                   extra=a.extra + b.changes)
                    pc.text = a.text
                    for nm, pr, rf in b.changes:
                        pc.text = edit_card(pc.text, nm, pr, rf, f"fitted to {Path(str(source)).name}", csrc)
                    try:
                        card_at_rate(pc.text, fs, csrc)
                    except InputError:
                        continue
                    pref, pz, pc.components, pc.gap = _evaluate(sim.run(pc.text, engine="native"), sig_m, layout)
                    pc.robust = robust_gap(pz, mask)
                    pc.widen = widening(pref, ref, z)
                    pc.score = (pc.robust + pc.widen) * (1.0 + PENALTY_PER_PARAM * pc.n_params)
                    if math.isfinite(pc.score) and math.isfinite(pc.gap):
                        pairs.append(pc)
            it["pairs"] = [c.to_json() for c in pairs]
            bp = min(pairs, key=lambda c: c.score) if pairs else None
            if bp is not None and bp.score < MIN_IMPROVEMENT * best.score:
                best = bp
        if best is None or not (math.isfinite(rg) and best.score <= MIN_IMPROVEMENT * rg):
            it["stop"] = "no candidate shrinks the gap significantly"
            break
        _log(f"gyrodenoise: " + "; ".join(f"{'re-fit' if rf else 'add'} {nm} {_short(pr)}"
                                          for nm, pr, rf in best.changes)
             + f": gap {g:.3g} -> {best.gap:.3g}", quiet)
        text = best.text
        for nm, pr, rf in best.changes:
            effects.append({"name": nm, "params": {k: float(v) for k, v in pr.items()},
                            "refit": rf, "why": best.why, "iteration": len(iterations) - 1})
        it["chosen"] = [nm for nm, _, _ in best.changes]
        sims = sim.run(text)
        ref, z, comp, g = _evaluate(sims, sig_m, layout)
    last = iterations[-1]
    if not last["within_scatter"] and any(s_ < 0 for s_ in last["where"]["allan_sign"]) \
            and not any(s_ > 0 for s_ in last["where"]["allan_sign"]):
        msg = ("the record's Allan deviation is below the card's wherever they disagree: the card is "
               "noisier than the record; gap only adds or re-fits terms and cannot remove or reduce "
               "gauss_markov/sinusoid terms")
        if not any("noisier" in m_ for m_ in limitations):
            limitations.append(msg)
    return GapResult(limitations=limitations, effects_added=effects, gap_before=gap_before, gap_after=g, card_text=text,
                     iterations=iterations, threshold=threshold, engine=engine, seeds=seed_list,
                     component_threshold=comp_threshold,
                     layout=layout, measured=sig_m)


# ------------------------------------------------------------------ report and plot
def format_report(res, source="MEASURED"):
    """A short text report (a minute to read)."""
    lay = res.layout
    out = [f"gyrodenoise gap: {source} ({lay.n} samples, {lay.fs:g} Hz, {lay.n / lay.fs / 60:.1f} min), "
           f"{len(res.seeds)} simulated seeds per card, engine {res.engine}",
           f"gap metric: {GAP_METRIC}",
           f"scatter threshold (1.5 x max leave-one-out gap of the simulations): {res.threshold:.3g}",
           ""]
    for i, it in enumerate(res.iterations):
        label = "input card" if i == 0 else "after " + " + ".join(
            e["name"] for e in res.effects_added if e.get("iteration", 0) < i)
        comp = ", ".join(f"{c} {it['components'][c]:.3g}" for c in COMPONENTS)
        out.append(f"[{i}] {label}: gap {it['card_gap']:.3g}  ({comp})")
        w = it["where"]
        bits = []
        if w["allan_tau_s"]:
            bits.append("Allan deviation at tau " + ", ".join(f"{a:.3g}-{b:.3g} s" for a, b in w["allan_tau_s"])
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
    for m_ in res.limitations:
        out.append(f"limitation: {m_}")
    out.append("")
    if res.effects_added:
        verdict = "added (in the order found; the last entry of a term is its value in the card): " + \
            ", ".join(f"{e['name']}{' (re-fit)' if e['refit'] else ''}" for e in res.effects_added)
        if not res.within_scatter:
            verdict += f"; still above the scatter threshold ({res.iterations[-1].get('stop')})"
    elif res.within_scatter:
        verdict = "nothing missing (within the simulations' scatter)"
    else:
        verdict = (f"nothing added: {res.iterations[-1].get('stop')}, but the gap is still above the "
                   f"scatter threshold ({res.threshold:.3g}): the card does not explain the record")
    out.append(f"gap {res.gap_before:.3g} -> {res.gap_after:.3g}; " + verdict)
    return "\n".join(out)


def _short(params):
    return "{" + ", ".join(f"{k}={v:.4g}" for k, v in params.items()) + "}"


def plot_gap(res, path, title=""):
    """PNG: measured Allan deviation vs the simulated band (mean +- 1 sigma of one
    simulation) for the input card and after each added effect; a PSD panel when a
    sinusoid was added."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    lay, sig = res.layout, res.measured
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
        label = "input card" if i == 0 else "+ " + " + ".join(
            e["name"] for e in res.effects_added if e.get("iteration", 0) < i)
        ax.fill_between(tau, np.exp(mu - sd) * 3600, np.exp(mu + sd) * 3600, color=col, alpha=0.25)
        ax.loglog(tau, np.exp(mu) * 3600, "-", color=col, label=f"{label} (gap {it['card_gap']:.3g})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel("Allan deviation (deg/h)")
    ax.set_title(title or "measured vs simulated (band: 1 sigma of one simulation)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
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
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
