"""edit_card keeps a card's comments (its docstring: "Comments and order are kept"): every
comment of the input, whole-line or trailing, in every table (the header, [sensor], [terms],
a [terms.x] sub-table, a [[terms.x]] array table), is in the card after each kind of edit
(a term added inline, re-fitted inline, re-fitted in its sub-table, a repeatable one
added, a term removed), and the lines the edits do not touch are unchanged and in order."""

from __future__ import annotations

import pytest

from gyrodenoise.modelgap import edit_card
from gyrodenoise.simulator import parse_card

CARD = """# header comment: the unit's datasheet, 2024
[sensor]   # the bench unit
name = "commented"   # its name
# a comment line inside [sensor]
sample_rate_hz = 100.0

[terms]   # the noise terms
# a comment line inside [terms]
angle_random_walk = { N = 0.1 }   # deg/sqrt(h), from the datasheet
quantization = { Q = 3.0e-4 }   # deg, from the ADC's LSB

[terms.bias_instability]   # measured on the bench
# a comment line inside a sub-table
B = 0.02   # deg/h

[terms.rate_random_walk]   # removed by the edits below
# a comment line inside the removed table
K = 0.001   # deg/h/sqrt(h)

[[terms.sinusoid]]   # the pump's line
# a comment line inside an array table
amplitude = 1.0
frequency = 2.0   # Hz
"""

#: the lines a re-fit rewrites (their values change)
REWRITTEN = ("angle_random_walk = ", "B = ")
#: the lines the removals comment out (kept, with their comments, behind "# ")
REMOVED = ("quantization = ", "[terms.rate_random_walk]", "# a comment line inside the removed", "K = ")

EDITS = (("constant_bias", {"value": 1.5}, False),
         ("angle_random_walk", {"N": 0.2}, True),
         ("bias_instability", {"B": 0.03}, True),
         ("gauss_markov", {"sigma": 2.0, "tau": 3.0}, False),
         ("quantization", None, True),
         ("rate_random_walk", None, True))


def _comment(line):
    """The comment of a line (from its first '#': the cards here have none in strings)."""
    return line[line.index("#"):] if "#" in line else None


def _edited():
    text = CARD
    for name, params, refit in EDITS:
        text = edit_card(text, name, params, refit=refit, source="c.toml")
    return text


def test_every_comment_and_untouched_line_is_kept_in_order():
    new = _edited()
    terms = parse_card(new).terms
    assert terms["angle_random_walk"] == {"N": 0.2} and terms["bias_instability"] == {"B": 0.03}
    assert "quantization" not in terms and "rate_random_walk" not in terms
    assert terms["constant_bias"] == {"value": 1.5}
    out = new.splitlines()
    kept = [ln for ln in CARD.splitlines() if not ln.startswith(REWRITTEN + REMOVED)]
    # the untouched lines, verbatim (trailing comments and spacing too) and in their order
    at = -1
    for ln in kept:
        assert ln in out[at + 1:], f"not kept, or out of order: {ln!r}"
        at = out.index(ln, at + 1)
    # the removed terms' lines, commented out with their own comments, in order
    at = -1
    for ln in CARD.splitlines():
        if ln.startswith(REMOVED):
            hit = [i for i, o in enumerate(out) if i > at and o.startswith("# " + ln.strip())]
            assert hit, f"not commented out with its comment: {ln!r}"
            at = hit[0]
    # every whole-line comment of the input kept as it was, once
    for ln in CARD.splitlines():
        if ln.lstrip().startswith("#") and not ln.startswith(REMOVED):
            assert out.count(ln) == 1, ln


@pytest.mark.xfail(strict=True, reason="edit_card rewrites a re-fitted line whole: the user's trailing "
                                       "comment on it ('# deg/sqrt(h), from the datasheet', '# deg/h') is "
                                       "lost (gyrodenoise/modelgap/cards.py _edit_lines)")
def test_a_refitted_line_keeps_its_own_comment():
    new = _edited()
    for ln in CARD.splitlines():
        if ln.startswith(REWRITTEN):
            assert _comment(ln) in new, ln
