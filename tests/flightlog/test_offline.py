"""The bridge's file mode filters a whole log with the offline form of ``motion``
by default (spec section 7: whole-record entry points may, per-sample
paths stay causal), ``--causal`` gives the causal filter, and the JSON and the text
summary say which form was used.

References, independent of the bridge's filtering code: the restarts from a rule
written in tests/flightlog/references.py (``ref_restarts``) on the timestamps read back by
pymavlink's DataFlash reader (``df_reference``); the offline form as
``gd.denoise(offline=True)`` run on EACH SESSION ON ITS OWN (an offline output
depends on its whole session and on nothing outside it); the causal form as
``Denoiser.process`` sample by sample.
"""
from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.denoiser import Denoiser

from tests.helpers import DATA, run_main, shared_log
from tests.flightlog.references import by_name, df_reference, ref_restarts

pytestmark = pytest.mark.slow          # real logs filtered whole, offline and causal

R2D = 180.0 / math.pi
LOG = "log171.bin"          # real ArduCopter log: 3 IMUs, a 2 s gap (restart) in each


def _main(*args):
    """``gyrodenoise mavlink ARGS`` in this process: (status, stdout, stderr)."""
    return run_main("mavlink", *args)


def _sessions(restarts):
    starts = [0, *[int(i) for i in np.flatnonzero(restarts) if i > 0], len(restarts)]
    return list(zip(starts[:-1], starts[1:]))


@functools.lru_cache(maxsize=2)
def _read(path):
    """pymavlink's reading of a DataFlash log (1-2 s for log171.bin: read once)."""
    return df_reference(path)[0]


@functools.lru_cache(maxsize=4)
def _reference(path, name, causal):
    """(raw float32 rad/s as logged, the expected filtered float32 rad/s, restarts) of stream
    ``name``; computed once per (log, stream, form): each form is the other's counter-check."""
    ref = _read(path)
    t, g = ref[name]
    rate = 1.0 / np.median(np.diff(t))
    r = ref_restarts(t)
    x = g.astype(np.float64) * R2D
    out = np.empty_like(x)
    for k in range(3):
        if causal:
            out[:, k] = Denoiser(rate, method="motion").process(x[:, k], r)
        else:                       # each session alone: nothing crosses a restart
            for a, b in _sessions(r):
                out[a:b, k] = gd.denoise(x[a:b, k], rate, method="motion", offline=True)
    return g, (out / R2D).astype(np.float32), r


@pytest.fixture(scope="module")
def default_json_run(tmp_path_factory):
    """log171.bin through the file mode with the default options, --no-plots --no-csv --json,
    run once for the tests that read it: (status, stdout, stderr)."""
    return _main(shared_log(LOG), "-o", tmp_path_factory.mktemp("offline_default"), "--no-plots", "--no-csv",
                 "--json")


@pytest.mark.parametrize("causal", [False, True])
def test_file_mode_offline_by_default_causal_on_request(tmp_path, request, causal):
    """log171.bin IMU2 (12k samples, one restart): the filtered log holds the offline
    form, per session, by default, and Denoiser's numbers with --causal; the JSON and
    the text summary name the form."""
    path = shared_log(LOG)
    opts = ["--causal"] if causal else []
    if causal:
        status, out, err = _main(path, "-o", tmp_path / "j", "--no-plots", "--no-csv", "--json", *opts)
    else:
        status, out, err = request.getfixturevalue("default_json_run")
    assert status == 0, err
    rep = json.loads(out)["logs"][0]
    assert rep["method"] == "motion" and rep["form"] == ("causal" if causal else "offline")
    g, expected, r = _reference(path, "IMU2", causal)
    assert r.sum() == by_name(rep)["IMU2"]["restarts"] == 1
    got, _ = df_reference(rep["output_log"])
    np.testing.assert_array_equal(got["IMU2"][1], expected)
    assert np.mean(got["IMU2"][1] != g) > 0.5                  # the filter did change the samples
    # the other form is a different output (the test tells the two apart)
    _, other, _ = _reference(path, "IMU2", not causal)
    assert np.mean(other != expected) > 0.5
    status, text, _ = _main(path, "-o", tmp_path / "t", "--no-plots", "--no-csv", *opts)
    assert status == 0
    assert ("method motion; causal:" if causal else "method motion; offline: whole record") in text
    assert " lag -0 ms" not in text                 # a lag of -0.2 ms reads 0 ms


def test_offline_output_stays_inside_each_sessions_raw_range(default_json_run):
    """The safety net checks an offline output against its whole session's raw range
    (it depends on the whole session): every stream of log171.bin passes, and every
    output sample lies inside [min, max] of its session's raw samples."""
    path = shared_log(LOG)
    status, out, err = default_json_run
    assert status == 0 and "NOT FILTERED" not in err
    rep = json.loads(out)["logs"][0]
    assert not any(s["left_raw"] for s in rep["streams"])
    ref = _read(path)
    got, _ = df_reference(rep["output_log"])
    for name in ("IMU", "IMU2", "IMU3"):
        t, g = ref[name]
        f = got[name][1]
        for a, b in _sessions(ref_restarts(t)):
            assert np.all(f[a:b] >= g[a:b].min(axis=0)) and np.all(f[a:b] <= g[a:b].max(axis=0)), name


def test_causal_option_combinations(tmp_path):
    """--causal with another method is refused (one line, exit 2, nothing written);
    with --method lowpass --zero-phase the low-pass's offline form is named; the
    FMU engine's form is causal (tests/flightlog/test_fmu_engine.py, where an FMU is built)."""
    log = DATA / "ardusub_small.BIN"
    status, out, err = _main(log, "-o", tmp_path / "x", "--method", "lowpass", "--causal", "--no-plots")
    assert status == 2 and out == "" and err.count("\n") == 1
    assert "--causal applies to --method motion only, not lowpass" in err
    assert not (tmp_path / "x").exists()
    status, out, err = _main(log, "-o", tmp_path / "z", "--method", "lowpass", "--zero-phase",
                             "--no-plots", "--no-csv", "--json")
    assert status == 0, err
    rep = json.loads(out)["logs"][0]
    assert rep["form"] == "offline" and "zero phase" in rep["form_note"]
    status, out, err = _main(log, "-o", tmp_path / "s", "--method", "shakf", "--no-plots", "--no-csv", "--json")
    assert status == 0 and json.loads(out)["logs"][0]["form"] == "causal"
