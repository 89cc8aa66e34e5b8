"""Model cards (``models/*.toml``) and the simulated gyro.

Conventions (IEEE Std 952-1997, Annex C; rates in deg/s inside, card units as
in the spec, section 4):

===================  ==============  =========================================
term                 card unit       simulated as
===================  ==============  =========================================
quantization Q       deg             white *angle* noise of std Q, differenced:
                                     rate_k = (w_k - w_{k-1}) / T  -> 3 Q^2/tau^2
angle_random_walk N  deg/sqrt(h)     white rate noise, std N / sqrt(T) -> N^2/tau
bias_instability B   deg/h           flicker (1/f) rate noise, one-sided PSD
                                     B^2 / (pi f): a bank of first-order
                                     Gauss-Markov processes, 3 per decade from
                                     1e-5 Hz to Nyquist, each of variance
                                     B^2 ln(10^(1/3)) / pi; Allan plateau
                                     0.664 B (within the bank's ripple, ~2 %)
rate_random_walk K   deg/h^1.5       rate random walk, increment std K sqrt(T)
                                     -> K^2 tau / 3
rate_ramp R          deg/h^2         deterministic R t -> R^2 tau^2 / 2
constant_bias        deg/h           value (+ repeatability * N(0,1) drawn
                                     afresh at the start and at every restart)
turn_on_transient    deg/h, s        amplitude exp(-t_since_restart / tau)
gauss_markov         deg/h, s        first-order GM, stationary std sigma
sinusoid             deg/h, Hz       amplitude sin(2 pi f t + phase_deg)
===================  ==============  =========================================

Time t counts from the start of the record; restarts reset only the turn-on
bias draw and the transient clock (the stochastic processes run on).

Streaming and batch give the same numbers: the noise is generated in fixed
blocks of :data:`BLOCK` samples from one seeded generator, whether one sample
(:class:`SimStream`, used by SimulatedFog.fmu) or a whole record
(:func:`simulate`) is asked for.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

BLOCK = 4096
FLICKER_F_LO_HZ = 1.0e-5
FLICKER_POLES_PER_DECADE = 3

DEG_H = 1.0 / 3600.0             # deg/h -> deg/s
DEG_RTH = 1.0 / 60.0             # deg/sqrt(h) -> deg/sqrt(s)
DEG_H15 = 1.0 / 3600.0 ** 1.5    # deg/h^1.5 -> deg/s^1.5
DEG_H2 = 1.0 / 3600.0 ** 2       # deg/h^2 -> deg/s^2

# term -> {field: (required, minimum, unit)}
TERM_FIELDS = {
    "quantization": {"Q": (True, 0.0, "deg")},
    "angle_random_walk": {"N": (True, 0.0, "deg/sqrt(h)")},
    "bias_instability": {"B": (True, 0.0, "deg/h")},
    "rate_random_walk": {"K": (True, 0.0, "deg/h^1.5")},
    "rate_ramp": {"R": (True, None, "deg/h^2")},
    "constant_bias": {"value": (True, None, "deg/h"), "repeatability": (False, 0.0, "deg/h")},
    "turn_on_transient": {"amplitude": (True, None, "deg/h"), "tau": (True, 1e-300, "s")},
    "gauss_markov": {"sigma": (True, 0.0, "deg/h"), "tau": (True, 1e-300, "s")},
    "sinusoid": {"amplitude": (True, None, "deg/h"), "frequency": (True, 0.0, "Hz"),
                 "phase_deg": (False, None, "deg")},
}
REPEATABLE = ("gauss_markov", "sinusoid")
ABSURD = 1.0e9   # any card value beyond this is refused as absurd


@dataclass
class ModelCard:
    """A parsed, checked model card."""
    name: str
    sample_rate_hz: float
    terms: dict            # term -> dict of floats, or list of dicts (repeatable)
    text: str = ""         # the TOML source, comments included
    source: str = "<card>"

    def term_list(self, name):
        """The instances of a term as a list (empty when absent)."""
        t = self.terms.get(name)
        if t is None:
            return []
        return t if isinstance(t, list) else [t]


def parse_card(text, source="<card>"):
    """Parse and check a model card; raises InputError naming the field."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", source) from None
    unknown = set(data) - {"sensor", "terms"}
    if unknown:
        raise InputError(f"unknown section [{sorted(unknown)[0]}] (expected [sensor], [terms])", source)
    sensor = data.get("sensor")
    if not isinstance(sensor, dict):
        raise InputError("missing [sensor] section", source)
    fs = sensor.get("sample_rate_hz")
    if isinstance(fs, bool) or not isinstance(fs, (int, float)) or not (0 < fs < ABSURD):
        raise InputError(f"sensor.sample_rate_hz must be a positive number below {ABSURD:g} Hz, "
                         f"got {fs!r}", source)
    name = str(sensor.get("name", Path(source).stem))
    raw_terms = data.get("terms", {})
    if not isinstance(raw_terms, dict):
        raise InputError("[terms] must be a table", source)
    terms = {}
    for tname, tval in raw_terms.items():
        if tname not in TERM_FIELDS:
            raise InputError(f"unknown term terms.{tname} (known: {', '.join(TERM_FIELDS)})", source)
        items = tval if isinstance(tval, list) else [tval]
        if isinstance(tval, list) and tname not in REPEATABLE:
            raise InputError(f"terms.{tname} may appear only once", source)
        checked = []
        for idx, item in enumerate(items):
            where = f"terms.{tname}" + (f"[{idx}]" if isinstance(tval, list) else "")
            if not isinstance(item, dict):
                raise InputError(f"{where} must be a table of fields", source)
            out = {}
            for fname, fval in item.items():
                if fname not in TERM_FIELDS[tname]:
                    raise InputError(f"unknown field {where}.{fname} (known: "
                                     f"{', '.join(TERM_FIELDS[tname])})", source)
                if isinstance(fval, bool) or not isinstance(fval, (int, float)):
                    raise InputError(f"{where}.{fname} must be a number, got {fval!r}", source)
                if not math.isfinite(fval) or abs(fval) > ABSURD:
                    raise InputError(f"{where}.{fname} is not a usable number: {fval!r}", source)
                _, minimum, unit = TERM_FIELDS[tname][fname]
                if minimum is not None and fval < minimum:
                    bound = "> 0" if 0 < minimum < 1e-100 else f">= {minimum:g}"
                    raise InputError(f"{where}.{fname} must be {bound} {unit}, got {fval!r}", source)
                out[fname] = float(fval)
            for fname, (required, _, unit) in TERM_FIELDS[tname].items():
                if required and fname not in out:
                    raise InputError(f"{where} is missing the field {fname} ({unit})", source)
            if tname == "sinusoid" and out["frequency"] > fs / 2:
                raise InputError(f"{where}.frequency {out['frequency']:g} Hz is above Nyquist "
                                 f"({fs / 2:g} Hz)", source)
            checked.append(out)
        terms[tname] = checked if isinstance(tval, list) else checked[0]
    return ModelCard(name=name, sample_rate_hz=float(fs), terms=terms, text=text, source=source)


def models_dir():
    """Folder of the embedded model cards."""
    return Path(__file__).resolve().parent / "data"


def load_card(path_or_name):
    """Read a card from a path, or by name from the embedded ``models/``."""
    if isinstance(path_or_name, ModelCard):
        return path_or_name
    path = Path(path_or_name)
    if not path.exists():
        embedded = models_dir() / (path.name if path.suffix else path.name + ".toml")
        if embedded.exists():
            path = embedded
        else:
            raise InputError("no such model card", str(path_or_name))
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read model card: {exc.__class__.__name__}", str(path)) from None
    return parse_card(text, source=str(path))


# ----------------------------------------------------------------- the model
def _bank(card):
    """AR(1) bank [a_j], [g_j], [stationary std_j] in deg/s for one sample period."""
    T = 1.0 / card.sample_rate_hz
    a, g, sd = [], [], []
    bi = card.terms.get("bias_instability")
    if bi and bi["B"] > 0:
        B = bi["B"] * DEG_H
        f_hi = 0.5 * card.sample_rate_hz
        n_dec = math.log10(f_hi / FLICKER_F_LO_HZ)
        n_poles = max(1, int(math.ceil(n_dec * FLICKER_POLES_PER_DECADE)))
        delta = math.log(f_hi / FLICKER_F_LO_HZ) / n_poles
        var = B * B * delta / math.pi
        for j in range(n_poles):
            fj = FLICKER_F_LO_HZ * math.exp((j + 0.5) * delta)
            aj = math.exp(-2.0 * math.pi * fj * T)
            a.append(aj)
            g.append(math.sqrt(var * (1.0 - aj * aj)))
            sd.append(math.sqrt(var))
    for gm in card.term_list("gauss_markov"):
        if gm["sigma"] > 0:
            aj = math.exp(-T / gm["tau"])
            s = gm["sigma"] * DEG_H
            a.append(aj)
            g.append(s * math.sqrt(1.0 - aj * aj))
            sd.append(s)
    rrw = card.terms.get("rate_random_walk")
    if rrw and rrw["K"] > 0:
        a.append(1.0)
        g.append(rrw["K"] * DEG_H15 * math.sqrt(T))
        sd.append(0.0)
    return np.array(a), np.array(g), np.array(sd)


def _ar1_bank(a, u, x0):
    """x_k = a * x_{k-1} + u_k per column; returns (x, last row)."""
    try:
        from scipy.signal import lfilter
    except ImportError:  # plain numpy: same two operations per sample
        x = np.empty_like(u)
        prev = x0.copy()
        for k in range(u.shape[0]):
            prev = a * prev + u[k]
            x[k] = prev
        return x, prev
    x = np.empty_like(u)
    for j in range(u.shape[1]):
        x[:, j] = lfilter([1.0], [1.0, -a[j]], u[:, j], zi=[a[j] * x0[j]])[0]
    return x, x[-1].copy()


class SimStream:
    """A simulated gyro, sample by sample or block by block (same numbers).

    Parameters
    ----------
    card : ModelCard or path
    seed : int
    """

    def __init__(self, card, seed=0):
        self.card = load_card(card)
        self.seed = int(seed)
        self.T = 1.0 / self.card.sample_rate_hz
        self.a, self.g, self.sd = _bank(self.card)
        q = self.card.terms.get("quantization")
        self.Q = q["Q"] if q else 0.0
        arw = self.card.terms.get("angle_random_walk")
        self.arw_sd = (arw["N"] * DEG_RTH / math.sqrt(self.T)) if arw else 0.0
        cb = self.card.terms.get("constant_bias", {})
        self.bias0 = cb.get("value", 0.0) * DEG_H
        self.bias_rep = cb.get("repeatability", 0.0) * DEG_H
        tt = self.card.terms.get("turn_on_transient")
        self.tr_amp = tt["amplitude"] * DEG_H if tt else 0.0
        self.tr_tau = tt["tau"] if tt else 1.0
        rr = self.card.terms.get("rate_ramp")
        self.ramp = rr["R"] * DEG_H2 if rr else 0.0
        self.sines = [(s["amplitude"] * DEG_H, s["frequency"], math.radians(s.get("phase_deg", 0.0)))
                      for s in self.card.term_list("sinusoid")]
        self.n_ch = 2 + len(self.a)   # [quant angle, arw, bank...]
        self.reset()

    def reset(self):
        ss = np.random.SeedSequence(self.seed)
        noise_seq, restart_seq = ss.spawn(2)
        self.rng = np.random.Generator(np.random.PCG64(noise_seq))
        self.rng_restart = np.random.Generator(np.random.PCG64(restart_seq))
        # stationary start of the bank (random walks start at 0)
        self.x = self.sd * self.rng.standard_normal(len(self.a))
        self.w_prev = self.Q * self.rng.standard_normal()
        self.block = np.empty(0)
        self.pos = 0
        self.k = 0                 # samples since start
        self.k_restart = 0         # samples since last restart
        self.bias = self._draw_bias()

    def _draw_bias(self):
        return self.bias0 + self.bias_rep * self.rng_restart.standard_normal() if self.bias_rep else self.bias0

    def _next_block(self):
        w = self.rng.standard_normal((BLOCK, self.n_ch))
        out = self.arw_sd * w[:, 1]
        if self.Q > 0:
            ang = self.Q * w[:, 0]
            prev = np.concatenate(([self.w_prev], ang[:-1]))
            out = out + (ang - prev) / self.T
            self.w_prev = float(ang[-1])
        if len(self.a):
            u = self.g * w[:, 2:]
            xb, self.x = _ar1_bank(self.a, u, self.x)
            out = out + xb.sum(axis=1)
        self.block = out
        self.pos = 0

    def _deterministic(self, t, t_restart):
        v = self.bias + self.ramp * t
        if self.tr_amp:
            v += self.tr_amp * math.exp(-t_restart / self.tr_tau)
        for amp, f, ph in self.sines:
            v += amp * math.sin(2.0 * math.pi * f * t + ph)
        return v

    def step(self, true_rate_deg_s=0.0, restart=False):
        """One measured sample (deg/s) for the true rate (deg/s)."""
        if restart and self.k > 0:
            self.k_restart = 0
            self.bias = self._draw_bias()
        if self.pos >= self.block.shape[0]:
            self._next_block()
        noise = float(self.block[self.pos])
        self.pos += 1
        y = true_rate_deg_s + noise + self._deterministic(self.k * self.T, self.k_restart * self.T)
        self.k += 1
        self.k_restart += 1
        return y

    def run(self, n_samples, true_rate_deg_s=None, restarts=None):
        """``n_samples`` measured samples (deg/s) at once, continuing the stream."""
        n = int(n_samples)
        noise = np.empty(n)
        i = 0
        while i < n:
            if self.pos >= self.block.shape[0]:
                self._next_block()
            take = min(n - i, self.block.shape[0] - self.pos)
            noise[i:i + take] = self.block[self.pos:self.pos + take]
            self.pos += take
            i += take
        k = self.k + np.arange(n)
        t = k * self.T
        rs = np.zeros(n, dtype=bool) if restarts is None else np.asarray(restarts, dtype=bool)
        # samples since last restart, and the bias in force, per sample
        k_restart = np.empty(n)
        bias = np.empty(n)
        kr, b = self.k_restart, self.bias
        prev = 0
        for s0 in list(np.flatnonzero(rs)) + [n]:
            seg = s0 - prev
            k_restart[prev:s0] = kr + np.arange(seg)
            bias[prev:s0] = b
            kr += seg
            if s0 < n and self.k + s0 > 0:
                kr = 0
                b = self._draw_bias()
            prev = s0
        self.k_restart, self.bias = kr, b
        det = bias + self.ramp * t
        if self.tr_amp:
            det = det + self.tr_amp * np.exp(-(k_restart * self.T) / self.tr_tau)
        for amp, f, ph in self.sines:
            det = det + amp * np.sin(2.0 * np.pi * f * t + ph)
        y = noise + det
        if true_rate_deg_s is not None:
            y = y + np.broadcast_to(np.asarray(true_rate_deg_s, dtype=float), (n,))
        self.k += n
        return y

    # -- state save / restore (for FMU state and tests)
    def get_state(self):
        return {"rng": self.rng.bit_generator.state, "rng_restart": self.rng_restart.bit_generator.state,
                "x": self.x.tolist(), "w_prev": self.w_prev, "block": self.block.tolist(),
                "pos": self.pos, "k": self.k, "k_restart": self.k_restart, "bias": self.bias}

    def set_state(self, st):
        self.rng.bit_generator.state = st["rng"]
        self.rng_restart.bit_generator.state = st["rng_restart"]
        self.x = np.array(st["x"], dtype=float)
        self.w_prev = float(st["w_prev"])
        self.block = np.array(st["block"], dtype=float)
        self.pos, self.k, self.k_restart = int(st["pos"]), int(st["k"]), int(st["k_restart"])
        self.bias = float(st["bias"])


@dataclass
class Record:
    """A gyro record: rate in deg/s at a fixed sample rate."""
    rate_deg_s: np.ndarray
    sample_rate_hz: float
    time_s: np.ndarray | None = None
    true_rate_deg_s: np.ndarray | None = None
    restarts: np.ndarray | None = None
    source: str = ""
    notes: list = field(default_factory=list)   # repairs and remarks, reported

    def __post_init__(self):
        if self.time_s is None:
            self.time_s = np.arange(len(self.rate_deg_s)) / self.sample_rate_hz

    def __len__(self):
        return len(self.rate_deg_s)


def simulate(card, n_samples, seed=0, true_rate_deg_s=None, restarts=None):
    """Simulate ``n_samples`` of the gyro described by ``card``.

    Parameters
    ----------
    card : ModelCard, path or embedded name (e.g. "paper_fog")
    n_samples : int
    seed : int
    true_rate_deg_s : float or array_like, optional
        True angular rate (deg/s) added to the sensor errors; default 0.
    restarts : array_like of bool, optional
        True where the gyro restarts (fresh turn-on bias, transient).

    Returns
    -------
    Record
        With ``true_rate_deg_s`` always set (zeros when not given).
    """
    card = load_card(card)
    n = int(n_samples)
    if n < 1:
        raise InputError(f"n_samples must be >= 1, got {n_samples!r}")
    stream = SimStream(card, seed=seed)
    truth = np.zeros(n) if true_rate_deg_s is None else np.broadcast_to(
        np.asarray(true_rate_deg_s, dtype=float), (n,)).copy()
    rs = None if restarts is None else np.asarray(restarts, dtype=bool)
    if rs is not None and rs.shape != (n,):
        raise InputError(f"restarts must be one bool per sample ({n}), got shape {rs.shape}")
    y = stream.run(n, truth, rs)
    return Record(rate_deg_s=y, sample_rate_hz=card.sample_rate_hz, true_rate_deg_s=truth,
                  restarts=rs, source=f"simulated:{card.name}:seed={seed}")
