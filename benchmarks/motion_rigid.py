"""``method="motion"`` with the rigid-body option (``max_motion_hz``) as methods for
benchmarks/tuned.py and benchmarks/real_motion.py:

    python benchmarks/real_motion.py --only path --method benchmarks/motion_rigid.py:band20 \\
        --method benchmarks/motion_rigid.py:band30
"""
import gyrodenoise as gd


def band20(rate_deg_s, sample_rate_hz):
    """gd.denoise(max_motion_hz=20): motion up to 20 Hz, content above counts as error."""
    return gd.denoise(rate_deg_s, sample_rate_hz, max_motion_hz=20.0)


def band30(rate_deg_s, sample_rate_hz):
    """gd.denoise(max_motion_hz=30)."""
    return gd.denoise(rate_deg_s, sample_rate_hz, max_motion_hz=30.0)
