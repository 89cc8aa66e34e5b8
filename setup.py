from setuptools import setup, Extension

setup(ext_modules=[
    Extension(
        "gyrodenoise.core._gdcore",
        sources=["gyrodenoise/core/gdcore.c", "gyrodenoise/core/gdbias.c", "gyrodenoise/core/gdsim.c", "gyrodenoise/core/_gdcoremodule.c"],
        depends=["gyrodenoise/core/gdcore.h", "gyrodenoise/core/gdmethods.h", "gyrodenoise/core/gdsim.h"],
        # -ffp-contract=off: no fused multiply-add, so the C core equals the plain-Python
        # kernels bit for bit (tests/core/test_c_core_equals_python.py). -fschedule-insns -fsched-pressure:
        # register-pressure-aware scheduling before allocation, measured with
        # benchmarks/bench_core.py: the gated SHAKF loop 36.4 -> 33.6 ns/sample, kf
        # 29.2 -> 28.0, the others unchanged, outputs identical (clang ignores both, warning).
        extra_compile_args=["-O2", "-fschedule-insns", "-fsched-pressure", "-ffp-contract=off", "-std=c99"],
        libraries=["m"],
        # the stable ABI (_gdcoremodule.c defines Py_LIMITED_API 0x030B0000): one binary per
        # platform for every CPython >= 3.11, named _gdcore.abi3.so, in a wheel tagged cp311-abi3
        py_limited_api=True,
        # optional: where there is no C compiler (most Windows and macOS desktops) the
        # package installs without it and runs the plain-Python kernels (same numbers,
        # slower; gyrodenoise/core/batch.py says so in one warning line)
        optional=True,
    ),
], options={"bdist_wheel": {"py_limited_api": "cp311"}})
