"""gyrodenoise.units is the one home of the rate units and of the Allan terms: every reader,
the Allan fit, the model cards and the model-gap workflow agree with it (independent
references: the definitions of the units, pi/180 and 3600 s per hour, written here)."""
import math

import numpy as np
import pytest

from gyrodenoise.units import ALLAN_TERMS, NOISE_SECTIONS, RATE_TO_DEG_S, TERM_BY_SECTION, TERM_SYMBOLS

# independent of the package: 1 rad = 180/pi deg, 1 h = 3600 s
DEG_S_OF = {"deg/s": 1.0, "deg/h": 1.0 / 3600.0, "rad/s": 180.0 / math.pi, "mrad/s": 0.18 / math.pi}
# s-based value (deg/s, s) -> spec unit: N deg/sqrt(s) -> deg/sqrt(h) is sqrt(3600) = 60, ...
SPEC = {"N": ("deg/sqrt(h)", 60.0), "B": ("deg/h", 3600.0), "K": ("deg/h^1.5", 3600.0 ** 1.5),
        "R": ("deg/h^2", 3600.0 ** 2), "Q": ("deg", 1.0)}


def test_rate_units_are_their_definitions():
    assert set(RATE_TO_DEG_S) == set(DEG_S_OF)
    for unit, k in RATE_TO_DEG_S.items():
        assert k == pytest.approx(DEG_S_OF[unit], rel=1e-15), unit


@pytest.mark.parametrize("unit", sorted(DEG_S_OF))
def test_recording_and_curve_readers_scale_by_the_unit(tmp_path, unit):
    from gyrodenoise.io.recording import read_recording
    from gyrodenoise.modelgap.curve import read_allan_curve
    rec_csv = tmp_path / "rec.csv"
    rec_csv.write_text("time,rate\n0,1.5\n0.01,-2.0\n0.02,0.25\n")
    rec = read_recording(rec_csv, rate_unit=unit)
    np.testing.assert_allclose(rec.rate_deg_s, np.array([1.5, -2.0, 0.25]) * DEG_S_OF[unit], rtol=1e-15)
    curve_csv = tmp_path / "curve.csv"
    curve_csv.write_text("tau_s,allan_deviation\n0.1,2.0\n1.0,1.0\n10.0,0.5\n")
    curve = read_allan_curve(curve_csv, unit=unit, sample_rate_hz=100.0, n_samples=10_000)
    np.testing.assert_allclose(curve.adev_deg_s, np.array([2.0, 1.0, 0.5]) * DEG_S_OF[unit], rtol=1e-15)


def test_allan_terms_units_and_factors():
    assert TERM_SYMBOLS == ("N", "B", "K", "R", "Q")          # Eq. (40)'s order, the tables' rows
    for t in ALLAN_TERMS:
        assert (t.unit, t.to_spec) == (SPEC[t.symbol][0], pytest.approx(SPEC[t.symbol][1], rel=1e-15))
    assert NOISE_SECTIONS == ("quantization", "angle_random_walk", "bias_instability", "rate_random_walk")


def test_allan_result_reports_the_spec_units_and_scales_by_them():
    from gyrodenoise.analysis.allan import allan
    y = np.random.default_rng(7).normal(0.0, 0.05, 20_000)       # white rate noise, deg/s
    res = allan(y, 100.0)
    assert res.to_json()["units"] == {s: SPEC[s][0] for s in TERM_SYMBOLS}
    for s in TERM_SYMBOLS:
        assert res.terms[s] == pytest.approx(res.terms_s[s] * SPEC[s][1], rel=1e-15)
    # N of white noise of std sigma at fs: sigma / sqrt(fs) deg/sqrt(s), x 60 in deg/sqrt(h)
    assert res.terms["N"] == pytest.approx(0.05 / math.sqrt(100.0) * 60.0, rel=0.05)


def test_model_cards_state_the_allan_terms_units():
    from gyrodenoise.simulator import TERM_FIELDS
    for section, term in TERM_BY_SECTION.items():
        required, _, unit = TERM_FIELDS[section][term.symbol]
        assert required and unit == SPEC[term.symbol][0], section


def test_kalibr_export_converts_with_the_spec_factors():
    from gyrodenoise.io.export import terms_to_si
    si = terms_to_si({"N": 0.1, "B": 2.0, "K": 3.0, "R": 4.0, "Q": 5.0})
    deg = math.pi / 180.0
    assert si["N_rad_sqrt_s"] == pytest.approx(0.1 * deg / 60.0, rel=1e-15)
    assert si["B_rad_s"] == pytest.approx(2.0 * deg / 3600.0, rel=1e-15)
    assert si["K_rad_s1_5"] == pytest.approx(3.0 * deg / 3600.0 ** 1.5, rel=1e-15)
    assert si["R_rad_s2"] == pytest.approx(4.0 * deg / 3600.0 ** 2, rel=1e-15)
    assert si["Q_rad"] == pytest.approx(5.0 * deg, rel=1e-15)
