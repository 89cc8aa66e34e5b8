"""Model cards (TOML, spec section 4) and the simulated gyro.

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
angle_gauss_markov   deg, s          first-order GM ANGLE th_k = a th_(k-1) +
                                     sigma sqrt(1 - a^2) v_k, a = exp(-T/tau),
                                     differenced: rate_k += (th_k - th_(k-1))/T
                                     (white angle noise with a correlation
                                     time; tau -> 0 is quantization Q = sigma;
                                     its normals from a generator of its own)
===================  ==============  =========================================

Every noise term with a magnitude (Q, N, B, K, gauss_markov and angle_gauss_markov
sigma) may carry ``spread``: the relative 1-sigma of that magnitude between units or runs.
It is not simulated here (nor by the C core or the FMUs: they simulate the card's
values, one unit); the gap workflow's reference draws one unit per simulated record
(``modelgap.population.draw_unit``).

Time t counts from the start of the record; restarts reset only the turn-on
bias draw and the transient clock (the stochastic processes run on).

The model itself is ``gyrodenoise/core/gdsim.c`` (its plain-Python twin
``core/simkernels.py`` where the extension is not built): this module parses
cards and adapts. One seeded generator (xoshiro256**, see ``gdsim.h``) draws
the noise sample by sample, so streaming (`SimStream`, used by
SimulatedFog.fmu) and batch (`simulate`) give the same numbers, and so do
SimulatedFogNative.fmu and any C host of ``gdsim.c``.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .core import simkernels as SK
from .errors import InputError
from .units import NOISE_SECTIONS, TERM_BY_SECTION

# optional on a noise term: the relative 1-sigma of its magnitude between units/runs, drawn per
# simulated record by the gap workflow's reference (modelgap.population.draw_unit); simulate() and
# the FMUs simulate the card's value (one unit)
#: a field of a term: (required, minimum or None, unit)
FieldSpec: TypeAlias = "tuple[bool, float | None, str]"
SPREAD: FieldSpec = (False, 0.0, "(relative 1-sigma)")
SPREAD_GROUP: FieldSpec = (False, 0.0, "(terms with the same group number share one draw; 0: none)")


def _allan_field(section: str, minimum: float | None) -> dict[str, FieldSpec]:
    """{field: (required, minimum, unit)} of an Allan term's one field (its symbol, its unit)."""
    term = TERM_BY_SECTION[section]
    return {term.symbol: (True, minimum, term.unit)}


# term -> {field: (required, minimum, unit)}
TERM_FIELDS: dict[str, dict[str, FieldSpec]] = {
    **{nm: {**_allan_field(nm, 0.0), "spread": SPREAD, "spread_group": SPREAD_GROUP}
       for nm in NOISE_SECTIONS},
    "rate_ramp": _allan_field("rate_ramp", None),
    "constant_bias": {"value": (True, None, "deg/h"), "repeatability": (False, 0.0, "deg/h")},
    "turn_on_transient": {"amplitude": (True, None, "deg/h"), "tau": (True, 1e-300, "s")},
    "gauss_markov": {"sigma": (True, 0.0, "deg/h"), "tau": (True, 1e-300, "s"), "spread": SPREAD, "spread_group": SPREAD_GROUP},
    "sinusoid": {"amplitude": (True, None, "deg/h"), "frequency": (True, 0.0, "Hz"),
                 "phase_deg": (False, None, "deg")},
    "angle_gauss_markov": {"sigma": (True, 0.0, "deg"), "tau": (True, 1e-300, "s"), "spread": SPREAD, "spread_group": SPREAD_GROUP},
}
REPEATABLE = ("gauss_markov", "sinusoid", "angle_gauss_markov")
ABSURD = 1.0e9   # any card value beyond this is refused as absurd


@dataclass
class ModelCard:
    """A parsed, checked model card."""
    name: str
    sample_rate_hz: float
    terms: dict[str, Any]  # term -> dict of floats, or list of dicts (repeatable)
    text: str = ""         # the TOML source, comments included
    source: str = "<card>"

    def term_list(self, name: str) -> list[dict[str, float]]:
        """The instances of a term as a list (empty when absent)."""
        t = self.terms.get(name)
        if t is None:
            return []
        return t if isinstance(t, list) else [t]


#: a model card: parsed, or its path, or the name of an embedded card ("paper_fog")
CardLike: TypeAlias = "ModelCard | str | os.PathLike[str]"


def parse_card(text: str, source: str = "<card>") -> ModelCard:
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
    terms: dict[str, Any] = {}
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
            out: dict[str, float] = {}
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


def models_dir() -> Path:
    """Folder of the embedded model cards."""
    return Path(__file__).resolve().parent / "data"


def load_card(path_or_name: CardLike) -> ModelCard:
    """Read a card from a path, or by name from the cards embedded in the package
    (`models_dir`: ``paper_fog``, ``ln200``, ...)."""
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
def _core() -> Any:
    """The compiled sensor model (gdsim.c through the extension), or None."""
    try:
        from .core import _gdcore  # type: ignore[attr-defined]  # the compiled extension
    except ImportError:
        return None
    return _gdcore if hasattr(_gdcore, "sim_run") else None


def _bank(card: CardLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """AR(1) bank [a_j], [g_j], [stationary std_j] in deg/s for one sample period:
    flicker poles, Gauss-Markov terms, rate random walk (the model's parameters,
    ``simkernels.params``)."""
    p = SK.params(SK.card_vector(load_card(card)), 0)
    nb = int(p[SK.PS_NBANK])
    bank = np.array(p[SK.PS_BANK:SK.PS_BANK + 3 * nb], dtype=float).reshape(nb, 3)
    return bank[:, 0].copy(), bank[:, 1].copy(), bank[:, 2].copy()


class SimStream:
    """A simulated gyro, sample by sample or block by block (same numbers).

    An adapter over the one sensor model, ``gyrodenoise/core/gdsim.c`` (the
    compiled extension), or its plain-Python specification
    ``gyrodenoise/core/simkernels.py`` (bit for bit the same numbers, ~160x
    slower per sample on paper_fog) where the extension is not built.
    Parameters and state are the model's flat float buffers (``gdsim.h``).

    Parameters
    ----------
    card : ModelCard or path
    seed : int, 0 <= seed < 2**53
    """

    def __init__(self, card: CardLike, seed: int = 0) -> None:
        self.card = load_card(card)
        if isinstance(seed, bool) or int(seed) != seed or not 0 <= int(seed) < 2 ** 53:
            raise InputError(f"seed must be a whole number from 0 to 2**53 - 1, got {seed!r}")
        self.seed = int(seed)
        try:
            v = SK.card_vector(self.card)
        except ValueError as exc:
            raise InputError(str(exc), self.card.source) from None
        self._C = _core()
        self.p: Any
        self.s: Any     # the model's state buffer: an array (compiled) or a list (plain Python)
        if self._C is not None:
            v = np.array(v)
            self.p = np.zeros(self._C.sim_n_params(v))
            self._C.sim_params(v, float(self.seed), self.p)
            self.s = np.zeros(self._C.sim_n_state(self.p))
        else:
            self.p = SK.params(v, self.seed)
            self.s = [0.0] * SK.n_state(self.p)
        self.reset()

    @property
    def compiled(self) -> bool:
        """True if this stream runs gdsim.c (else the plain-Python twin, same numbers)."""
        return self._C is not None

    def reset(self) -> None:
        """Back to the start (seeded generators, stationary bank, first bias draw)."""
        if self._C is not None:
            self._C.sim_reset(self.p, self.s)
        else:
            SK.reset(self.p, self.s)

    def step(self, true_rate_deg_s: float = 0.0, restart: bool = False) -> float:
        """One measured sample (deg/s) for the true rate (deg/s)."""
        if self._C is None:
            return SK.step(self.p, self.s, float(true_rate_deg_s), bool(restart))
        out = np.empty(1)
        self._C.sim_run(self.p, self.s, np.array([float(true_rate_deg_s)]), np.array([bool(restart)]), out)
        return float(out[0])

    def run(self, n_samples: int, true_rate_deg_s: npt.ArrayLike | None = None,
            restarts: npt.ArrayLike | None = None) -> np.ndarray:
        """``n_samples`` measured samples (deg/s) at once, continuing the stream."""
        n = int(n_samples)
        truth = None if true_rate_deg_s is None else np.ascontiguousarray(
            np.broadcast_to(np.asarray(true_rate_deg_s, dtype=float), (n,)))
        rs = None if restarts is None else np.ascontiguousarray(restarts, dtype=bool)
        if self._C is None:
            return np.array(SK.run(self.p, self.s, n, truth, rs), dtype=float)
        out = np.empty(n)
        self._C.sim_run(self.p, self.s, truth, rs, out)
        return out

    # -- state save / restore (for FMU state and tests): the state buffer, as floats
    def get_state(self) -> list[float]:
        return [float(x) for x in self.s]

    def set_state(self, st: list[float]) -> None:
        if len(st) != len(self.s):
            raise ValueError(f"simulator state has {len(st)} values, this card needs {len(self.s)}")
        for i, x in enumerate(st):
            self.s[i] = float(x)


@dataclass
class Record:
    """A gyro record: rate in deg/s at a fixed sample rate."""
    rate_deg_s: np.ndarray
    sample_rate_hz: float
    time_s: np.ndarray = None  # type: ignore[assignment]  # left out: arange(n) / sample_rate_hz
    true_rate_deg_s: np.ndarray | None = None
    restarts: np.ndarray | None = None
    source: str = ""
    notes: list[str] = field(default_factory=list)   # repairs and remarks, reported
    unit: str = "deg/s"        # the unit the file's column was read in (a reader's record; deg/s otherwise)
    unit_how: str = ""         # how the reader decided it ("as stated", "as its units row says", "assumed; ...")

    def __post_init__(self) -> None:
        if self.time_s is None:
            self.time_s = np.arange(len(self.rate_deg_s)) / self.sample_rate_hz

    def __len__(self) -> int:
        return len(self.rate_deg_s)


def simulate(card: CardLike, n_samples: int, seed: int = 0, true_rate_deg_s: npt.ArrayLike | None = None,
             restarts: npt.ArrayLike | None = None) -> Record:
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
