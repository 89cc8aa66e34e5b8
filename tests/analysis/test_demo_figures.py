"""The demo's figures show the paper's model: its AR figures are drawn from a SHAKF run.

The package default (motion) identifies no AR model: AR figures drawn from it would be
flat zero lines, an empty residual PSD and c = 0. These tests read
the written PNGs back as pixels (independently of the code that drew them), check
the AR numbers against a plain SHAKF run, and check that an empty figure is refused.
"""
import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.analysis import plots
from gyrodenoise.core import kernels as K
from gyrodenoise.core.batch import run
from gyrodenoise.analysis.experiments import ar_identification, compare
from gyrodenoise.simulator import load_card

FS_HZ = 200.0


@pytest.fixture
def plt():
    """matplotlib.pyplot on the Agg backend (imported by the tests that draw: collecting
    this module imports no matplotlib)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot
    return matplotlib.pyplot


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo's static part on 3 min of the paper's FOG (seed 0), figures written."""
    card = load_card("paper_fog")
    rec = gd.simulate(card, 36_000, seed=0)
    res = compare(rec, ar_order=3, seed=0)
    out = tmp_path_factory.mktemp("demo")
    figs = plots.demo_figures(card, rec, res, out, ar_order=3, seed=0)
    return rec, res, {f.name: f for f in figs}


def coloured_rows(png):
    """Pixel rows holding saturated (coloured, not grey/black/white) pixels."""
    import matplotlib.image
    img = matplotlib.image.imread(png)[..., :3]
    sat = img.max(axis=2) - img.min(axis=2)
    return np.flatnonzero((sat > 0.3).any(axis=1))


def test_ar_model_is_the_shakf_rls_not_the_default(demo):
    rec, res, _ = demo
    p = K.make_params(ar_order=3, method="shakf", sample_rate_hz=FS_HZ)
    _, st = run(p, K.init_state(p), rec.rate_deg_s)
    ar = res["ar_model"]
    assert ar["phi"] == pytest.approx(K.phi(p, st), abs=0, rel=1e-12)
    assert ar["c_deg_s"] == pytest.approx(K.c_deg_s(p, st), abs=0, rel=1e-12)
    # the paper's FOG: a clearly identified model, not the zeros of an unidentified one
    assert min(abs(v) for v in ar["phi"]) > 0.02
    assert ar["c_deg_s"] != 0.0


def test_ar_convergence_curves_move_then_settle():
    rec = gd.simulate("paper_fog", 12_000, seed=0)
    theta, residual, warmup_s = ar_identification(rec.rate_deg_s, FS_HZ, 3)
    assert theta.shape == (12_000, 4)
    assert warmup_s == pytest.approx(1.0)
    early, late = theta[:200], theta[-2000:]
    for j in range(4):
        assert np.ptp(early[:, j]) > 10 * np.ptp(late[:, j]) > 0    # converges (paper Figs 4-5)
    assert np.all(np.isfinite(residual)) and np.std(residual) > 0


def test_demo_pngs_are_not_empty(demo):
    _, _, figs = demo
    assert set(figs) == {"allan.png", "series.png", "ar_convergence.png", "residual_psd.png"}
    for name, path in figs.items():
        rows = coloured_rows(path)
        # a flat line plus its legend covers ~12 rows; a curve that moves covers hundreds
        assert rows.size > 60, f"{name}: only {rows.size} pixel rows carry a coloured curve"


def test_an_empty_figure_is_refused(tmp_path, plt):
    fig, (a1, a2) = plt.subplots(2, 1)
    a1.plot([0, 1, 2], [0.3, 0.1, 0.2])
    a2.plot([0, 1, 2], [0.0, 0.0, 0.0])           # an AR parameter never identified
    with pytest.raises(plots.EmptyFigureError, match="flat"):
        plots._save(plt, fig, tmp_path / "flat.png")
    fig, ax = plt.subplots()
    ax.loglog([1, 2, 3], [0.0, 0.0, 0.0])         # the PSD of a zero residual
    with pytest.raises(plots.EmptyFigureError, match="shows no data"):
        plots._save(plt, fig, tmp_path / "zero_psd.png")
    assert not list(tmp_path.iterdir())            # nothing written
    assert not plt.get_fignums()                   # and the figures closed


def test_table1_flags_a_fit_that_misses_its_own_points():
    """The five-term fit of a filtered output can miss its own Allan points (the
    motion bank's 0.1-100 s hump read as rate random walk: 4.2x on this 30 min record,
    10x on the demo's 2 h); Table 1 says so for the series where it does and for no
    series where the fit holds."""
    from gyrodenoise.cli.commands import POOR_FIT, format_compare
    res = compare(gd.simulate("paper_fog", 360_000, seed=0), ar_order=3, seed=0)
    mis = res["fit_misfit_factor"]
    assert mis["raw"] < 1.5 and mis["ar_fit"] < 1.5        # sums of Eq. (40) noises: the fit holds
    assert mis["motion"] > POOR_FIT
    text = format_compare(res)
    line = next(x for x in text.splitlines() if x.startswith("Eq. (40) fit misses"))
    assert "(motion)" in line and "(raw)" not in line
    assert "motion: the causal filter" in text


def test_fit_misfit_of_white_noise_is_near_one():
    rng = np.random.default_rng(3)
    r = gd.allan(0.01 * rng.standard_normal(200_000), FS_HZ)
    assert 1.0 <= r.fit_misfit() < 1.3


def test_octave_band_spread_tells_white_from_coloured():
    from scipy.signal import lfilter, welch
    rng = np.random.default_rng(4)
    w = rng.standard_normal(400_000)
    f, p = welch(w, fs=FS_HZ, nperseg=8192)
    assert plots.octave_band_spread(f, p) < 1.3                    # white: flat within the scatter
    f, p = welch(lfilter([1.0], [1.0, -0.9], w), fs=FS_HZ, nperseg=8192)
    assert plots.octave_band_spread(f, p) > 50                     # AR(1) 0.9: ~360x from DC to Nyquist
