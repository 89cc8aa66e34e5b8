"""The frequency-by-throttle map (gyrodenoise.flightlog.heatmap) against SYNTHETIC truth:
a tone whose frequency follows the throttle as f = F sqrt(thr / REF), the way a motor's
vibration does, must make the map's ridge within one frequency bin of it in every bin,
and the drawn centre of a throttle-tracking harmonic notch with those F and REF must lie
on it (and miss it with another REF); a second harmonic lies on the notch's second line."""
from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.flightlog import heatmap as hmod
from gyrodenoise.flightlog.timeseries import Channels
from gyrodenoise.flightlog.vehicle_filters import ardupilot_chain

FS = 1000.0
F_HZ, REF = 100.0, 0.35


def tracked_tone(seconds=120.0, seed=1, second=0.0):
    """(t, gyro (n, 3) deg/s, throttle Channels at 10 Hz): the throttle a slow raised
    cosine 0.2..0.7, a 5 deg/s tone at F sqrt(thr / REF) (phase-continuous) on every
    axis, ``second`` deg/s at twice it, 1 deg/s white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FS)) / FS
    thr = 0.2 + 0.5 * (0.5 - 0.5 * np.cos(2 * np.pi * t / seconds))
    phase = 2 * np.pi * np.cumsum(F_HZ * np.sqrt(thr / REF)) / FS
    g = np.column_stack([5 * np.sin(phase) + second * np.sin(2 * phase) + rng.normal(0, 1, len(t))
                         for _ in range(3)])
    return t, g, Channels("CTUN.ThO", "0..1", t[::100], {"throttle": thr[::100]})


@pytest.fixture(scope="module")
def tone_map():
    t, g, thr = tracked_tone(second=2.0)
    return hmod.heatmap("synthetic", t, g, FS, thr, "throttle [0..1]")


def test_the_ridge_follows_the_throttle_tracked_tone_within_one_bin(tone_map):
    hm = tone_map
    df = hm.freq_hz[1] - hm.freq_hz[0]
    ok = hm.windows > 0
    assert ok.sum() >= 20 and hm.edges[0] > 0.2 - 0.02 and hm.edges[-1] < 0.7 + 0.02
    err = hm.ridge_hz()[ok] - F_HZ * np.sqrt(hm.centres[ok] / REF)
    assert np.max(np.abs(err)) <= df, err
    # a map that lost the square root (f proportional to throttle) would miss by tens of Hz
    assert np.max(np.abs(hm.ridge_hz()[ok] - F_HZ * hm.centres[ok] / REF)) > 5 * df


def _notch_stages(ref, fm_rat=0.5):
    params = {"INS_HNTCH_ENABLE": 1, "INS_HNTCH_MODE": 1, "INS_HNTCH_FREQ": F_HZ, "INS_HNTCH_REF": ref,
              "INS_HNTCH_FM_RAT": fm_rat, "INS_HNTCH_BW": 20, "INS_HNTCH_ATT": 40, "INS_HNTCH_HMNCS": 3}
    return ardupilot_chain(params)[0]


def test_the_drawn_notch_centre_lies_on_the_ridge_for_the_right_parameters(tone_map):
    hm = tone_map
    df = hm.freq_hz[1] - hm.freq_hz[0]
    ok = hm.windows > 0
    x = hm.centres[ok]
    lines, notes = hmod.notch_lines(_notch_stages(REF), x, hmod.throttle_notch_hz, FS / 2)
    assert notes == [] and [ln.label.split("harmonic ")[1][0] for ln in lines] == ["1", "2"]
    assert np.max(np.abs(lines[0].freq_hz - hm.ridge_hz()[ok])) <= df
    assert np.allclose(lines[1].freq_hz, 2 * lines[0].freq_hz)
    # the second harmonic's own ridge (above 1.5 x the fundamental) lies on the second line
    ridge2 = []
    for f1, row in zip(lines[0].freq_hz, hm.psd[ok]):
        band = (hm.freq_hz > 1.5 * f1) & (hm.freq_hz < 2.5 * f1)
        ridge2.append(hm.freq_hz[band][np.argmax(row[band])])
    assert np.max(np.abs(np.array(ridge2) - lines[1].freq_hz)) <= 2 * df
    wrong, _ = hmod.notch_lines(_notch_stages(0.5), x, hmod.throttle_notch_hz, FS / 2)
    assert np.max(np.abs(wrong[0].freq_hz - hm.ridge_hz()[ok])) > 2 * df


def test_measured_tracking_has_no_throttle_line_and_rpm_lines_follow_rpm():
    st = dict(_notch_stages(REF)[0], tracking="esc", reference=1.0, min_ratio=0.5)
    lines, notes = hmod.notch_lines([st], np.array([0.3, 0.5]), hmod.throttle_notch_hz, FS / 2)
    assert lines == [] and "follows esc" in notes[0]
    rpm = np.array([3000.0, 6000.0, 9000.0])
    lines, _ = hmod.notch_lines([st], rpm, hmod.rpm_notch_hz, FS / 2)
    # max(FREQ x FM_RAT, REF x rpm / 60): 50 Hz floor, then 100, 150 Hz
    assert np.allclose(lines[0].freq_hz, [50.0, 100.0, 150.0])


def test_window_psd_is_a_density_parseval():
    """White noise of sigma 2 deg/s: the window PSD integrates to sigma^2 (within 5 %)."""
    rng = np.random.default_rng(0)
    t = np.arange(200_000) / FS
    _, _, f, psd = hmod.window_psd(t, rng.normal(0, 2.0, len(t)), FS)
    assert abs(np.sum(psd.mean(axis=0)) * (f[1] - f[0]) / 4.0 - 1.0) < 0.05


def test_no_window_spans_a_gap_or_a_boot():
    t = np.concatenate([np.arange(1000), 5000 + np.arange(1000)]) / FS
    tc, _, _, _ = hmod.window_psd(t, np.zeros(len(t)), FS, nperseg=256)
    assert not np.any((tc > 1.0) & (tc < 5.0)) and len(tc) == 2 * 6
    boots = np.repeat([0, 1], 1000)
    tc, bc, _, _ = hmod.window_psd(np.arange(2000) / FS, np.zeros(2000), FS, boots=boots, nperseg=256)
    assert len(tc) == 2 * 6 and list(np.unique(bc)) == [0, 1]


def test_no_map_without_a_whole_window():
    """A 2 Hz stream with gaps (as a telemetry log's SCALED_IMU2) has no 32-sample window:
    no map. (The empty map the browser check found on ardusub_small.tlog had windows but
    none in a bin; heatmap now returns None for that too, not reproduced here.)"""
    t = np.concatenate([np.arange(20), 100 + np.arange(20)]) / 2.0
    thr = Channels("VFR_HUD.throttle", "0..1", t, {"throttle": np.full(len(t), 0.5)})
    assert hmod.heatmap("slow", t, np.zeros((len(t), 3)), 2.0, thr, "throttle") is None


def test_a_throttle_that_never_varied_gives_no_map_and_says_why(tone_map):
    """copter462_notch_fragment (never armed, throttle 0) drew a one-column map: windows in
    fewer than MIN_BINS bins are no map, and the note says how many; the tone's map has
    windows in every bin and is kept."""
    t, g, _ = tracked_tone(seconds=20.0)
    idle = Channels("CTUN.ThO", "0..1", t[::100], {"throttle": np.zeros(len(t[::100]))})
    hm = hmod.heatmap("idle", t, g, FS, idle, "throttle [0..1]")
    assert hm is not None and (hm.windows > 0).sum() == 1
    why = hmod.too_narrow(hm, "throttle")
    assert why.startswith(f"no frequency-by-throttle map: its {int(hm.windows.sum())} gyro windows fall in 1 of the "
                          f"{hmod.BINS} throttle bins")
    assert hmod.too_narrow(tone_map, "throttle") is None


class _BlackboxBlock:
    """One Betaflight log of a file as the blackbox adapter holds it: main frames at
    ``time_s``, their ``eRPM[i]`` columns (eRPM / 100, as logged)."""

    def __init__(self, time_s, erpm):
        self.time_s, self.main, self.throttle, self._erpm = time_s, np.ones(len(time_s)), None, erpm

    def columns(self, name):
        return self._erpm if name == "eRPM" else None


class _Parameters:
    def __init__(self, values, autopilot):
        self.values, self.autopilot = values, autopilot


class _BetaflightLog:
    """The parts of a Betaflight FlightLog the maps read: the pre-filter gyro (debug
    GYRO_SCALED), the eRPM columns, the header's motor_poles."""

    def __init__(self, stream, block, poles):
        from gyrodenoise.flightlog.autopilots import BETAFLIGHT
        from gyrodenoise.flightlog.formats import format_named
        self.gyro, self.payload, self.boots = [stream], [block], []
        self.format = format_named("blackbox")
        self._params = _Parameters({"motor_poles": str(poles)}, BETAFLIGHT)

    def parameters(self):
        return self._params


def test_betaflight_rpm_map_from_erpm_follows_the_motor_tone():
    """Betaflight's motor_rpm reads eRPM (rev/min = eRPM x 100 / (poles / 2)): a SYNTHETIC
    2 kHz pre-filter gyro with a 5 deg/s tone at the motors' rotation rate (rpm / 60,
    6000..18000 rev/min), eRPM logged for 4 motors with 14 poles: the RPM map's ridge is
    within one frequency bin of rpm / 60 in every bin, on the drawn 'motor rotation x1' line."""
    from gyrodenoise.flightlog.autopilots import BETAFLIGHT
    from gyrodenoise.flightlog.streams import GyroStream
    fs, seconds, poles = 2000.0, 60.0, 14
    rng = np.random.default_rng(4)
    t = np.arange(int(seconds * fs)) / fs
    rpm = 12000.0 - 6000.0 * np.cos(2 * np.pi * t / seconds)
    phase = 2 * np.pi * np.cumsum(rpm / 60.0) / fs
    g = np.column_stack([5 * np.sin(phase) + rng.normal(0, 1, len(t)) for _ in range(3)])
    erpm = np.round(np.column_stack([rpm * (1 + 0.002 * k) for k in range(4)]) * (poles / 2) / 100.0)
    s = GyroStream(name="gyro pre-filter (debug GYRO_SCALED)", message="debug", unit="deg/s", to_deg_s=1.0,
                   time_s=t, raw=g, index=np.arange(len(t)), rate_hz=fs, restarts=np.zeros(len(t), bool))
    log = _BetaflightLog(s, _BlackboxBlock(t, erpm), poles)
    maps, notes = hmod.log_heatmaps(log, None, stages=[], autopilot=BETAFLIGHT)
    (hm,) = maps
    assert hm.x_source == "eRPM[i]" and hm.x_label.startswith("mean motor RPM")
    df = hm.freq_hz[1] - hm.freq_hz[0]
    ok = hm.windows > 0
    assert ok.sum() >= 20
    assert np.max(np.abs(hm.ridge_hz()[ok] - hm.centres[ok] / 60.0)) <= df
    line = next(ln for ln in hm.lines if ln.label.startswith("motor rotation x1"))
    assert np.max(np.abs(np.interp(hm.centres[ok], line.x, line.freq_hz) - hm.ridge_hz()[ok])) <= df
