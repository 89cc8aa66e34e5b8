"""The bad-input corpus (tests/corpus/, listed in its README): every case gets a
one-line error with exit status 2 and no traceback, or a documented, reported
repair with exit status 0 and nothing dropped or invented."""
import random
import subprocess
import sys

import numpy as np
import pytest

from gyrodenoise.cli import main
from gyrodenoise.errors import InputError
from gyrodenoise.simulator import parse_card
from tests.helpers import CORPUS, DATA

REC = CORPUS / "recordings"
CARDS = CORPUS / "cards"

# file -> substring of the one-line error (exit 2)
BAD_RECORDINGS = {
    "empty.csv": "empty file",
    "blank_lines.csv": "empty file",
    "header_only.csv": "header only, no data rows",
    "no_header.csv": "line 1: no header row",
    "single_row.csv": "only 1 data row(s)",
    "nan.csv": "line 3: column rate is nan",
    "inf.csv": "line 4: column rate is -inf",
    "nan_time.csv": "line 3: column time is NaN",
    "text_value.csv": "line 3: column rate: 'abc' is not a number",
    "empty_cell.csv": "line 3: column rate: '' is not a number",
    "truncated_row.csv": "line 3: 2 fields, expected 3 (truncated row?)",
    "wrong_column.csv": "line 1: no column 'rate' (columns: t, omega)",
    "absurd_value.csv": "line 3: column rate: 1e+300 deg/s is beyond 1e+06 deg/s",
    "binary.csv": "not a text CSV file",
    "truncated.csv.gz": "cannot read: Compressed file ended",
    "corrupted.csv.gz": "cannot read: CRC check failed",
}

# file -> substring of the note (exit 0, the repair or report is documented)
REPAIRED_RECORDINGS = {
    "jumping_time.csv": "1 gap of more than 4 missing samples (700 missing; longest 7.01 s before sample 300) "
                        "restart the filter; runs of 300 | 300 samples",
    "repeated_time.csv": "1 repeated timestamp (kept)",
    "decreasing_time.csv": "1 time reversal (first before sample 2) restart the filter; runs of 2 | 1 samples",
    "constant.csv": "the rate is constant (0.25 deg/s)",
    "saturated.csv": "suspected saturation: 60 samples in runs of >= 10 equal values at the rate's maximum 0.5",
    "spike.csv": "1 isolated spike(s) of more than 8 robust sigmas (first at line 302, sample 300, -17 deg/s)",
    "extra_columns.csv": "ignored columns: temp_c",
    "semicolon.csv": "fields separated by semicolons",
}

BAD_CARDS = {
    "unknown_term.toml": "unknown term terms.flux_drift",
    "unknown_field.toml": "unknown field terms.angle_random_walk.M",
    "unknown_section.toml": "unknown section [noise]",
    "missing_sensor.toml": "missing [sensor] section",
    "empty.toml": "missing [sensor] section",
    "missing_rate.toml": "sensor.sample_rate_hz must be a positive number below 1e+09 Hz, got None",
    "missing_field.toml": "terms.gauss_markov is missing the field tau (s)",
    "negative_arw.toml": "terms.angle_random_walk.N must be >= 0 deg/sqrt(h), got -0.01",
    "negative_rate.toml": "sensor.sample_rate_hz must be a positive number below 1e+09 Hz, got -200.0",
    "zero_tau.toml": "terms.turn_on_transient.tau must be > 0 s, got 0.0",
    "absurd_value.toml": "terms.bias_instability.B is not a usable number",
    "absurd_rate.toml": "sensor.sample_rate_hz must be a positive number below 1e+09 Hz",
    "nan_value.toml": "terms.rate_ramp.R is not a usable number: nan",
    "string_value.toml": "terms.angle_random_walk.N must be a number, got '0.01'",
    "bool_value.toml": "terms.angle_random_walk.N must be a number, got True",
    "above_nyquist.toml": "terms.sinusoid[0].frequency 150 Hz is above Nyquist (100 Hz)",
    "repeated_term.toml": "terms.angle_random_walk may appear only once",
    "not_toml.toml": "not valid TOML",
}


def test_corpus_folder_matches_the_tables_and_readme():
    """Every corpus file has a test case and a README line, and vice versa."""
    readme = (CORPUS / "README.md").read_text()
    recs = {p.name for p in REC.iterdir()}
    assert recs == set(BAD_RECORDINGS) | set(REPAIRED_RECORDINGS)
    assert {p.name for p in CARDS.iterdir()} == set(BAD_CARDS)
    for name in recs | set(BAD_CARDS):
        assert f"`{name}`" in readme, name


def _one_line_error(capsys, argv, path, needle):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 2, err
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("gyrodenoise: error: ")
    assert str(path) in lines[0] and needle in lines[0], lines[0]


@pytest.mark.parametrize("name", sorted(BAD_RECORDINGS))
@pytest.mark.parametrize("command", ["denoise", "allan"])
def test_bad_recording_one_line_exit_2(capsys, tmp_path, name, command):
    path = REC / name
    argv = [command, path] + (["-o", tmp_path / "o.csv"] if command == "denoise" else [])
    _one_line_error(capsys, argv, path, BAD_RECORDINGS[name])
    assert not (tmp_path / "o.csv").exists()          # nothing written on error


@pytest.mark.parametrize("name", sorted(REPAIRED_RECORDINGS))
def test_repaired_recording_is_reported_and_complete(capsys, tmp_path, name):
    path = REC / name
    out_csv = tmp_path / "o.csv"
    code = main(["denoise", str(path), "-o", str(out_csv)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert any(line.startswith(f"gyrodenoise: note: {path}: ") and REPAIRED_RECORDINGS[name] in line
               for line in err.splitlines()), err
    assert "Traceback" not in err
    raw = np.loadtxt(path, delimiter=";" if name == "semicolon.csv" else ",", skiprows=1, usecols=(0, 1))
    got = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    assert got.shape[0] == raw.shape[0]                       # nothing dropped or invented
    np.testing.assert_allclose(got[:, 0], raw[:, 0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got[:, 1], raw[:, 1], rtol=0, atol=1e-9)   # raw kept as is
    assert np.all(np.isfinite(got[:, 2]))


def test_constant_record_passes_through_and_allan_terms_are_zero(capsys):
    path = REC / "constant.csv"
    assert main(["allan", str(path), "--json"]) == 0
    out, err = capsys.readouterr()
    import json
    d = json.loads(out)
    assert any("constant" in n for n in d["notes"])
    # zero within rounding of 0.25 deg/s in float64 (the largest term, R, in deg/h^2)
    for t, v in d["terms"].items():
        assert 0.0 <= v < 1e-6, (t, v)
    from gyrodenoise.denoiser import denoise
    z = np.full(400, 0.25)
    np.testing.assert_allclose(denoise(z, 100.0), z, rtol=1e-6, atol=0)   # ridge prior of the RLS


def test_spike_is_kept_in_raw_and_kept_out_of_the_filter(capsys, tmp_path):
    path = REC / "spike.csv"
    out_csv = tmp_path / "o.csv"
    assert main(["denoise", str(path), "-o", str(out_csv), "--method", "shakf"]) == 0
    err = capsys.readouterr().err
    assert "outlier gate (k=5): 1 sample(s) kept out of the filter" in err
    got = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    assert got[300, 1] == -17.0
    assert abs(got[300, 2] - 1.0) < 0.02          # the prediction (true level 1.0, noise 0.01)
    assert np.max(np.abs(got[300:, 2] - 1.0)) < 0.02
    # with the gate off the spike enters the filter (the paper's filter)
    assert main(["denoise", str(path), "-o", str(out_csv), "--method", "shakf", "--outlier-sigma", "0"]) == 0
    capsys.readouterr()
    off = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    assert np.max(np.abs(off[300:, 2] - 1.0)) > np.max(np.abs(got[300:, 2] - 1.0))


def test_wrong_rate_unit_and_bad_filter_options(capsys, tmp_path):
    path = REC / "extra_columns.csv"
    _one_line_error(capsys, ["denoise", path, "-o", tmp_path / "o.csv", "--rate-unit", "deg/min"],
                    path, "unknown rate unit 'deg/min'")
    # deg/s data declared as rad/s is accepted (1 rad/s is a plausible rate); the
    # absurd-value bound catches only impossible conversions: 1e5 rad/s > 1e6 deg/s
    p = tmp_path / "big.csv"
    p.write_text("time,rate\n0,1e5\n0.01,1e5\n")
    _one_line_error(capsys, ["allan", p, "--rate-unit", "rad/s"], p, "line 2: column rate: 100000.0 rad/s is beyond 1e+06 deg/s")
    for opt, val, word in [("--outlier-sigma", "1", "outlier_sigma"), ("--outlier-sigma", "-2", "outlier_sigma"),
                           ("--outlier-run", "0", "outlier_run"), ("--b", "1", "b out of range"),
                           ("--lam", "0", "lam")]:
        code = main(["denoise", str(path), "-o", str(tmp_path / "o.csv"), opt, val])
        err = capsys.readouterr().err
        assert code == 2 and word in err and len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize("name", sorted(BAD_CARDS))
def test_bad_model_card_one_line_exit_2(capsys, name):
    path = CARDS / name
    _one_line_error(capsys, ["demo", "--model", path, "--hours", "0.01", "--no-plots"], path, BAD_CARDS[name])
    with pytest.raises(InputError) as exc:
        parse_card(path.read_text(), source=str(path))
    assert BAD_CARDS[name] in str(exc.value) and "\n" not in str(exc.value)


def run_cli(*args):
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", *map(str, args)],
                       capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout, p.stderr


@pytest.mark.parametrize("argv", [
    ["denoise", REC / "nan.csv", "-o", "/nonexistent/o.csv"],
    ["allan", REC / "truncated.csv.gz"],
    ["compare", REC / "binary.csv"],
    ["demo", "--model", CARDS / "unknown_term.toml"],
])
@pytest.mark.slow
def test_real_entry_point_exits_2_without_traceback(argv):
    code, out, err = run_cli(*argv)
    assert code == 2 and out == "" and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and err.startswith("gyrodenoise: error: ")


# ------------------------------------------------------- truncated / corrupted logs
def _corrupt(src, dst, start, every):
    b = bytearray(src.read_bytes())
    for i in range(start, len(b), every):
        b[i] ^= 0x5A
    dst.write_bytes(bytes(b))
    return dst


def _logs(tmp_path):
    """Synthetic damaged logs made from the small permissive logs in tests/data."""
    r = random.Random(1)
    junk = bytes(r.randrange(256) for _ in range(5000))
    binlog = (DATA / "ardusub_small.BIN").read_bytes()
    tlog = (DATA / "fs-batt.log.tlog").read_bytes()
    cases = {}
    for ext in ("tlog", "bin", "ulg"):
        (tmp_path / f"junk.{ext}").write_bytes(junk)
    cases["junk.tlog"] = (2, "no readable MAVLink record")
    cases["junk.bin"] = (2, "not a DataFlash binary log")
    cases["junk.ulg"] = (2, "not a readable ULog")
    (tmp_path / "empty.tlog").write_bytes(b"")
    cases["empty.tlog"] = (2, "no readable MAVLink record")
    (tmp_path / "cut100.bin").write_bytes(binlog[:100])
    cases["cut100.bin"] = (2, "no gyro stream")
    (tmp_path / "header.ulg").write_bytes(b"ULog\x01\x12\x35\x01" + b"\x00" * 8)
    cases["header.ulg"] = (2, "no gyro stream")
    (tmp_path / "cut.tlog").write_bytes(tlog[: len(tlog) // 3 + 7])
    cases["cut.tlog"] = (0, "truncated")
    _corrupt(DATA / "ardusub_small.BIN", tmp_path / "flipped.bin", 500, 97)
    cases["flipped.bin"] = (0, "unreadable records skipped")
    _corrupt(DATA / "fs-batt.log.tlog", tmp_path / "flipped.tlog", 300, 211)
    cases["flipped.tlog"] = (0, "unreadable records skipped")
    return cases


@pytest.mark.slow
def test_truncated_and_corrupted_logs(tmp_path):
    import json
    for name, (want, needle) in _logs(tmp_path).items():
        path = tmp_path / name
        code, out, err = run_cli("mavlink", path, "-o", tmp_path / ("out_" + name), "--json", "--no-plots")
        assert code == want, (name, err)
        assert "Traceback" not in err and "Warning" not in err, (name, err)
        if want == 2:
            # --json always prints one object, with the error in it
            assert json.loads(out) == {"error": err.strip().removeprefix("gyrodenoise: error: "),
                                       "exit_status": 2}, (name, out)
            assert len(err.strip().splitlines()) == 1, (name, err)
            assert str(path) in err and needle in err, (name, err)
            continue
        d = json.loads(out)
        rep = d["logs"][0] if "logs" in d else d
        text = json.dumps(rep)
        assert needle.split()[0] in text, (name, text[:500])
        for s in rep["streams"]:
            got = np.loadtxt(s["csv"], delimiter=",", skiprows=1)
            for k in range(3):                  # raw_k, filtered_k column pairs
                raw, filt = got[:, 1 + 2 * k], got[:, 2 + 2 * k]
                usable = np.isfinite(raw) & (np.abs(raw) <= 1e6)
                assert np.all(np.isfinite(filt[usable])), (name, s["name"])
                np.testing.assert_array_equal(filt[~usable], raw[~usable])   # kept as they are
        if name == "flipped.bin":
            # damaged DataFlash records decode to absurd rates: counted, kept out of the filter
            s0 = rep["streams"][0]
            assert sum(s0["non_finite_samples"].values()) > 0
            # a damaged timestamp does not stretch a flight segment (the log spans 265-289 s)
            assert rep["segments"] and all(seg["end_s"] < 300 for seg in rep["segments"]), rep["segments"]
            # and they stay out of the noise figures (a 25 Hz IMU at rest: ~0.05 deg/s)
            for a in ("x", "y", "z"):
                assert 0 < s0["noise"][a]["raw"] < 1.0 and 0 < s0["noise"][a]["filtered"] < 1.0, s0["noise"]


def test_demo_refuses_bad_gate_options_before_simulating(capsys):
    for opt, val in [("--outlier-sigma", "1.5"), ("--outlier-run", "0")]:
        code = main(["demo", "--hours", "0.01", "--no-plots", opt, val])
        out, err = capsys.readouterr()
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
        assert opt[2:].replace("-", "_") in err and "simulating" not in err
