"""The command line: contracts of spec sections 1-3 and the bad-input rules."""
import json
import subprocess
import sys

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.cli import main
from tests.helpers import assert_golden, main_in_process


def run_cli(*args):
    """Run the real console entry in a subprocess: (status, stdout, stderr)."""
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", *map(str, args)],
                       capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout, p.stderr


@pytest.fixture(scope="module")
def sim_csv(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    rec = gd.simulate("paper_fog", 40_000, seed=5, true_rate_deg_s=2.0)
    path = d / "sim.csv"
    np.savetxt(path, np.column_stack([rec.time_s, rec.rate_deg_s, rec.true_rate_deg_s]),
               delimiter=",", header="time,rate,true_rate", comments="", fmt="%.12g")
    return path, rec


def test_denoise_writes_time_raw_filtered_true(sim_csv, tmp_path):
    path, rec = sim_csv
    out = tmp_path / "out.csv"
    assert main(["denoise", str(path), "-o", str(out), "--method", "shakf"]) == 0
    with open(out) as f:
        assert f.readline().strip() == "time,raw,filtered,true_rate"
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    ref = gd.denoise(rec.rate_deg_s, 200.0, method="shakf")
    np.testing.assert_allclose(data[:, 2], ref, rtol=1e-9)
    np.testing.assert_allclose(data[:, 1], rec.rate_deg_s, rtol=1e-9)
    # the filter reduces the error against the truth after the warm-up
    err_raw = np.sqrt(np.mean((data[400:, 1] - 2.0) ** 2))
    err_f = np.sqrt(np.mean((data[400:, 2] - 2.0) ** 2))
    assert err_f < 0.2 * err_raw


@pytest.mark.golden
def test_allan_json_contract(sim_csv):
    """The whole JSON is the reviewed tests/golden/allan_paper_fog.json; its N is the
    card's (independent reference: paper_fog's N = 0.006 deg/sqrt(h)) within 10 %."""
    path, rec = sim_csv
    code, out, err = run_cli("allan", path, "--json")
    assert code == 0, err
    d = json.loads(out)
    assert_golden("allan_paper_fog", d, {path.parent: "<tmp>"})
    assert len(d["tau_s"]) == len(d["adev_deg_h"]) == len(d["adev_err_deg_h"]) > 10
    assert d["terms"]["N"] == pytest.approx(0.006, rel=0.1)


@pytest.mark.slow
def test_compare_json_contract(sim_csv):
    path, _ = sim_csv
    code, out, err = run_cli("compare", path, "--json")
    assert code == 0, err
    d = json.loads(out)
    assert set(d["rows"]) == {"raw", "ar_fit", "kf", "shakf", "motion"}   # motion beside the paper's two
    assert set(d["rmse_deg_s"]) == {"raw", "kf", "shakf", "motion"}
    assert d["rmse_deg_s"]["shakf"] < d["rmse_deg_s"]["kf"] < d["rmse_deg_s"]["raw"]
    assert d["rows"]["shakf"]["N"] < d["rows"]["raw"]["N"]


@pytest.mark.slow
def test_demo_json_quick(tmp_path):
    code, out, err = run_cli("demo", "--hours", "0.05", "--dynamic-s", "20", "--json", "--out", tmp_path)
    assert code == 0, err
    d = json.loads(out)
    assert len(d["dynamic"]["rows"]) == 5
    assert {"raw", "kf", "shakf"} <= set(d["static"]["rmse_deg_s"])
    for f in d["figures"]:
        assert (tmp_path / f.split("/")[-1]).stat().st_size > 10_000


BAD = {
    "empty.csv": ("", "empty file"),
    "header.csv": ("time,rate\n", "header only"),
    "noheader.csv": ("0.0,1.0\n0.01,1.1\n", "no header row"),
    "nan.csv": ("time,rate\n0,1\n0.01,nan\n0.02,1\n", "line 3: column rate is nan"),
    "inf.csv": ("time,rate\n0,1\n0.01,1\n0.02,-inf\n", "line 4: column rate is -inf"),
    "text.csv": ("time,rate\n0,1\n0.01,abc\n", "line 3: column rate: 'abc' is not a number"),
    "short.csv": ("time,rate,true_rate\n0,1,0\n0.01,1\n", "line 3: 2 fields"),
    "one.csv": ("time,rate\n0,1\n", "only 1 data row"),
    "col.csv": ("t,omega\n0,1\n0.01,1\n", "no column 'rate'"),
}


#: bad recordings also run through the console entry in a process of their own (the others
#: through cli.main in this process: 0.4 s a process, 11 of them)
BAD_IN_A_PROCESS = {"empty.csv", "nan.csv"}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_recordings_get_one_line_and_exit_2(tmp_path, capfd, name):
    text, needle = BAD[name]
    path = tmp_path / name
    path.write_text(text)
    args = ("denoise", path, "-o", tmp_path / "o.csv")
    runs = [main_in_process(capfd, *args)] + ([run_cli(*args)] if name in BAD_IN_A_PROCESS else [])
    for code, out, err in runs:
        assert code == 2
        assert out == ""
        lines = err.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in err, err
        assert str(path) in lines[0] and needle in lines[0], lines[0]


def test_missing_file_unknown_unit_and_bad_parameter(tmp_path):
    code, _, err = run_cli("allan", tmp_path / "nope.csv")
    assert code == 2 and "no such file" in err and len(err.strip().splitlines()) == 1
    p = tmp_path / "ok.csv"
    p.write_text("time,rate\n" + "".join(f"{i / 100},{np.sin(i)}\n" for i in range(300)))
    code, _, err = run_cli("allan", p, "--rate-unit", "furlong/s")
    assert code == 2 and "unknown rate unit" in err
    code, _, err = run_cli("denoise", p, "-o", tmp_path / "o.csv", "--gamma", "0.5")
    assert code == 2 and "gamma" in err and "Traceback" not in err


def test_gap_is_reported_and_restarts_the_filter(tmp_path):
    t = np.concatenate([np.arange(0, 5, 0.01), np.arange(10, 15, 0.01)])
    z = 1.0 + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    p = tmp_path / "gap.csv"
    np.savetxt(p, np.column_stack([t, z]), delimiter=",", header="time,rate", comments="")
    code, out, err = run_cli("denoise", p, "-o", tmp_path / "o.csv", "--causal")
    assert code == 0 and "restart the filter" in err and "causal" in err
    data = np.loadtxt(tmp_path / "o.csv", delimiter=",", skiprows=1)
    assert data.shape[0] == t.size                       # nothing dropped or invented
    # after the gap the filter starts again: the output is a fresh run's on the samples after it
    # (raw while it warms up: the first 63 samples at least)
    import gyrodenoise as gd
    np.testing.assert_array_equal(data[500:563, 2], data[500:563, 1])
    np.testing.assert_allclose(data[500:, 2], gd.denoise(data[500:, 1], 100.0), rtol=0, atol=2e-6)
    # the default on a file: offline (forward + backward), each side of the gap on its own
    code, out, err = run_cli("denoise", p, "-o", tmp_path / "off.csv")
    assert code == 0 and "offline" in err
    off = np.loadtxt(tmp_path / "off.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(off[:500, 2], gd.denoise(off[:500, 1], 100.0, offline=True), rtol=0, atol=2e-6)
    np.testing.assert_allclose(off[500:, 2], gd.denoise(off[500:, 1], 100.0, offline=True), rtol=0, atol=2e-6)
    assert np.std(off[500:600, 2] - 1.0) < 0.5 * np.std(off[500:600, 1] - 1.0)   # no raw warm-up left
    code, _, err = run_cli("denoise", p, "-o", tmp_path / "x.csv", "--method", "kf", "--causal")
    assert code == 2 and "--causal" in err and not (tmp_path / "x.csv").exists()


def test_rate_units_and_no_time_column(tmp_path):
    z = np.full(500, 3600.0)  # deg/h
    p = tmp_path / "degh.csv"
    np.savetxt(p, z[:, None], delimiter=",", header="rate", comments="")
    code, _, err = run_cli("denoise", p, "-o", tmp_path / "o.csv", "--rate-unit", "deg/h")
    assert code == 2 and "no column 'time'" in err
    code, _, err = run_cli("denoise", p, "-o", tmp_path / "o.csv", "--rate-unit", "deg/h",
                           "--sample-rate", "100")
    assert code == 0, err
    data = np.loadtxt(tmp_path / "o.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 1], 1.0)
    np.testing.assert_allclose(data[-1, 0], 4.99)


def test_dynamic_table_reports_the_step_with_and_without_the_gate():
    """Demo's 'price paid': with the default outlier gate a 10 deg/s step is
    followed within 0.2 s (20 rejected samples at 200 Hz, then a re-open);
    the paper's SHAKF without the gate has not reached 90 % after 10 s."""
    from gyrodenoise.analysis.experiments import dynamic_table, rise_time
    # the figure itself: a ramp of 1 deg/s per s from t = 2 s reaches 90 % of 10 at 11 s
    t = np.arange(0.0, 20.0, 0.5)
    assert rise_time(np.clip(t - 2.0, 0.0, None), t, 2.0, 10.0) == 9.0
    assert rise_time(np.clip(t - 2.0, 0.0, None), t, 2.0, 10.0, frac=0.5) == 5.0
    assert rise_time(np.zeros_like(t), t, 2.0, 10.0) is None
    dyn = dynamic_table("paper_fog", rates_deg_s=(5.0,), duration_s=60.0, seed=3)
    st = dyn["step"]
    assert st["rise_time_90_s"]["shakf"] is not None and st["rise_time_90_s"]["shakf"] <= 0.2
    ng = st["no_gate"]["rise_time_90_s"]["shakf"]
    assert ng is None or ng > 10.0
    assert st["no_gate"]["rmse_deg_s"]["shakf"] > 10 * st["rmse_deg_s"]["shakf"]
    # the conventional KF follows the step within a few samples without the gate
    assert st["no_gate"]["rise_time_90_s"]["kf"] <= 0.05


@pytest.mark.parametrize("args, names", [
    (("gap", "x.csv", "--model", "m.toml", "--out", "o.toml", "--seeds", "x"), ("gyrodenoise gap", "--seeds")),
    (("gap", "x.csv", "--model", "m.toml", "--out", "o.toml", "--engine", "fmi"), ("gyrodenoise gap", "--engine")),
    (("gap", "--rate-colunm", "a", "x.csv", "--model", "m.toml", "--out", "o.toml"),
     ("gyrodenoise gap", "--rate-colunm")),
    (("denoise", "x.csv", "--ar-order", "q", "-o", "y.csv"), ("gyrodenoise denoise", "--ar-order")),
    (("denoise", "x.csv"), ("gyrodenoise denoise", "-o/--output")),
    (("fmu", "build", "--bogus"), ("gyrodenoise fmu build", "--bogus")),
    (("bogus",), ("gyrodenoise", "bogus")),
])
def test_option_errors_are_one_line_naming_the_command_and_option(tmp_path, capfd, monkeypatch, args, names):
    """A bad option value, a missing or unknown option: one line on stderr naming the
    (sub)command and the option, exit 2, nothing on stdout (argparse printed its whole
    usage block first, and the top-level usage for a subcommand's unknown option)."""
    monkeypatch.chdir(tmp_path)
    status, out, err = main_in_process(capfd, *args)
    assert status == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{names[0]}: error:") and names[1] in lines[0], lines[0]
    assert list(tmp_path.iterdir()) == []


def test_gap_says_which_rate_unit_it_assumed(tmp_path, capfd):
    """gap on a record without --rate-unit says it read the column as deg/s (a rad/s
    record read silently as deg/s would fit a card 57x too small); with
    --rate-unit given, no such note, and the unit scales the fitted white noise."""
    rng = np.random.default_rng(20)
    t = np.arange(4096) / 100.0
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([t, 1e-3 * rng.standard_normal(t.size)]), delimiter=",",
               header="time,gyro_x", comments="")
    cards = {}
    for unit in (None, "rad/s"):
        out = tmp_path / f"{unit or 'none'}.toml".replace("/", "_")
        args = ["gap", path, "--rate-column", "gyro_x", "--model", "paper_fog", "--out", out,
                "--engine", "native", "--seeds", "3", "--no-plot", "--max-effects", "1"]
        if unit:
            args += ["--rate-unit", unit]
        status, _, err = main_in_process(capfd, *args)
        assert status == 0, err
        said = [ln for ln in err.splitlines() if "read as deg/s (the default" in ln]
        assert len(said) == (1 if unit is None else 0), err
        if unit is None:
            assert "'gyro_x'" in said[0] and str(path) in said[0]
        cards[unit] = gd.simulator.parse_card(out.read_text(), str(out))
    n_deg = cards[None].terms["angle_random_walk"]["N"]
    n_rad = cards["rad/s"].terms["angle_random_walk"]["N"]
    assert n_rad / n_deg == pytest.approx(180.0 / np.pi, rel=0.2)


def test_gap_spike_note_names_gaps_own_remedy(tmp_path, capfd):
    """A record with a wild sample: gap's note names gap's remedy (--outliers), not the
    filters' options (--method shakf / --outlier-sigma are not gap options);
    denoise keeps naming the outlier gate."""
    rng = np.random.default_rng(21)
    t = np.arange(4096) / 100.0
    rate = 1e-2 * rng.standard_normal(t.size)
    rate[1000] = 5.0
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([t, rate]), delimiter=",", header="time,rate", comments="")
    status, _, err = main_in_process(capfd, "gap", path, "--model", "paper_fog", "--out", tmp_path / "o.toml",
                                     "--engine", "native", "--seeds", "3", "--no-plot", "--max-effects", "1")
    assert status == 0, err
    spike = [ln for ln in err.splitlines() if "isolated spike" in ln]
    assert len(spike) == 1 and "--outliers" in spike[0] and "--outlier-sigma" not in spike[0], err
    status, _, err = main_in_process(capfd, "denoise", path, "-o", tmp_path / "f.csv", "--method", "shakf")
    assert status == 0, err
    spike = [ln for ln in err.splitlines() if "isolated spike" in ln]
    assert len(spike) == 1 and "--outlier-sigma" in spike[0], err
