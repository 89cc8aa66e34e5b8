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


def test_gap_and_the_several_axes_form_take_skip_rows(tmp_path, capsys):
    """--skip-rows reaches gap's reader and the several-axes reader: a header row holding a number
    (a column named 1000) after two lines of free text is no header to the automatic preamble
    rule, so without the option gap names --skip-rows; with it the header is found and gap gets
    as far as the record's length."""
    p = tmp_path / "pre.csv"
    t = np.arange(2000) / 100.0
    g = np.random.default_rng(3).normal(0.0, 0.1, (2000, 3))
    rows = "\n".join(f"{a:.2f},{x:.6f},{y:.6f},{z:.6f},0" for a, (x, y, z) in zip(t, g))
    p.write_text("logged by bench 7\nrun 12 of 1000 samples\ntime,gx,gy,gz,1000\n" + rows + "\n")
    gap = ["gap", str(p), "--model", "paper_fog", "--out", str(tmp_path / "n.toml"), "--no-plot",
           "--rate-column", "gx"]
    assert main(gap) == 2
    assert "--skip-rows" in capsys.readouterr().err
    assert main([*gap, "--skip-rows", "2"]) == 2
    assert "only 2000 samples" in capsys.readouterr().err
    assert main(["allan", str(p), "--rate-column", "gx,gy,gz", "--skip-rows", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["axes"]) == {"gx", "gy", "gz"}
