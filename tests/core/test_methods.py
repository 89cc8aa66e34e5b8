"""The method registry (gyrodenoise.core.methods) and what is derived from it."""

from __future__ import annotations

import inspect
import math
from pathlib import Path

import pytest

import gyrodenoise as gd
from gyrodenoise.core import kernels as K
from gyrodenoise.core import methods as M

CORE = Path(M.__file__).parent


def test_generated_header_is_the_registry_s():
    """gdmethods.h is checked in (the C builds need no Python); regenerating it gives the same file."""
    assert (CORE / M.HEADER).read_text() == M.c_header(), "run: python -m gyrodenoise.core.methods"


def test_ids_are_distinct_and_mirrored_by_the_c_core():
    ids = [m.id for m in M.METHODS]
    assert len(set(ids)) == len(ids) and len({m.name for m in M.METHODS}) == len(ids)
    assert K.METHODS == {m.name: m.id for m in M.METHODS}
    C = pytest.importorskip("gyrodenoise.core._gdcore")
    for m in M.METHODS:
        assert C.CONSTANTS[f"METHOD_{m.name.upper()}"] == m.id


def test_defaults_of_the_api_are_the_registry_s():
    assert inspect.signature(gd.denoise).parameters["method"].default == M.DEFAULT_METHOD
    assert inspect.signature(gd.Denoiser).parameters["method"].default == M.DEFAULT_METHOD
    p = K.make_params()
    for par in M.PARAMS:
        if par.slot is not None and par.applies_to(M.DEFAULT_METHOD):
            assert p[getattr(K, par.slot)] == float(par.default), par.name


def test_every_default_is_in_its_own_range():
    for par in M.PARAMS:
        if par.default is not None:
            assert par.error(par.default, 200.0) is None, par.name
            assert par.fmu_error(par.fmu_default(), 200.0) is None, par.name


@pytest.mark.parametrize("par", M.PARAMS, ids=lambda p: p.name)
def test_make_params_refuses_each_bound_naming_the_parameter(par):
    """Just outside each bound (and a NaN) is refused with one line naming the parameter;
    on a closed bound the value itself passes."""
    method = par.methods[0] if par.methods else "shakf"
    bad = [math.nan] if par.type is float else [2.5]
    if par.lo is not None:
        bad.append(par.lo if par.lo_open else (par.lo - 1 if par.type is int else math.nextafter(par.lo, -1e300)))
        if not par.lo_open and par.name != "sample_rate_hz":
            K.make_params(method=method, **{par.name: par.lo})
    if par.hi is not None:
        bad.append(par.hi if par.hi_open else (par.hi + 1 if par.type is int else math.nextafter(par.hi, 1e300)))
    if par.nyquist:
        bad.append(100.0)               # half of the default 200 Hz
    for v in bad:
        if par.off and v == 0:
            continue
        kw = {"method": method, par.name: v}
        with pytest.raises(ValueError, match=f"^{par.name} (out of range|must be)"):
            K.make_params(**kw)


def test_a_method_s_option_with_another_method():
    with pytest.raises(ValueError, match="max_motion_hz applies to method 'motion' only"):
        K.make_params(method="kf", max_motion_hz=5.0)
    with pytest.raises(TypeError, match="'min_cutof_hz'"):
        K.make_params(method="one_euro", min_cutof_hz=1.0)
    with pytest.raises(ValueError, match="method must be one of"):
        K.make_params(method="euro")


def test_fmu_bounds_are_inclusive_versions_of_the_ranges():
    for par in M.fmu_parameters():
        lo, hi = par.fmu_bounds()
        if lo is not None and not (par.off or par.default is None):
            assert par.error(lo, 1e9) is None, par.name
        if hi is not None:
            assert par.error(hi, 1e9) is None, par.name


def test_cli_options_are_derived():
    from gyrodenoise.cli import options as O
    assert O.FILTER_PARAMS["--order"] == "order" and O.FILTER_PARAMS["--beta"] == "beta"
    assert O.METHOD_OF_OPTION == {"--cutoff-hz": "lowpass", "--order": "lowpass", "--max-motion-hz": "motion",
                                  "--min-cutoff-hz": "one_euro", "--beta": "one_euro", "--d-cutoff-hz": "one_euro",
                                  "--causal": "motion", "--zero-phase": "lowpass", "--bias-tracking": "motion",
                                  "--bias-still-s": "motion", "--bias-memory-s": "motion",
                                  "--earth-rate-floor-deg-h": "motion"}


def test_c_butter_sos_equals_python_bit_for_bit():
    """gd_butter_sos (the native FMU's low-pass design, in the C core) is kernels.butter_sos."""
    C = pytest.importorskip("gyrodenoise.core._gdcore")
    for fs in (25.000625015646552, 200.0, 400.0, 8000.0, 1e6):
        for fc in (1e-3, 0.3, 3.3, 20.0, 0.2499 * fs, 0.45 * fs, 0.4999 * fs):
            for order in range(1, 9):
                assert C.butter_sos(order, fc, fs) == K.butter_sos(order, fc, fs), (order, fc, fs)
