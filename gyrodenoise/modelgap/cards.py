"""Model cards as text: re-parse at a record's rate, add or re-fit a term in place."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import TYPE_CHECKING

from gyrodenoise.errors import InputError

if TYPE_CHECKING:
    from gyrodenoise.simulator import ModelCard


# ------------------------------------------------------------------ cards as text
def _fmt_num(v: float) -> str:
    return f"{float(v):.6g}"


def card_at_rate(text: str, fs: float, source: str = "<card>") -> ModelCard:
    """Parse a card's text as simulated at ``fs`` Hz (the record's rate).

    The text is re-parsed through `gyrodenoise.simulator.parse_card`
    with ``sensor.sample_rate_hz`` set to ``fs``, so every rate-dependent
    check (a sinusoid above the record's Nyquist frequency) applies at the
    rate the card is actually simulated at; the error names ``source``.
    """
    from dataclasses import replace

    from gyrodenoise.simulator import parse_card
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


def text_at_rate(text: str, fs: float) -> str:
    """The card text with sensor.sample_rate_hz set to ``fs`` (for the FMU's String parameter)."""
    new, n = re.subn(r"(?m)^(\s*sample_rate_hz\s*=\s*)[^#\n]*", lambda mo: mo.group(1) + repr(float(fs)) + " ",
                     text, count=1)
    return new if n else text


def _table_range(lines: list[str], i: int) -> tuple[int, int]:
    """(start, end) of the body of the table whose header is line ``i``."""
    header = re.compile(r"^\s*\[")
    end = next((j for j in range(i + 1, len(lines)) if header.match(lines[j])), len(lines))
    return i + 1, end


def _last_content(lines: list[str], lo: int, hi: int, default: int) -> int:
    return max([j for j in range(lo, hi) if lines[j].strip() and not lines[j].lstrip().startswith("#")],
               default=default)


def _remove_lines(lines: list[str], name: str, note: str) -> list[str]:
    """Comment out every instance of terms.name: its inline line in [terms], its
    [terms.name] table or its [[terms.name]] tables with their bodies."""
    out: list[str] = []
    i = 0
    table = re.compile(rf"^\s*\[\[?\s*terms\s*\.\s*{re.escape(name)}\s*\]\]?\s*(#.*)?$")
    inline = re.compile(rf"^\s*{re.escape(name)}\s*=")
    in_terms = False
    while i < len(lines):
        ln = lines[i]
        if table.match(ln):
            lo, hi = _table_range(lines, i)
            out += [f"# {ln.strip()}    # removed, {note}"] + [f"# {b.strip()}" if b.strip() else b
                                                                for b in lines[lo:hi]]
            i = hi
            continue
        if re.match(r"^\s*\[", ln):
            in_terms = bool(re.match(r"^\s*\[\s*terms\s*\]\s*(#.*)?$", ln))
        elif in_terms and inline.match(ln):
            ln = f"# {ln.strip()}    # removed, {note}"
        out.append(ln)
        i += 1
    return out


def _edit_lines(lines: list[str], name: str, params: Mapping[str, float] | None, refit: bool,
                note: str) -> list[str]:
    """The edit itself (see `edit_card`); returns the new list of lines."""
    from gyrodenoise.simulator import REPEATABLE
    if params is None:
        return _remove_lines(lines, name, note)
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


def _holds(text: str, name: str, params: Mapping[str, float] | None, n_before: int) -> bool:
    """Does the card text parse as TOML with terms.name holding ``params`` (the last
    instance, one more than ``n_before``, for a repeatable term)?"""
    import tomllib

    from gyrodenoise.simulator import REPEATABLE
    try:
        t = tomllib.loads(text).get("terms", {}).get(name)
    except tomllib.TOMLDecodeError:
        return False
    if params is None:
        return t is None
    if name in REPEATABLE:
        if not isinstance(t, list) or len(t) != n_before + 1:
            return False
        t = t[-1]
    if not isinstance(t, dict) or set(t) != set(params):
        return False
    return all(math.isclose(float(t[k]), float(v), rel_tol=1e-5, abs_tol=1e-300) for k, v in params.items())


def _n_instances(text: str, name: str) -> int:
    import tomllib
    try:
        t = tomllib.loads(text).get("terms", {}).get(name)
    except tomllib.TOMLDecodeError:
        return 0
    return 0 if t is None else len(t) if isinstance(t, list) else 1


def edit_card(text: str, name: str, params: Mapping[str, float] | None, refit: bool = False,
              note: str = "fitted by gyrodenoise gap", source: str = "<card>") -> str:
    """Add a term to (or replace a re-fitted term in, or with ``params=None`` remove
    every instance of a term from) the TEXT of a card.

    Comments and order are kept. A non-repeatable term becomes an inline-table
    line in ``[terms]`` (replacing its old line when ``refit``), or, when the
    card writes it as a ``[terms.name]`` sub-table, that sub-table's fields are
    rewritten in place (fields the new fit does not set are commented out). A
    repeatable one (gauss_markov, sinusoid, angle_gauss_markov) becomes a new ``[[terms.name]]``
    table at the end. The edited text is checked by parsing it back: the term
    must then hold exactly ``params``; a layout this function cannot edit
    (e.g. a term written as dotted keys ``name.N = ...`` or a repeatable term
    written as an inline array) raises `InputError` naming ``source``
    and the term.
    """
    new = "\n".join(_edit_lines(text.splitlines(), name, params, refit, note)) + "\n"
    if not _holds(new, name, params, _n_instances(text, name)):
        raise InputError(f"cannot rewrite terms.{name} in the way this card writes it (supported: an "
                         f"inline table `{name} = {{ ... }}` in [terms], a [terms.{name}] table, or "
                         f"[[terms.{name}]] tables for gauss_markov/sinusoid/angle_gauss_markov); rewrite the card in one "
                         f"of those forms", source)
    return new


# parameters that exercise edit_card on every term of the vocabulary (check_editable)
_PROBE_PARAMS = {"quantization": {"Q": 1e-4}, "angle_random_walk": {"N": 0.1}, "bias_instability": {"B": 0.1},
          "rate_random_walk": {"K": 0.1}, "rate_ramp": {"R": 1.0}, "constant_bias": {"value": 1.0},
          "turn_on_transient": {"amplitude": 1.0, "tau": 10.0}, "gauss_markov": {"sigma": 1.0, "tau": 1.0},
          "sinusoid": {"amplitude": 1.0, "frequency": 1e-3, "phase_deg": 0.0},
          "angle_gauss_markov": {"sigma": 1e-4, "tau": 0.1}}


def check_editable(card: ModelCard) -> None:
    """Raise `InputError` up front (naming the card and the term) when
    `edit_card` cannot add or re-fit some term of the vocabulary in the
    way this card is written."""
    from gyrodenoise.simulator import parse_card
    for name, params in _PROBE_PARAMS.items():
        new = edit_card(card.text, name, params, refit=name in card.terms, source=card.source)
        parse_card(new, card.source)
