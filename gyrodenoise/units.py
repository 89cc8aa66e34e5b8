"""Units: the one home of the rate units and of the Allan noise terms' names and units.

Inside, rates are deg/s and times s. A rate read in another unit is multiplied by
`RATE_TO_DEG_S` of that unit (recordings' ``--rate-unit``, published Allan
curves' ``--allan-unit``, the flight logs' field units).

The Allan noise terms (IEEE Std 952-1997, Annex C; Sun et al. 2016, Eq. (40)) are
named three ways: a symbol (``N``), a model card's section (``angle_random_walk``)
and a unit in the spec (``deg/sqrt(h)``). `ALLAN_TERMS` holds the three and
the factor from the s-based value (deg/s, s) to the spec's unit; everything else
(the Allan fit's output, the CLI's table, the model cards, the model-gap workflow)
derives its names, labels and factors from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

RAD_TO_DEG = 180.0 / math.pi
MRAD_TO_DEG = RAD_TO_DEG / 1000.0

#: rate unit label -> factor to deg/s
RATE_TO_DEG_S: dict[str, float] = {"deg/s": 1.0, "deg/h": 1.0 / 3600.0, "rad/s": RAD_TO_DEG,
                                   "mrad/s": MRAD_TO_DEG}

#: standard gravity, m/s^2 (the "g" of accelerometer datasheets)
STANDARD_GRAVITY = 9.80665
#: acceleration unit label -> factor to m/s^2 (the accelerometer columns' ``--accel-unit``)
ACCEL_TO_M_S2: dict[str, float] = {"m/s^2": 1.0, "g": STANDARD_GRAVITY, "mg": STANDARD_GRAVITY / 1000.0}


@dataclass(frozen=True)
class AllanTerm:
    """One term of the five-term Allan model."""
    symbol: str        #: "N"
    section: str       #: the model card's [terms] section, "angle_random_walk"
    unit: str          #: the spec's unit, "deg/sqrt(h)"
    to_spec: float     #: value in s-based units (deg/s, s) * to_spec = value in the spec's unit
    adev_slope: float  #: log-log slope of its Allan deviation
    stochastic: bool = True   #: False: a deterministic term (the rate ramp)


#: the five terms in the order of Eq. (40) and of every table and JSON output
ALLAN_TERMS: tuple[AllanTerm, ...] = (
    AllanTerm("N", "angle_random_walk", "deg/sqrt(h)", 60.0, -0.5),
    AllanTerm("B", "bias_instability", "deg/h", 3600.0, 0.0),
    AllanTerm("K", "rate_random_walk", "deg/h^1.5", 3600.0 ** 1.5, 0.5),
    AllanTerm("R", "rate_ramp", "deg/h^2", 3600.0 ** 2, 1.0, stochastic=False),
    AllanTerm("Q", "quantization", "deg", 1.0, -1.0),
)
#: symbol -> term, card section -> term
TERM_BY_SYMBOL: dict[str, AllanTerm] = {t.symbol: t for t in ALLAN_TERMS}
TERM_BY_SECTION: dict[str, AllanTerm] = {t.section: t for t in ALLAN_TERMS}
#: the symbols in Eq. (40) order: N, B, K, R, Q
TERM_SYMBOLS: tuple[str, ...] = tuple(t.symbol for t in ALLAN_TERMS)
#: the card sections of the stochastic Allan-shaped terms, short tau first: quantization,
#: angle_random_walk, bias_instability, rate_random_walk
NOISE_SECTIONS: tuple[str, ...] = tuple(t.section for t in sorted(ALLAN_TERMS, key=lambda t: t.adev_slope)
                                        if t.stochastic)


#: an accelerometer's Allan terms: the gyro's numbers (an acceleration in m/s^2 where the gyro's
#: rate is in deg/s) with m/s in place of deg, and their names: symbol -> (name, unit)
ACCEL_TERMS: dict[str, tuple[str, str]] = {
    "N": ("velocity random walk", "m/s/sqrt(h)"), "B": ("bias instability", "m/s/h"),
    "K": ("acceleration random walk", "m/s/h^1.5"), "R": ("acceleration ramp", "m/s/h^2"),
    "Q": ("velocity quantization", "m/s")}
