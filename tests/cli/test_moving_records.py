"""allan, compare and denoise on a record that moves (a true_rate column): allan analyses
the sensor's error (rate - true_rate), compare warns, denoise prints the RMSE against the
true rate."""
import json

import numpy as np
import pytest

from tests.helpers import assert_golden, run_main


def _moving_csv(path, n=12_000, fs=100.0, true_rate=True):
    """paper_fog (seeded) under +-70 deg/s of smooth motion, and the same sensor at rest."""
    import gyrodenoise as gd
    from benchmarks import profiles
    tr = profiles.smooth(n, fs, seed=3)
    rec = gd.simulate("paper_fog", n, seed=5, true_rate_deg_s=tr)
    still = gd.simulate("paper_fog", n, seed=5)
    cols = [np.arange(n) / fs, rec.rate_deg_s] + ([tr] if true_rate else [])
    np.savetxt(path, np.column_stack(cols), delimiter=",", comments="", fmt="%.12g",
               header="time,rate" + (",true_rate" if true_rate else ""))
    return tr, still


@pytest.mark.golden
def test_allan_of_a_moving_record_analyses_rate_minus_true_rate(tmp_path):
    """With true_rate present allan analyses the sensor's error and says so: its N and
    K equal those of the same sensor simulated at rest (same seed; independent
    reference) within 1e-6, where the measured rate alone gives K ~ 1e6 deg/h^1.5. The
    whole JSON (what was analysed, the motion's figures, every term) is the reviewed
    tests/golden/allan_moving_record.json."""
    from gyrodenoise.analysis.allan import allan
    path = tmp_path / "moving.csv"
    _, still = _moving_csv(path)
    st, out, _ = run_main("allan", path, "--json")
    assert st == 0
    d = json.loads(out)
    assert_golden("allan_moving_record", d, {tmp_path: "<tmp>"})
    assert d["true_rate_motion_deg_s"]["std"] > 5.0
    ref = allan(still.rate_deg_s, 100.0)
    for t in ("N", "K"):
        assert d["terms"][t] == pytest.approx(ref.terms[t], rel=1e-6), t
    st, text, _ = run_main("allan", path)
    assert text.startswith("analysed: rate - true_rate")


@pytest.mark.golden
def test_compare_of_a_moving_record_warns(tmp_path):
    """compare's JSON on a moving record (its warning, the RMSE against the true rate, every
    row) is the reviewed tests/golden/compare_moving_record.json; the text says it too."""
    path = tmp_path / "moving.csv"
    _moving_csv(path)
    st, out, _ = run_main("compare", path, "--json")
    assert st == 0
    d = json.loads(out)
    assert_golden("compare_moving_record", d, {tmp_path: "<tmp>"})
    assert len(d["warnings"]) == 1
    st, text, _ = run_main("compare", path)
    assert "WARNING: the record moves (true_rate" in text


def test_compare_of_a_still_record_does_not_warn(tmp_path):
    import gyrodenoise as gd
    rec = gd.simulate("paper_fog", 12_000, seed=5, true_rate_deg_s=2.0)
    path = tmp_path / "still.csv"
    np.savetxt(path, np.column_stack([np.arange(12_000) / 100.0, rec.rate_deg_s, rec.true_rate_deg_s]),
               delimiter=",", header="time,rate,true_rate", comments="", fmt="%.12g")
    st, out, _ = run_main("compare", path, "--json")
    assert st == 0 and "warnings" not in json.loads(out)


def test_denoise_with_true_rate_prints_rmse_raw_and_filtered(tmp_path):
    """The RMSE line's figures equal numpy's RMSE of the written CSV's columns (4 digits)."""
    import re
    path = tmp_path / "moving.csv"
    _moving_csv(path)
    out = tmp_path / "out.csv"
    st, _, err = run_main("denoise", path, "-o", out)
    assert st == 0
    m = re.search(r"RMSE against true_rate over (\d+) samples: raw (\S+), filtered (\S+) deg/s", err)
    assert m, err
    a = np.genfromtxt(out, delimiter=",", names=True)
    assert int(m.group(1)) == len(a)
    assert float(m.group(2)) == pytest.approx(np.sqrt(np.mean((a["raw"] - a["true_rate"]) ** 2)), rel=1e-3)
    assert float(m.group(3)) == pytest.approx(np.sqrt(np.mean((a["filtered"] - a["true_rate"]) ** 2)), rel=1e-3)
