"""The benchmarks' compiled loops: numba's ``njit`` (cached, without the GIL) where numba
is installed, else the plain Python function (same numbers, slower)."""

from __future__ import annotations

try:
    import numba
except ImportError:  # pragma: no cover
    numba = None

HAVE_NUMBA = numba is not None


def njit(fn):
    """``fn`` compiled by numba (``cache=True, nogil=True``), or ``fn`` itself without numba."""
    return numba.njit(cache=True, nogil=True)(fn) if numba is not None else fn
