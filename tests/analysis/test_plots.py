"""The figures (gyrodenoise.analysis.plots) drawn in this process: each is written as a PNG,
a panel that would show nothing is refused, and the residual PSD's flatness figure is the
ratio of its octave-band levels."""
import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.analysis import plots

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_octave_band_spread_is_the_ratio_of_the_band_levels():
    f_hz = np.arange(1025) * 0.5                 # the first and last (Nyquist) bins are left out
    assert plots.octave_band_spread(f_hz, np.ones_like(f_hz)) == pytest.approx(1.0)
    pxx = np.where(f_hz < 64.0, 1.0, 4.0)         # octaves from 4 Hz: 4-8 ... 32-64 at 1, 64-128+ at 4
    assert plots.octave_band_spread(f_hz, pxx) == pytest.approx(4.0)


def test_allan_and_psd_figures_are_written(tmp_path):
    fs = 100.0
    raw = gd.simulate("paper_fog", 6000, seed=2).rate_deg_s
    filtered = gd.denoise(raw, fs)
    paths = [plots.allan_figure({"raw": gd.allan(raw, fs), "filtered": gd.allan(filtered, fs)}, tmp_path / "a.png"),
             plots.psd_figure(raw - raw.mean(), fs, tmp_path / "p.png")]
    for p in paths:
        assert p.read_bytes()[:8] == PNG_MAGIC, p


def test_a_panel_with_a_flat_line_is_refused_and_nothing_is_written(tmp_path):
    t = np.arange(3000) / 100.0
    with pytest.raises(plots.EmptyFigureError):
        plots.series_figure(t, {"raw": np.zeros_like(t)}, tmp_path / "flat.png")
    assert not (tmp_path / "flat.png").exists()
