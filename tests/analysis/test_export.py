"""Kalibr / MATLAB export of the Allan terms: conversions worked by hand."""

import argparse
import datetime
import math
import re

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.io import export
from gyrodenoise.errors import InputError
from tests.helpers import assert_golden

# a known case, in the spec's units
TERMS = {"N": 0.15, "B": 2.0, "K": 30.0, "R": 5.0, "Q": 1e-4}


def _keys(text):
    """key -> (value string, comment) of the uncommented 'key: value' lines."""
    out = {}
    for line in text.splitlines():
        m = re.match(r"^([a-z_]+):\s*([^#\s]+)\s*(#.*)?$", line)
        if m:
            out[m.group(1)] = (m.group(2), m.group(3) or "")
    return out


def test_si_conversion_by_hand():
    si = export.terms_to_si(TERMS)
    # N = 0.15 deg/sqrt(h) = 0.15/60 deg/sqrt(s) = 0.0025 deg/sqrt(s) = 4.3633e-5 rad/sqrt(s)
    assert si["N_rad_sqrt_s"] == pytest.approx(0.15 * math.pi / 180 / 60, rel=1e-14)
    assert si["N_rad_sqrt_s"] == pytest.approx(4.36332313e-5, rel=1e-8)
    # B = 2 deg/h = 2/3600 deg/s = 9.6963e-6 rad/s
    assert si["B_rad_s"] == pytest.approx(9.69627362e-6, rel=1e-8)
    # K = 30 deg/h^1.5 = 30 / 216000 deg/s^1.5 = 2.4241e-6 rad/s^1.5
    assert si["K_rad_s1_5"] == pytest.approx(30 / 216000 * math.pi / 180, rel=1e-14)
    assert si["K_rad_s1_5"] == pytest.approx(2.42406841e-6, rel=1e-8)
    assert si["R_rad_s2"] == pytest.approx(5 / 3600 ** 2 * math.pi / 180, rel=1e-14)
    assert si["Q_rad"] == pytest.approx(1e-4 * math.pi / 180, rel=1e-14)


def _lines(text):
    """An exported file as golden JSON: its lines, today's date (in its header) normalised."""
    return {"lines": text.replace(datetime.date.today().isoformat(), "<date>").splitlines()}


@pytest.mark.golden
def test_kalibr_yaml_keys_units_and_placeholders():
    """The values by hand; the whole file (units, header, placeholders) is the reviewed
    tests/golden/kalibr_imu_yaml.json."""
    text = export.kalibr_imu_yaml(TERMS, 200.0, rostopic="/imu0", source="x.csv")
    assert_golden("kalibr_imu_yaml", _lines(text))
    k = _keys(text)
    assert set(k) == {"gyroscope_noise_density", "gyroscope_random_walk", "rostopic", "update_rate"}
    assert float(k["gyroscope_noise_density"][0]) == pytest.approx(4.36332313e-5, rel=1e-8)
    assert float(k["gyroscope_random_walk"][0]) == pytest.approx(2.42406841e-6, rel=1e-8)
    assert k["rostopic"][0] == "/imu0" and k["update_rate"][0] == "200.0"
    # a rate estimated from timestamps is written to 10 digits, still a float
    assert _keys(export.kalibr_imu_yaml(TERMS, 200.0000000001819))["update_rate"][0] == "200.0"
    # accelerometer keys: present only as commented placeholders (the golden file), never invented
    assert "accelerometer_noise_density" not in k
    # inflation multiplies both densities and is recorded
    k3 = _keys(export.kalibr_imu_yaml(TERMS, 200.0, inflate=3.0))
    assert float(k3["gyroscope_noise_density"][0]) == pytest.approx(3 * 4.36332313e-5, rel=1e-8)
    assert float(k3["gyroscope_random_walk"][0]) == pytest.approx(3 * 2.42406841e-6, rel=1e-8)


def test_kalibr_marks_upper_bounds():
    bounds = {"N": "fit", "B": "fit", "K": "upper_bound", "R": "upper_bound", "Q": "fit"}
    k = _keys(export.kalibr_imu_yaml(TERMS, 100.0, bounds=bounds))
    assert "UPPER BOUND" in k["gyroscope_random_walk"][1]
    assert "UPPER BOUND" not in k["gyroscope_noise_density"][1]


@pytest.mark.golden
def test_matlab_script_values_by_hand():
    text = export.matlab_gyroparams_script(TERMS)
    assert_golden("matlab_gyroparams", _lines(text))
    vals = dict(re.findall(r"'(\w+)', ([0-9.eE+-]+)", text))
    assert float(vals["NoiseDensity"]) == pytest.approx(0.15 * math.pi / 180 / 60, rel=1e-15)
    # BiasInstability is B itself (the plateau divided by 0.664), not the plateau
    assert float(vals["BiasInstability"]) == pytest.approx(2.0 / 3600 * math.pi / 180, rel=1e-15)
    assert float(vals["RandomWalk"]) == pytest.approx(30.0 / 3600 ** 1.5 * math.pi / 180, rel=1e-15)
    assert text.count("params = gyroparams(") == 1
    assert text.rstrip().endswith("rate random walk K.")
    # every continued line of the call ends its code part with "..." or ");"
    for line in text.splitlines():
        if line.startswith("    '"):
            code = line.split("%")[0].rstrip()
            assert code.endswith("...") or code.endswith(");")


def _parser():
    p = argparse.ArgumentParser()
    p.add_argument("input")
    export.add_export_options(p)
    return p


def test_export_from_args_on_a_real_fit(tmp_path):
    rec = gd.simulate("paper_fog", 200 * 600, seed=7)
    res = gd.allan(rec.rate_deg_s, 200.0)
    args = _parser().parse_args(["rec.csv", "--kalibr-yaml", str(tmp_path / "imu.yaml"),
                                 "--matlab", str(tmp_path / "gyro.m"), "--kalibr-rostopic", "/fog"])
    written = export.export_from_args(args, res)
    assert written == [str(tmp_path / "imu.yaml"), str(tmp_path / "gyro.m")]
    k = _keys((tmp_path / "imu.yaml").read_text())
    # the card's N = 0.006 deg/sqrt(h); the fit recovers it within 5 %
    assert float(k["gyroscope_noise_density"][0]) == pytest.approx(0.006 * np.pi / 180 / 60, rel=0.05)
    assert k["rostopic"][0] == "/fog" and float(k["update_rate"][0]) == 200.0
    assert "gyroparams" in (tmp_path / "gyro.m").read_text()
    # nothing asked, nothing written
    assert export.export_from_args(_parser().parse_args(["rec.csv"]), res) == []


def test_export_bad_path_and_factor_are_one_line_errors(tmp_path):
    res = gd.allan(gd.simulate("paper_fog", 5000, seed=8).rate_deg_s, 200.0)
    args = _parser().parse_args(["r.csv", "--kalibr-yaml", str(tmp_path / "no" / "such" / "imu.yaml")])
    with pytest.raises(InputError, match=r"imu\.yaml: cannot write"):
        export.export_from_args(args, res)
    args = _parser().parse_args(["r.csv", "--kalibr-yaml", str(tmp_path / "i.yaml"), "--kalibr-inflate", "-2"])
    with pytest.raises(InputError, match="--kalibr-inflate"):
        export.export_from_args(args, res)


@pytest.mark.slow
def test_allan_command_writes_exports_and_keeps_json_clean(tmp_path):
    """`gyrodenoise allan IN --json --kalibr-yaml --matlab`: files written, the
    Kalibr density equals the JSON's N converted by hand, stdout one JSON object."""
    import json
    import subprocess
    import sys
    rec = gd.simulate("paper_fog", 200 * 300, seed=9)
    src = tmp_path / "rec.csv"
    np.savetxt(src, np.column_stack([rec.time_s, rec.rate_deg_s]), delimiter=",",
               header="time,rate", comments="", fmt="%.12g")
    y, m = tmp_path / "imu.yaml", tmp_path / "gyro.m"
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "allan", str(src), "--json",
                        "--kalibr-yaml", str(y), "--matlab", str(m)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    obj = json.loads(p.stdout)
    n_deg_rth = obj["terms"]["N"]
    assert float(_keys(y.read_text())["gyroscope_noise_density"][0]) == pytest.approx(
        n_deg_rth * math.pi / 180.0 / 60.0, rel=1e-9)
    assert "'NoiseDensity'" in m.read_text()
    assert f"wrote {y}" in p.stderr
    # a bad path: one line, exit 2
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "allan", str(src),
                        "--matlab", str(tmp_path / "no" / "x.m")], capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "x.m" in p.stderr


@pytest.mark.parametrize("topic", ["a: b # c", "imu 0", "", "/imu0/"])
def test_bad_rostopic_is_a_one_line_error(tmp_path, topic):
    res = gd.allan(gd.simulate("paper_fog", 5000, seed=8).rate_deg_s, 200.0)
    args = _parser().parse_args(["r.csv", "--kalibr-yaml", str(tmp_path / "i.yaml"), "--kalibr-rostopic", topic])
    with pytest.raises(InputError, match="--kalibr-rostopic"):
        export.export_from_args(args, res)
    assert not (tmp_path / "i.yaml").exists()


def test_good_rostopics_are_written(tmp_path):
    res = gd.allan(gd.simulate("paper_fog", 5000, seed=8).rate_deg_s, 200.0)
    for topic in ("/imu0", "imu", "/vehicle/imu_raw", "~imu"):
        args = _parser().parse_args(["r.csv", "--kalibr-yaml", str(tmp_path / "i.yaml"), "--kalibr-rostopic", topic])
        export.export_from_args(args, res)
        assert _keys((tmp_path / "i.yaml").read_text())["rostopic"][0] == topic
