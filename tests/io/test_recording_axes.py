"""Every axis and the accelerometer in one run: `allan` and `denoise`
over gx,gy,gz,ax,ay,az of one file, synthetic white noise of known N per axis; the
complete Kalibr imu.yaml and the MATLAB gyroparams + accelparams from one command."""
import json
import math

import numpy as np
import pytest

from gyrodenoise.cli import main

FS = 100.0
N_GYRO = {"gx": 0.2, "gy": 0.4, "gz": 0.8}            # deg/sqrt(h)
N_ACCEL = {"ax": 0.05, "ay": 0.10, "az": 0.15}         # m/s/sqrt(h) (velocity random walk)


def _record(path, n=30_000):
    rng = np.random.default_rng(11)
    cols = {"time": np.arange(n) / FS}
    for name, nd in {**N_GYRO, **N_ACCEL}.items():
        cols[name] = nd / 60.0 * math.sqrt(FS) * rng.standard_normal(n) + (9.81 if name == "az" else 0.1)
    np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols), comments="",
               fmt="%.10g")
    return cols


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out, err


def test_allan_over_every_axis_with_the_accelerometer(tmp_path, capsys):
    path = tmp_path / "imu.csv"
    _record(path)
    yaml, m = tmp_path / "imu.yaml", tmp_path / "imu.m"
    out, err = _run(capsys, "allan", path, "--json", "--kalibr-yaml", yaml, "--matlab", m)
    d = json.loads(out)
    assert list(d["axes"]) == [*N_GYRO, *N_ACCEL]
    for name, nd in N_GYRO.items():
        assert d["axes"][name]["sensor"] == "gyro" and d["axes"][name]["units"]["N"] == "deg/sqrt(h)"
        assert d["axes"][name]["terms"]["N"] == pytest.approx(nd, rel=0.1)
    for name, nd in N_ACCEL.items():
        a = d["axes"][name]
        assert a["sensor"] == "accel" and a["units"]["N"] == "m/s/sqrt(h)" and a["units"]["B"] == "m/s/h"
        assert a["names"]["K"] == "acceleration random walk"
        assert a["terms"]["N"] == pytest.approx(nd, rel=0.1)
    assert "gyro columns gx, gy, gz in deg/s (assumed" in err and "accel columns ax, ay, az in m/s^2 (assumed" in err
    keys = {k.strip(): v.split("#")[0].strip() for k, v in
            (ln.split(":", 1) for ln in yaml.read_text().splitlines() if ln and not ln.startswith("#"))}
    # one number per sensor: the noisiest axis, in SI
    assert float(keys["gyroscope_noise_density"]) == pytest.approx(
        d["axes"]["gz"]["terms"]["N"] * math.pi / 180 / 60, rel=1e-9)
    assert float(keys["accelerometer_noise_density"]) == pytest.approx(d["axes"]["az"]["terms"]["N"] / 60, rel=1e-9)
    assert float(keys["accelerometer_noise_density"]) == pytest.approx(0.15 / 60, rel=0.1)
    assert "accelerometer_random_walk" in keys and float(keys["update_rate"]) == FS
    script = m.read_text()
    assert "gyro = gyroparams(" in script and "accel = accelparams(" in script
    nd = script.split("accel = accelparams(")[1].split("'NoiseDensity', [")[1].split("]")[0].split()
    np.testing.assert_allclose([float(v) for v in nd], [d["axes"][a]["terms"]["N"] / 60 for a in N_ACCEL], rtol=1e-12)


def test_rate_column_list_and_the_single_axis_json_kept(tmp_path, capsys):
    path = tmp_path / "imu.csv"
    _record(path, n=5000)
    d = json.loads(_run(capsys, "allan", path, "--json", "--rate-column", "gx,gy")[0])
    assert list(d["axes"]) == ["gx", "gy"]                  # named: no accelerometer unless asked
    d = json.loads(_run(capsys, "allan", path, "--json", "--rate-column", "gy,gz", "--accel-column", "az",
                        "--accel-unit", "g")[0])
    assert list(d["axes"]) == ["gy", "gz", "az"] and d["axes"]["az"]["unit_read"] == "g"
    one = json.loads(_run(capsys, "allan", path, "--json", "--rate-column", "gx")[0])
    assert "axes" not in one and set(one["terms"]) == {"N", "B", "K", "R", "Q"}      # spec section 3 as before
    code = main(["allan", str(path), "--rate-column", "gx,nope"])
    _, err = capsys.readouterr()
    assert code == 2 and "no column 'nope'" in err and len(err.strip().splitlines()) == 1


def test_denoise_writes_one_filtered_column_per_axis(tmp_path, capsys):
    path, out = tmp_path / "imu.csv", tmp_path / "out.csv"
    cols = _record(path, n=6000)
    _, err = _run(capsys, "denoise", path, "-o", out, "--method", "shakf")
    assert "6000 samples x 6 axes (gx, gy, gz, ax, ay, az)" in err
    with open(out) as f:
        header = f.readline().strip().split(",")
    assert header == ["time"] + [c for a in [*N_GYRO, *N_ACCEL] for c in (a, f"{a}_filtered")]
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(got[:, 0], cols["time"], atol=1e-9)
    for j, a in enumerate([*N_GYRO, *N_ACCEL]):
        raw, filt = got[3000:, 1 + 2 * j], got[3000:, 2 + 2 * j]
        np.testing.assert_allclose(got[:, 1 + 2 * j], cols[a], rtol=1e-9)          # raw kept
        assert np.std(filt) < 0.3 * np.std(raw), a


def test_an_accelerometer_in_g_read_as_m_s2_is_refused_not_silent(tmp_path, capsys):
    """Three accelerometer axes in g read in the assumed m/s^2 gave a velocity random walk
    9.8x too low with only the usual 'assumed' note (held-out trial, gnss-ins-sim's record
    with its accelerometer divided by 9.80665): gravity reads |a| = 1 there, never 9.81, so
    the record is refused in one line naming the unit; stated, it is read."""
    path = tmp_path / "imu_g.csv"
    cols = _record(path)
    g = tmp_path / "imu_in_g.csv"
    data = np.column_stack([cols[k] / 9.80665 if k in N_ACCEL else cols[k] for k in cols])
    np.savetxt(g, data, delimiter=",", header=",".join(cols), comments="", fmt="%.10g")
    code = main(["allan", str(g), "--json"])
    out, err = capsys.readouterr()
    assert code == 2 and json.loads(out)["exit_status"] == 2
    assert err.strip().splitlines()[-1].startswith("gyrodenoise: error:") and "--accel-unit g" in err
    out, err = _run(capsys, "allan", g, "--json", "--accel-unit", "g")
    assert json.loads(out)["axes"]["az"]["terms"]["N"] == pytest.approx(N_ACCEL["az"], rel=0.1)
    _run(capsys, "allan", path, "--json")          # in m/s^2: |a| 9.81, read as it is
