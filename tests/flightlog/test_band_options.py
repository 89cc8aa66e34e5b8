"""One rule for the band options, --cutoff-hz (the low-pass) and --max-motion-hz
(motion's rigid-body band): each is checked against each stream's rate and must
be below its Nyquist frequency. A stream that cannot take it is written raw with
its reason naming the option, like a stream too slow to denoise (exit status 0); a log
where no stream can take it is refused: one line, exit 2, nothing written."""
import json

import pytest

from gyrodenoise.flightlog.filtering import BAND_OPTIONS, refused_band_option
from tests.helpers import DATA, run_main, shared_log
from tests.flightlog.references import by_name

#: each band option with the arguments that select its method
OPTIONS = {"--cutoff-hz": ["--method", "lowpass", "--cutoff-hz"], "--max-motion-hz": ["--max-motion-hz"]}


@pytest.mark.parametrize("option", OPTIONS)
@pytest.mark.parametrize("hz", ["13", "100"])
def test_above_every_nyquist_of_a_log_is_refused(tmp_path, option, hz):
    """25 Hz log (Nyquist 12.5 Hz): one line naming the
    option and the Nyquist frequency, exit 2, nothing on stdout, nothing written."""
    out = tmp_path / "o"
    status, so, se = run_main("mavlink", DATA / "ardusub_small.BIN", "-o", out, "--no-plots", *OPTIONS[option], hz)
    assert status == 2 and so == "", se
    assert se.count("\n") == 1 and f"{option} {float(hz):g} is at or above the Nyquist" in se, se
    assert "12.5 Hz" in se and "Traceback" not in se
    assert not out.exists()


@pytest.mark.parametrize("option", OPTIONS)
def test_the_flown_50_hz_log_refuses_either_option_above_25_hz(tmp_path, option):
    """log171 (IMU, IMU2, IMU3 at 50 Hz): --max-motion-hz 100 and --cutoff-hz 30 alike."""
    log = shared_log("log171.bin")
    hz = "100" if option == "--max-motion-hz" else "30"
    status, so, se = run_main("mavlink", log, "-o", tmp_path / "o", "--no-plots", *OPTIONS[option], hz)
    assert status == 2 and so == "" and f"{option} {hz} is at or above" in se and "25 Hz" in se, se
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("option", OPTIONS)
def test_a_stream_that_cannot_take_it_is_not_filtered_with_the_reason_and_exit_0(tmp_path, option):
    """copter_00061: IMU[0], IMU[1] at 25 Hz, the batch sampler at about 2 kHz; 15 Hz is
    above the IMUs' Nyquist only: those two go out unfiltered with the reason naming the
    option and the rate (as a stream too slow to denoise does: a multi-rate log is
    ordinary), not counted as a failure, exit 0; the batch sampler is filtered."""
    log = shared_log("copter_00061-2021-11-21_18-03-38.bin")
    status, so, se = run_main("mavlink", log, "-o", tmp_path, "--no-plots", "--no-csv", "--json", *OPTIONS[option], "15")
    assert status == 0, se
    rep = json.loads(so)
    s = by_name(rep["logs"][0])
    param = {"--cutoff-hz": "cutoff_hz", "--max-motion-hz": "max_motion_hz"}[option]
    for name in ("IMU[0]", "IMU[1]"):
        assert s[name]["left_raw"] is None
        assert "cannot run at 24.9" in s[name]["not_filtered"] and param in s[name]["not_filtered"]
    assert rep["streams_left_raw"] == []
    assert s["ISB.gyro[0]"]["left_raw"] is None
    assert "cannot run" not in (s["ISB.gyro[0]"]["not_filtered"] or "")


@pytest.mark.parametrize("option", OPTIONS)
def test_above_every_nyquist_of_every_log_exits_2(tmp_path, option):
    import shutil
    logs = tmp_path / "logs"
    logs.mkdir()
    for name in ("a.BIN", "b.BIN"):
        shutil.copy(DATA / "ardusub_small.BIN", logs / name)
    status, _, se = run_main("mavlink", logs, "-o", tmp_path / "o", "--no-plots", "--jobs", "2", *OPTIONS[option], "20")
    assert status == 2 and f"{option} 20 is at or above the Nyquist" in se, se
    assert se.strip().count("\n") == 0, se          # one line, whichever band option


def test_which_band_option_the_core_refused():
    """The core's rate check names its parameter: that option, with the value given;
    another failure, or an option not given, is none of them."""
    assert BAND_OPTIONS == {"cutoff_hz": "--cutoff-hz", "max_motion_hz": "--max-motion-hz"}
    exc = ValueError("max_motion_hz out of range: 100.0 (must be ... below half the sample rate, 25 Hz)")
    assert refused_band_option(exc, {"max_motion_hz": 100.0}) == ("--max-motion-hz", 100.0)
    assert refused_band_option(ValueError("cutoff_hz out of range: 30.0"), {"cutoff_hz": 30}) == ("--cutoff-hz", 30.0)
    assert refused_band_option(exc, {}) is None
    assert refused_band_option(ValueError("warmup out of range"), {"cutoff_hz": 30.0}) is None
