"""Awkward but ordinary recording files: a ``rostopic echo -p`` export, space /
tab / semicolon separators and decimal commas, a cell ``1_05``, the rate unit always said.
Synthetic records of known N (deg/sqrt(h))."""
import json
import math

import numpy as np
import pytest

from gyrodenoise.cli import main
from gyrodenoise.io.recording import read_recording

N_DEG = 0.75                       # deg/sqrt(h), the MPU-6050
FS = 200.0
T0_NS = 1_700_000_000_000_000_000


def _white_deg_s(n, seed=0):
    return N_DEG / 60.0 * math.sqrt(FS) * np.random.default_rng(seed).standard_normal(n)


def _rostopic_csv(path, n=12_000):
    """What ``rostopic echo -p /imu0`` writes: %time (receive, ns), the header (seq, stamp in
    ns, frame_id), orientation and covariances, angular_velocity in rad/s, linear_acceleration."""
    gyro = np.column_stack([_white_deg_s(n, s) for s in (1, 2, 3)]) * math.pi / 180.0
    acc = np.random.default_rng(4).normal(0, 0.02, (n, 3)) + [0, 0, 9.81]
    cov = [f"field.{w}_covariance{i}" for w in ("orientation",) for i in range(9)]
    head = (["%time", "field.header.seq", "field.header.stamp", "field.header.frame_id",
             "field.orientation.x", "field.orientation.y", "field.orientation.z", "field.orientation.w"] + cov
            + [f"field.angular_velocity.{a}" for a in "xyz"] + [f"field.angular_velocity_covariance{i}" for i in range(9)]
            + [f"field.linear_acceleration.{a}" for a in "xyz"]
            + [f"field.linear_acceleration_covariance{i}" for i in range(9)])
    stamp = T0_NS + np.arange(n, dtype=np.int64) * 5_000_000
    recv = stamp + 300_000 + (np.arange(n) % 7) * 10_000
    with open(path, "w") as f:
        f.write(",".join(head) + "\n")
        zeros9 = ",".join(["0.0"] * 9)
        for i in range(n):
            f.write(f"{recv[i]},{i},{stamp[i]},imu_link,0.0,0.0,0.0,1.0,{zeros9},"
                    f"{gyro[i, 0]:.17g},{gyro[i, 1]:.17g},{gyro[i, 2]:.17g},{zeros9},"
                    f"{acc[i, 0]:.17g},{acc[i, 1]:.17g},{acc[i, 2]:.17g},{zeros9}\n")
    return gyro, acc


def test_rostopic_echo_csv_is_read_in_rad_s_with_its_ns_stamps(tmp_path, capsys):
    """The Kalibr user's route: before, `gyroscope_noise_density: 6.913` and `update_rate: 1e-07`."""
    path = tmp_path / "imu0.csv"
    gyro, _ = _rostopic_csv(path)
    yaml = tmp_path / "imu.yaml"
    code = main(["allan", str(path), "--json", "--kalibr-yaml", str(yaml)])
    out, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(out)
    assert d["sample_rate_hz"] == pytest.approx(FS, rel=1e-6)
    assert "gyro columns field.angular_velocity.x, field.angular_velocity.y, field.angular_velocity.z in rad/s" in err
    assert "time column in ns (a Unix epoch from 2023-11-14" in err
    for a in "xyz":
        assert d["axes"][f"field.angular_velocity.{a}"]["terms"]["N"] == pytest.approx(N_DEG, rel=0.1)
        assert d["axes"][f"field.linear_acceleration.{a}"]["sensor"] == "accel"
    keys = dict(ln.split(":", 1) for ln in yaml.read_text().splitlines() if ln and not ln.startswith("#"))
    density = float(keys["gyroscope_noise_density"].split("#")[0])
    assert density == pytest.approx(N_DEG * math.pi / 180 / 60, rel=0.15)        # 2.18e-4 rad/s/sqrt(Hz)
    assert float(keys["update_rate"].split("#")[0]) == pytest.approx(FS, rel=1e-6)
    assert float(keys["accelerometer_noise_density"].split("#")[0]) > 0


def _plain(n=3000):
    t = np.arange(n) / FS
    return t, 0.5 + _white_deg_s(n)


@pytest.mark.parametrize("sep,decimal,name", [(" ", ".", "spaces"), ("  ", ".", "spaces"), ("\t", ".", "tabs"),
                                              (";", ",", "semicolons"), ("\t", ",", "tabs")])
def test_separators_and_decimal_commas_are_read(tmp_path, sep, decimal, name):
    """Before: 'no column 'rate' (columns: time rate)'."""
    t, z = _plain()
    path = tmp_path / "r.txt"
    cell = lambda v: (f"{v:.6f}").replace(".", decimal)  # noqa: E731
    path.write_text(f"time{sep}rate\n" + "".join(f"{cell(a)}{sep}{cell(b)}\n" for a, b in zip(t, z)))
    rec = read_recording(path)
    np.testing.assert_allclose(rec.rate_deg_s, np.round(z, 6), atol=1e-9)
    assert rec.sample_rate_hz == pytest.approx(FS)
    assert f"fields separated by {name}" + ("; decimal commas read" if decimal == "," else "") in rec.notes


def test_a_cell_with_an_underscore_is_refused(tmp_path, capsys):
    """Python's float('1_05') is 105: a recording's cell is not Python source."""
    path = tmp_path / "u.csv"
    path.write_text("time,rate\n0,1\n0.01,1_05\n0.02,1\n")
    code = main(["allan", str(path)])
    _, err = capsys.readouterr()
    assert code == 2 and err.strip() == f"gyrodenoise: error: {path}: line 3: column rate: '1_05' is not a number"


def test_the_rate_unit_is_always_said(tmp_path, capsys):
    """rad/s read as deg/s gave N 57x too small, silently."""
    t, z = _plain()
    path = tmp_path / "r.csv"
    np.savetxt(path, np.column_stack([t, z]), delimiter=",", header="time,rate", comments="", fmt="%.8f")
    for extra, said in (([], "gyro column rate in deg/s (assumed; --rate-unit deg/h|rad/s|mrad/s if not)"),
                        (["--rate-unit", "rad/s"], "gyro column rate in rad/s (as stated)")):
        code = main(["allan", str(path), "--json", *extra])
        out, err = capsys.readouterr()
        assert code == 0 and said in err and said in json.loads(out)["notes"], err


def test_decimal_commas_in_a_comma_separated_file_are_refused(tmp_path, capsys):
    """`0,01,1,05` under `time,rate` read as time 0, rate 1 before: silently wrong."""
    path = tmp_path / "dc.csv"
    path.write_text("time,rate\n0,00,1,00\n0,01,1,05\n")
    code = main(["allan", str(path)])
    _, err = capsys.readouterr()
    assert code == 2 and err.strip() == (f"gyrodenoise: error: {path}: line 2: 4 fields, expected 2 (decimal commas "
                                         f"in a comma-separated file? separate the fields by ';')")
    path.write_text("time,rate,\n0.00,1.00,\n0.01,1.05,\n0.02,1.0,\n")      # a trailing comma: an empty field
    assert read_recording(path).rate_deg_s.tolist() == [1.0, 1.05, 1.0]


def test_a_units_row_under_the_header_gives_the_units(tmp_path, capsys):
    """A two-row header (names, then units: a TStick export in rad/s): before, 'not a number'."""
    t, z = _plain()
    z_rad = z * math.pi / 180.0
    z_rad[300] += 1.0                                          # a spike: its line counts the units row
    path = tmp_path / "tstick.csv"
    path.write_text("time,gx\ns,rad/s\n" + "".join(f"{a:.6f},{b:.9f}\n" for a, b in zip(t, z_rad)))
    rec = read_recording(path, rate_column="gx")
    np.testing.assert_allclose(rec.rate_deg_s[:300], z[:300], atol=1e-6)
    assert "gyro column gx in rad/s (as its units row says)" in rec.notes
    assert any("first at line 303, sample 300" in x for x in rec.notes), rec.notes
    path.write_text("t [ms]\n[ms] [deg/s]\n".replace("t [ms]", "t rate")
                    + "".join(f"{a * 1000:.0f} {b:.6f}\n" for a, b in zip(t, z)))
    rec = read_recording(path)
    assert rec.sample_rate_hz == pytest.approx(FS) and "gyro column rate in deg/s (as its units row says)" in rec.notes
    assert any(x.startswith("time column in ms (as stated") for x in rec.notes), rec.notes
