"""``method="motion"`` offline as a method for benchmarks/tuned.py:

    python benchmarks/tuned.py --method benchmarks/motion_offline.py:offline
"""
import gyrodenoise as gd


def offline(rate_deg_s, sample_rate_hz):
    """The forward and backward runs of the causal filter blended (gd.denoise(offline=True))."""
    return gd.denoise(rate_deg_s, sample_rate_hz, offline=True)
