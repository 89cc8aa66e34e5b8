"""Broad humps of a gyro spectrum (gyrodenoise.flightlog.spectra.find_humps): a motor band
tens of Hz wide, what a tuner puts the notch on, which the narrow-line peak finder
(gyrodenoise.analysis.spectrum.find_peaks) never marks. Synthetic spectra of known truth: a
Welch estimate of K segments is the true PSD times chi2(2K)/2K (seeded), on 1 Hz bins to
500 Hz, as the 1 kHz LOG00037 at 1024 samples a segment; then the shared Betaflight log."""
from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.analysis import spectrum as sp
from gyrodenoise.flightlog.spectra import describe_hump, find_humps, hump_floor, summary_lines
from tests.helpers import SHARED_LOGS

F = np.arange(501, dtype=np.float64)         # 0..500 Hz, 1 Hz bins
SEGMENTS = 25


def _welch(true_psd, seed, segments=SEGMENTS):
    """A Welch estimate of ``true_psd`` from ``segments`` segments (chi-square scatter per bin)."""
    rng = np.random.default_rng(seed)
    return true_psd * rng.chisquare(2 * segments, size=len(true_psd)) / (2 * segments)


def _floor(slope=0.0):
    """A floor falling as f**-slope from 5 Hz (flat below), 1e-3 (deg/s)^2/Hz at 100 Hz."""
    return 1e-3 * (np.maximum(F, 5.0) / 100.0) ** (-slope)


def _hump(centre=128.0, top_db=15.0, sigma_oct=0.12):
    """A hump Gaussian in dB on log2 f: half its dB height at +-sigma sqrt(2 ln 2) octaves."""
    with np.errstate(divide="ignore"):
        o = np.log2(np.maximum(F, 1e-9) / centre)
    return 10.0 ** (top_db * np.exp(-0.5 * (o / sigma_oct) ** 2) / 10.0)


def test_a_narrow_line_is_a_peak_not_a_hump():
    true = _floor(0.0)
    k = 200
    true[k - 1:k + 2] += 1e-3 * 100.0 * np.array([0.25, 1.0, 0.25])    # +20 dB, the Hann main lobe
    for seed in range(5):
        psd = _welch(true, seed)
        assert find_humps(F, psd) == [], seed
        peaks = sp.find_peaks(F, psd, SEGMENTS, min_freq_hz=5.0, min_ratio=4.0)
        assert abs(peaks[0]["freq_hz"] - 200.0) < 1.0


@pytest.mark.parametrize("slope", [0.0, 1.0, 2.0])
def test_a_broad_hump_is_found_on_white_and_falling_floors(slope):
    """A 15 dB band 0.28 octave wide at half height (116-141 Hz), on white, 1/f and 1/f**2
    floors: one hump, centred within 3 %, its band within 0.06 octave, its height within
    2.5 dB; the narrow-line peak finder does not see it (the defect this fixes)."""
    sigma = 0.12
    half = sigma * np.sqrt(2.0 * np.log(2.0))
    lo, hi = 128.0 * 2.0 ** -half, 128.0 * 2.0 ** half
    for seed in range(5):
        psd = _welch(_floor(slope) * _hump(sigma_oct=sigma), seed)
        humps = find_humps(F, psd)
        assert len(humps) == 1, (seed, humps)
        q = humps[0]
        assert q["freq_hz"] == pytest.approx(128.0, rel=0.03)
        assert abs(np.log2(q["lo_hz"] / lo)) < 0.06 and abs(np.log2(q["hi_hz"] / hi)) < 0.06, q
        assert q["above_floor_db"] == pytest.approx(15.0, abs=2.5)
        assert q["harmonic_of_hz"] is None
        # its rms: the excess power over the true floor within the band found, to 15 %
        band = (F >= q["lo_hz"]) & (F <= q["hi_hz"])
        truth = np.sqrt(np.sum((_floor(slope) * (_hump(sigma_oct=sigma) - 1.0))[band]))
        assert q["amplitude_rms"] == pytest.approx(truth, rel=0.15)
        peaks = sp.find_peaks(F, psd, SEGMENTS, min_freq_hz=5.0, min_ratio=4.0)
        assert not any(lo <= p["freq_hz"] <= hi for p in peaks), peaks


def test_harmonic_humps_are_named():
    psd = _welch(_floor(1.0) * _hump(128.0, 18.0) * _hump(384.0, 10.0, 0.06), 3)
    humps = sorted(find_humps(F, psd), key=lambda q: q["freq_hz"])
    assert [round(q["freq_hz"] / 128.0) for q in humps] == [1, 3]
    assert humps[1]["harmonic_n"] == 3 and humps[1]["harmonic_of_hz"] == pytest.approx(humps[0]["freq_hz"])
    assert "(3 x 1" in describe_hump(humps[1])


@pytest.mark.parametrize("slope", [0.0, 1.0, 2.0, 3.0])
def test_no_hump_in_noise_alone(slope):
    """Smooth monotonic floors (with a steep low-pass knee at 300 Hz), 40 seeds each: no hump
    (a falsely found one in any of 160 spectra fails)."""
    knee = 1.0 / (1.0 + (F / 300.0) ** 8)
    for seed in range(40):
        assert find_humps(F, _welch(_floor(slope) * knee, 100 + seed)) == [], seed


def test_the_floor_follows_a_power_law_to_the_ends():
    """On a log-frequency grid a power law is a line: the floor equals it, ends included."""
    y = -20.0 * np.log10(np.geomspace(5.0, 500.0, 160))
    np.testing.assert_allclose(hump_floor(y, 73), y, atol=1e-9)


def test_a_bump_two_octaves_wide_is_the_floor():
    """Half its height 2.1 octaves wide: the floor's shape, no hump; at 0.7 octave a hump."""
    assert find_humps(F, _welch(_floor(1.0) * _hump(128.0, 12.0, sigma_oct=0.9), 7)) == []
    assert len(find_humps(F, _welch(_floor(1.0) * _hump(128.0, 12.0, sigma_oct=0.3), 7))) == 1


def test_summary_lines_name_the_hump():
    spec = {"available": True, "unit": "deg/s", "min_peak_freq_hz": 5.0, "min_peak_db": 6.02,
            "peaks": {"x": []}, "humps": {"x": [{"freq_hz": 128.4, "lo_hz": 113.0, "hi_hz": 147.0,
                                                 "width_octaves": 0.38, "above_floor_db": 19.2,
                                                 "amplitude_rms": 1.9, "harmonic_of_hz": None, "harmonic_n": 1}]}}
    assert summary_lines(spec)[0] == ("x: broad 113-147 Hz (centre 128 Hz), 1.9 deg/s rms, 19 dB over the floor")


LOG = SHARED_LOGS / "betaflight" / "LOG00037.BFL"


@pytest.mark.skipif(not LOG.is_file(), reason=f"third-party log not present: {LOG}")
def test_betaflight_motor_band_is_a_hump():
    """LOG00037's pre-filter gyro (debug GYRO_SCALED, 1 kHz): the motor band 110-145 Hz is
    a hump on every axis (the narrow-line finder marked a 47 Hz line on y only); the
    post-filter gyroADC, where the filters took it out, has none there."""
    from gyrodenoise.flightlog import blackbox
    bb = blackbox.read_blackbox(LOG)[0]
    for x, expect in ((bb.gyro_prefilter_dps, True), (bb.gyro_dps, False)):
        for k in range(3):
            f, psd, n = sp.welch_psd(x[:, k], 1000.0, 1024)
            band = [q for q in find_humps(f, psd) if 100.0 <= q["freq_hz"] <= 150.0]
            assert bool(band) is expect, (k, band)
            if expect:
                assert band[0]["lo_hz"] > 100.0 and band[0]["hi_hz"] < 155.0
                assert band[0]["above_floor_db"] > 12.0
