"""SimulatedFogNative.fmu: the model-card gyro as a native FMI 2.0 co-simulation FMU.

No Python and no libpython at run time: the binary is the project's sensor model
(``gyrodenoise/core/gdsim.c``, the C that ``gyrodenoise.simulate`` and the pythonfmu
``SimulatedFog.fmu`` run) behind the shared FMI layer (``gyrodenoise/fmu/sources/native/gdfmi.c``) and
its hooks (``gyrodenoise/fmu/sources/native/simulatedfog_native.c``). Same variables (names, types,
causality, variability, units, start values) as ``SimulatedFog.fmu``, declared in
:data:`gyrodenoise.fmu.variables.SIMULATED_FOG_NATIVE`; same card and
seed: same numbers as ``gyrodenoise.simulate``.

The card. TOML is parsed here in Python, so the FMU reads a *compiled* card: the card
vector (``simkernels.card_vector``, card units) one field a line, each value as the hex
digits of its IEEE 754 bits (exact on every platform) with the decimal value beside it.
:func:`compile_card` writes it; the build bundles every card of ``gyrodenoise/data``
as ``resources/cards/NAME.gdcard`` (the FMU's ``card`` parameter takes the name, a
compiled card file's path, or the compiled text).

>>> from gyrodenoise.fmu.simnative import compile_card
>>> compile_card("paper_fog").splitlines()[0]
'gdcard 1 125'
"""

from __future__ import annotations

import struct
from pathlib import Path

from gyrodenoise.core import simkernels as SK
from gyrodenoise.errors import InputError
from gyrodenoise.fmu.nativemodel import CORE_DIR, PACKAGE_DIR, NativeModel
from gyrodenoise.fmu.variables import DEFAULT_STEP_SIZE_S, SIMULATED_FOG_NATIVE as VARIABLES, UNITS

MODEL_NAME = "SimulatedFogNative"
CARD_FORMAT = 1
R = SK.MAX_REPEAT
#: names of the card vector's fields (simkernels.card_vector), in its order
CARD_FIELDS = (("sample_rate_hz", "Q", "N", "B", "K", "R", "bias", "bias_rep", "tr_amp", "tr_tau", "n_gm",
                "n_sin")
               + tuple(f"{col}_{i + 1}" for col in ("gm_sigma", "gm_tau", "sin_amp", "sin_f", "sin_phase_deg")
                       for i in range(R))
               + ("n_agm",) + tuple(f"{col}_{i + 1}" for col in ("agm_sigma", "agm_tau") for i in range(R)))


def _check_layout():
    if len(CARD_FIELDS) != SK.CARD_LEN:    # a programming error, not the user's: loud, not a skip
        raise RuntimeError(f"the card vector has {SK.CARD_LEN} fields, {MODEL_NAME} knows {len(CARD_FIELDS)}: "
                           "update gyrodenoise/fmu/simnative.py CARD_FIELDS, gdsim.c (gd_sim_card_from_vector) "
                           "and simulatedfog_native.c (check_vector)")


#: the card parameter's text, at most (gyrodenoise/fmu/sources/native/simulatedfog_native.c: CARD_LEN - 1)
CARD_TEXT_MAX = 8191
#: the card's name and file in the compiled card's comment line, at most (characters)
CARD_COMMENT_MAX = 200


#: the separator of the fields in the one-line form of a compiled card (no comma, semicolon,
#: quote or tab: a CSV or TSV writer that does not quote keeps it in one cell)
ONE_LINE_SEPARATOR = " | "


def compile_card(card, one_line=False):
    """The compiled card (text) of ``card`` (a ModelCard, a card path or a bundled name).

    ``one_line=True``: the same fields on one line, separated by ``' | '``, without the
    comment lines (``gdcard 1 125 | sample_rate_hz 0x4069000000000000 200.0 | ...``): the form
    for a parameter value that ends up in a host's result file."""
    from gyrodenoise.simulator import load_card
    from gyrodenoise._version import __version__
    _check_layout()
    card = load_card(card)
    try:
        v = SK.card_vector(card)
    except ValueError as exc:
        raise InputError(str(exc), card.source) from None
    what = " ".join(f"{card.name} ({Path(card.source).name})".split())   # one line
    if len(what) > CARD_COMMENT_MAX:        # a long card name would push the text past the
        what = what[:CARD_COMMENT_MAX - 3] + "..."   # FMU's card buffer (CARD_TEXT_MAX)
    lines = [f"gdcard {CARD_FORMAT} {len(v)}",
             f"# {what}, compiled by gyrodenoise {__version__} for {MODEL_NAME}:",
             "# the card vector (simkernels.card_vector, card units): field, IEEE 754 bits, value"]
    for name, x in zip(CARD_FIELDS, v):
        bits = struct.unpack("<Q", struct.pack("<d", float(x)))[0]
        lines.append(f"{name} 0x{bits:016x} {float(x)!r}")
    if one_line:
        text = ONE_LINE_SEPARATOR.join(line for line in lines if not line.startswith("#"))
    else:
        text = "\n".join(lines) + "\n"
    if len(text) > CARD_TEXT_MAX:           # cannot happen with CARD_COMMENT_MAX (worst case ~7,300)
        raise InputError(f"the compiled card is {len(text)} characters long, the FMU takes at most "
                         f"{CARD_TEXT_MAX}", card.source)
    return text


def bundled_cards():
    """{name: path} of the cards bundled in the FMU (the package's model cards)."""
    return {p.stem: p for p in sorted((PACKAGE_DIR / "data").glob("*.toml"))}


def _fields(compiled):
    """The field lines of a compiled card (its comment lines left out)."""
    return [line for line in compiled.splitlines() if not line.startswith("#")]


def bundled_name(card):
    """The name of the bundled card that ``card`` (a ModelCard, a card path or a bundled name)
    is, or None: a bundled card with the same card vector (same numbers), whatever the file it
    was read from (the bundled card of the same file name first)."""
    from gyrodenoise.simulator import load_card
    card = load_card(card)
    fields = _fields(compile_card(card))
    stem = Path(str(card.source)).stem
    for name, path in sorted(bundled_cards().items(), key=lambda item: item[0] != stem):
        if _fields(compile_card(path)) == fields:
            return name
    return None


def _resources():
    return {f"cards/{name}.gdcard": compile_card(path).encode() for name, path in bundled_cards().items()}


def _header_lines():
    _check_layout()
    names = ", ".join(f'"{n}"' for n in CARD_FIELDS)
    return (f"#define GD_CARD_LEN {len(CARD_FIELDS)}",
            f"#define GD_CARD_FIELDS {{{names}}}",
            f'#define GD_BUNDLED_CARDS "{", ".join(bundled_cards())}"')


SIMULATED_FOG_NATIVE = NativeModel(
    MODEL_NAME,
    "Simulated gyro from a gyrodenoise model card (compiled, see the card parameter): measured_rate = "
    "true_rate + sensor errors, the sensor model gdsim.c (same numbers as gyrodenoise.simulate), native C: "
    "no Python needed. One communication step = one sample.",
    VARIABLES, DEFAULT_STEP_SIZE_S, "simulatedfog_native.c", "simulatedfog_native_all.c",
    (CORE_DIR / "gdsim.c", CORE_DIR / "gdsim.h"), {"deg/s": UNITS["deg/s"]},
    header_lines=_header_lines, resources=_resources)

