"""gyrodenoise: gyro denoising with an online improved AR(n) model and a
modified Sage-Husa adaptive Kalman filter (Sun et al., Sensors 2016), Allan
variance analysis, a model-card gyro simulator, FMUs and a MAVLink bridge.

Python API (numpy arrays in, numpy out)::

    import gyrodenoise as gd
    filtered = gd.denoise(rate_deg_s, sample_rate_hz)                  # method="motion"
    paper = gd.denoise(rate_deg_s, sample_rate_hz, method="shakf", outlier_sigma=0)
    result = gd.allan(rate_deg_s, sample_rate_hz)
    record = gd.simulate("models/paper_fog.toml", n_samples, seed=0)
"""

from gyrodenoise._version import __version__
from gyrodenoise.denoiser import Denoiser, denoise

__all__ = ["Denoiser", "denoise", "allan", "simulate", "load_card", "gap", "__version__"]


def allan(rate_deg_s, sample_rate_hz, **kw):
    """Allan deviation and five-term fit; see :func:`gyrodenoise.analysis.allan.allan`."""
    from gyrodenoise.analysis.allan import allan as _allan
    return _allan(rate_deg_s, sample_rate_hz, **kw)


def simulate(card, n_samples, seed=0, true_rate_deg_s=None, restarts=None):
    """Simulated gyro record; see :func:`gyrodenoise.simulator.simulate`."""
    from gyrodenoise.simulator import simulate as _simulate
    return _simulate(card, n_samples, seed=seed, true_rate_deg_s=true_rate_deg_s,
                     restarts=restarts)


def gap(rate_deg_s, sample_rate_hz, card, **kw):
    """Model-gap workflow; see :func:`gyrodenoise.modelgap.gap` (imported on use:
    it pulls in scipy and matplotlib)."""
    from gyrodenoise.modelgap import gap as _gap
    return _gap(rate_deg_s, sample_rate_hz, card, **kw)


def load_card(path_or_name):
    """Read a model card; see :func:`gyrodenoise.simulator.load_card`."""
    from gyrodenoise.simulator import load_card as _load
    return _load(path_or_name)
