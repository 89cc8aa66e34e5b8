"""Records as people have them, each a known-truth synthetic record (seeded): free-text
lines before the header row (a preamble), a unit after a column's name
(``gyro_x (deg/s)``, ``time (sec)``, as gnss-ins-sim writes them) and raw counts
(``--rate-scale``: the unit per count)."""
import json
import math

import numpy as np
import pytest

from gyrodenoise.cli import main
from gyrodenoise.errors import InputError
from gyrodenoise.io.recording import peek_header, read_axes, read_recording

FS = 100.0
PREAMBLE = ["Fs,100", "Logging Type,1", "Initialization time,-1", "Waiting time,-1"]


def _white(n, nd_deg_sqrt_h, seed):
    """White rate noise (deg/s) of angle random walk ``nd_deg_sqrt_h``."""
    return nd_deg_sqrt_h / 60.0 * math.sqrt(FS) * np.random.default_rng(seed).standard_normal(n)


def _write(path, header, cols, preamble=(), fmt="%.10g"):
    body = "\n".join(",".join(fmt % v for v in row) for row in np.column_stack(cols))
    path.write_text("".join(f"{ln}\n" for ln in preamble) + ",".join(header) + "\n" + body + "\n")


def _run(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:         # argparse's refusal
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------ preamble
def test_a_preamble_before_the_header_is_skipped_and_said(tmp_path):
    x = [_white(3000, 0.3, s) for s in (1, 2, 3)]
    path = tmp_path / "mpu.csv"
    _write(path, ["gx", "gy", "gz"], x, PREAMBLE)
    rec = read_axes(path, ["gx", "gy", "gz"], sample_rate_hz=FS)
    for ax, want in zip(rec.axes, x):
        np.testing.assert_allclose(ax.values, want, rtol=1e-9)
    assert rec.notes[0].startswith("4 line(s) before the header row skipped as a preamble")
    assert "Fs,100; Logging Type,1" in rec.notes[0]
    assert peek_header(path) == ["gx", "gy", "gz"]


def test_a_bad_value_after_a_preamble_names_its_own_line(tmp_path):
    path = tmp_path / "mpu.csv"
    path.write_text("\n".join([*PREAMBLE, "gx,gy", "1,2", "3,4", "5,x", "7,8"]) + "\n")
    with pytest.raises(InputError, match=r"line 8: column gy: 'x' is not a number"):
        read_axes(path, ["gx", "gy"], sample_rate_hz=FS)


def test_the_commands_find_the_columns_after_a_preamble(tmp_path, capsys):
    path = tmp_path / "mpu.csv"
    _write(path, ["time", "rate"], [np.arange(3000) / FS, _white(3000, 0.5, 4)], ["recorded on bench 3"])
    code, out, err = _run(capsys, "allan", path, "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["terms"]["N"] == pytest.approx(0.5, rel=0.1)
    assert "1 line(s) before the header row skipped as a preamble (free text, not columns): recorded on bench 3" in err


def test_lines_with_as_many_fields_as_the_header_are_no_preamble(tmp_path):
    # a bad first row: not to be taken for the header (the header is line 1)
    path = tmp_path / "bad.csv"
    path.write_text("time,rate\n0.0,abc\n0.01,1.0\n0.02,1.1\n")
    with pytest.raises(InputError, match=r"line 2: column rate: 'abc' is not a number"):
        read_recording(path)


# ------------------------------------------------------------------ unit after a name
def test_a_unit_after_the_column_name_is_read(tmp_path):
    n = 3000
    rad = np.deg2rad(_white(n, 0.4, 5))
    path = tmp_path / "gyro.csv"
    _write(path, ["time (sec)", "gyro_x (rad/s)", "gyro_y (rad/s)", "gyro_z (rad/s)", "accel_x (m/s^2)"],
           [np.arange(n) / FS, rad, rad, rad, np.full(n, 0.1)])
    rec = read_axes(path)
    assert [a.column for a in rec.axes] == ["gyro_x (rad/s)", "gyro_y (rad/s)", "gyro_z (rad/s)", "accel_x (m/s^2)"]
    np.testing.assert_allclose(rec.axes[0].values, np.rad2deg(rad), rtol=1e-9)
    assert rec.axes[0].unit == "rad/s" and rec.axes[0].unit_how == "as its header says"
    assert "gyro columns gyro_x (rad/s), gyro_y (rad/s), gyro_z (rad/s) in rad/s (as its header says)" in rec.notes
    assert rec.sample_rate_hz == pytest.approx(FS)
    # the name without its unit finds the column too
    one = read_recording(path, rate_column="gyro_y")
    np.testing.assert_allclose(one.rate_deg_s, np.rad2deg(rad), rtol=1e-9)


def test_a_unit_after_the_name_gives_the_allan_terms_in_it(tmp_path, capsys):
    n = 20_000
    path = tmp_path / "gyro-0.csv"
    _write(path, ["gyro_x (rad/s)"], [np.deg2rad(_white(n, 0.6, 6))])
    code, out, err = _run(capsys, "allan", path, "--sample-rate", FS, "--rate-column", "gyro_x (rad/s)", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["rate_unit"] == {"unit": "rad/s", "how": "as its header says"}
    assert d["terms"]["N"] == pytest.approx(0.6, rel=0.1)      # read as deg/s it would be 57x smaller


# ------------------------------------------------------------------ raw counts
@pytest.mark.parametrize("unit,per_count", [("deg/s", 0.00763), ("rad/s", 1.3737e-4)])
def test_raw_counts_with_a_rate_scale(tmp_path, capsys, unit, per_count):
    n = 20_000
    truth = _white(n, 20.0, 7)                                      # deg/s, an MPU-6050's noise level
    counts = np.round((truth if unit == "deg/s" else np.deg2rad(truth)) / per_count)
    path = tmp_path / "counts.csv"
    _write(path, ["gx", "gy"], [counts, 2 * counts], fmt="%d")
    code, out, err = _run(capsys, "allan", path, "--sample-rate", FS, "--rate-column", "gx,gy", "--rate-unit", unit,
                          "--rate-scale", f"{per_count},{2 * per_count}", "--json")
    assert code == 0, err
    d = json.loads(out)
    for col in ("gx", "gy"):
        assert d["axes"][col]["terms"]["N"] == pytest.approx(20.0 * (1 if col == "gx" else 4), rel=0.1)
    assert d["axes"]["gx"]["rate_scale"] == per_count and d["axes"]["gy"]["rate_scale"] == 2 * per_count
    assert f"gyro columns gx, gy x {per_count:g}, {2 * per_count:g} (--rate-scale) in {unit} (as stated)" in d["notes"]
    # one factor for one column: the single-axis JSON says it too
    code, out, err = _run(capsys, "allan", path, "--sample-rate", FS, "--rate-column", "gx", "--rate-unit", unit,
                          "--rate-scale", per_count, "--json")
    d = json.loads(out)
    assert code == 0 and d["rate_scale"] == per_count and d["terms"]["N"] == pytest.approx(20.0, rel=0.1)


@pytest.mark.parametrize("scale,message", [
    ("2,3", "--rate-scale gives 2 factors for 1 rate column(s) (gx)"),
    ("0", "--rate-scale 0.0 is not a factor"),
    ("inf", "--rate-scale inf is not a factor"),
    ("x", "argument --rate-scale: not a number: 'x'")])
def test_a_bad_rate_scale_is_one_line(tmp_path, capsys, scale, message):
    path = tmp_path / "counts.csv"
    _write(path, ["gx"], [np.arange(100.0)])
    code, out, err = _run(capsys, "allan", path, "--sample-rate", FS, "--rate-column", "gx", f"--rate-scale={scale}")
    assert code == 2 and message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


# ------------------------------------------------------------------ the exports and the JSON of an IMU
def test_kalibr_writes_an_unresolved_random_walk_as_its_bound_and_says_how(tmp_path, capsys):
    n = 30_000
    path = tmp_path / "imu.csv"
    _write(path, ["time", "gx", "gy", "gz", "ax", "ay", "az"],
           [np.arange(n) / FS, *(_white(n, 0.3, s) for s in (8, 9, 10)),
            *(0.001 * _white(n, 60.0, s) + g for s, g in ((11, 0.0), (12, 0.0), (13, 9.81)))])
    yaml = tmp_path / "imu.yaml"
    code, out, err = _run(capsys, "allan", path, "--json", "--kalibr-yaml", yaml)
    assert code == 0, err
    d = json.loads(out)
    keys = {k.strip(): v for k, v in (ln.split(":", 1) for ln in yaml.read_text().splitlines()
                                      if ln and not ln.startswith("#"))}
    value, comment = keys["gyroscope_random_walk"].split("#", 1)
    # white noise only: K is not resolved; the value written is the largest bound over the axes, in SI
    assert all(d["axes"][c]["exported_bounds"]["K"] == "upper_bound" for c in ("gx", "gy", "gz"))
    k_max = max(d["axes"][c]["exported_terms"]["K"] for c in ("gx", "gy", "gz"))
    assert float(value) == pytest.approx(k_max / 3600.0 / 60.0 * math.pi / 180.0, rel=1e-8)
    assert "UPPER BOUND written as the value (Kalibr needs a number)" in comment
    # and it is a bound: at the well-measured taus its +1/2 line (K^2 tau / 3) stays within the
    # measured Allan variance + 2 sigma
    for c in ("gx", "gy", "gz"):
        a = d["axes"][c]
        k_s = a["terms"]["K"] / 3600.0 / 60.0
        tau, adev, err_ = (np.array(a[k]) / (1 if k == "tau_s" else 3600.0)
                           for k in ("tau_s", "adev_deg_h", "adev_err_deg_h"))
        well = err_ < 0.1 * adev
        assert well.sum() > 10
        assert np.all(k_s ** 2 * tau[well] / 3.0 <= (adev[well] + 2.0 * err_[well]) ** 2)


def test_an_accelerometer_curve_is_under_its_own_unit(tmp_path, capsys):
    n = 10_000
    path = tmp_path / "imu.csv"
    acc = [0.01 * _white(n, 60.0, s) + g for s, g in ((14, 0.0), (15, 0.0), (16, 9.81))]
    _write(path, ["time", "gx", "ax", "ay", "az"], [np.arange(n) / FS, _white(n, 0.3, 17), *acc])
    code, out, err = _run(capsys, "allan", path, "--json", "--rate-column", "gx", "--accel-column", "ax,ay,az")
    assert code == 0, err
    d = json.loads(out)
    assert "adev_deg_h" in d["axes"]["gx"] and "adev_m_s_h" not in d["axes"]["gx"]
    for name, x in zip(("ax", "ay", "az"), acc):
        a = d["axes"][name]
        assert "adev_deg_h" not in a and "adev_err_deg_h" not in a and a["adev_unit"] == "m/s/h"
        # tau = 1 sample: the Allan deviation is sqrt(mean(diff^2) / 2) (m/s^2), x 3600 in m/s/h
        assert a["tau_s"][0] == pytest.approx(1.0 / FS)
        assert a["adev_m_s_h"][0] == pytest.approx(math.sqrt(np.mean(np.diff(x) ** 2) / 2.0) * 3600.0, rel=1e-6)
        assert len(a["adev_err_m_s_h"]) == len(a["tau_s"])


# ------------------------------------------------------------------ accelerometer counts
def _mpu_counts(n, seed):
    """An MPU-6050 at rest at +-2 g: 16,384 counts per g, gravity on z, white noise."""
    rng = np.random.default_rng(seed)
    return [np.round(16384.0 * (g + 0.002 * rng.standard_normal(n))) for g in (0.0, 0.0, 1.0)]


def test_accelerometer_counts_are_refused_naming_the_options(tmp_path, capsys):
    """Counts read in the assumed m/s^2 give |a| ~ 16,384: no unit of the reader's; refused,
    naming --accel-scale and --accel-unit (before, it passed the gravity check silently)."""
    n = 6000
    path = tmp_path / "mpu.csv"
    _write(path, ["time", "gx", "gy", "gz", "ax", "ay", "az"],
           [np.arange(n) / FS, *[_white(n, 0.3, s) for s in (21, 22, 23)], *_mpu_counts(n, 24)], fmt="%.12g")
    code, out, err = _run(capsys, "allan", path, "--json")
    assert code == 2 and "--accel-scale" in err and "--accel-unit" in err and "1.64e+04" in err, err
    k = 1.0 / 16384.0
    code, out, err = _run(capsys, "allan", path, "--json", "--accel-scale", k)   # the product in assumed m/s^2: ~1
    assert code == 2 and "--accel-unit g" in err and "after --accel-scale" in err, err
    code, out, err = _run(capsys, "allan", path, "--json", "--accel-scale", k, "--accel-unit", "g")
    assert code == 0, err
    d = json.loads(out)
    assert d["axes"]["az"]["accel_scale"] == k and d["axes"]["az"]["unit_read"] == "g"
    assert d["axes"]["gx"]["rate_scale"] is None and "accel_scale" not in d["axes"]["gx"]
    assert f"accel columns ax, ay, az x {k:g} (--accel-scale) in g (as stated)" in d["notes"]
    # the white noise: 0.002 g per sample at 100 Hz, N = 0.002 * 9.80665 / sqrt(100) * 60 m/s/sqrt(h)
    assert d["axes"]["ax"]["terms"]["N"] == pytest.approx(0.002 * 9.80665 / 10.0 * 60.0, rel=0.1)


def test_a_bad_accel_scale_is_one_line(tmp_path, capsys):
    n = 6000
    path = tmp_path / "mpu.csv"
    _write(path, ["time", "gx", "ax", "ay", "az"], [np.arange(n) / FS, _white(n, 0.3, 25), *_mpu_counts(n, 26)])
    code, _, err = _run(capsys, "allan", path, "--accel-column", "ax,ay,az", "--accel-scale", "1,2")
    assert code == 2 and "--accel-scale gives 2 factors for 3 accelerometer column(s)" in err, err
    code, _, err = _run(capsys, "allan", path, "--rate-column", "gx,gx", "--accel-scale", "1")
    assert code == 2 and "--accel-scale is given but no accelerometer column is read" in err, err
