"""``compare`` and ``gap`` given several rate columns (``--rate-column gx,gy,gz`` as ``allan``
and ``denoise`` take it): compare gives Table 1 per axis (one JSON object whose ``axes`` maps
each column to the single-column object); gap fits a card to one sensor axis and refuses
several in one line. Known truth: seeded white noise of a different level per axis."""
import json
import math

import numpy as np
import pytest

from gyrodenoise.cli import main

FS = 100.0
N_TRUE = {"gx": 0.5, "gy": 1.0, "gz": 2.0}       # deg/sqrt(h)


def _record(path, n=6000):
    rng = np.random.default_rng(21)
    cols = {"time": np.arange(n) / FS, **{c: nd / 60.0 * math.sqrt(FS) * rng.standard_normal(n)
                                           for c, nd in N_TRUE.items()}}
    np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols), comments="",
               fmt="%.10g")


def _run(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_compare_over_several_axes_gives_each_axis_its_table(tmp_path, capsys):
    path = tmp_path / "imu.csv"
    _record(path)
    code, out, err = _run(capsys, "compare", path, "--rate-column", "gx,gz", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert list(d["axes"]) == ["gx", "gz"] and d["n_samples"] == 6000 and d["sample_rate_hz"] == FS
    for c, res in d["axes"].items():
        assert res["rows"]["raw"]["N"] == pytest.approx(N_TRUE[c], rel=0.1)
        assert set(res["rows"]) >= {"raw", "ar_fit", "kf", "shakf"}
    # each axis' object is the one that column alone gives
    code, out, err = _run(capsys, "compare", path, "--rate-column", "gz", "--json")
    assert code == 0, err
    alone = json.loads(out)
    assert alone["rows"] == d["axes"]["gz"]["rows"]
    code, out, err = _run(capsys, "compare", path, "--rate-column", "gx,gy")
    assert code == 0 and out.startswith("gx:\nTable 1") and "\n\ngy:\nTable 1" in out


def test_compare_refuses_a_missing_axis_in_one_line(tmp_path, capsys):
    path = tmp_path / "imu.csv"
    _record(path, n=200)
    code, out, err = _run(capsys, "compare", path, "--rate-column", "gx,gq")
    assert code == 2 and "no column 'gq'" in err and len(err.strip().splitlines()) == 1


def test_gap_refuses_several_axes_in_one_line(tmp_path, capsys):
    path = tmp_path / "imu.csv"
    _record(path, n=200)
    code, out, err = _run(capsys, "gap", path, "--rate-column", "gx,gy", "--model", "paper_fog",
                          "--out", tmp_path / "new.toml", "--engine", "native", "--no-plot")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "--rate-column gx,gy: gap fits a model card to one sensor axis" in err
    assert not (tmp_path / "new.toml").exists()
