from setuptools import setup, Extension

setup(ext_modules=[
    Extension(
        "gyrodenoise.core._gdcore",
        sources=["gyrodenoise/core/gdcore.c", "gyrodenoise/core/_gdcoremodule.c"],
        depends=["gyrodenoise/core/gdcore.h"],
        extra_compile_args=["-O2", "-ffp-contract=off", "-std=c99"],
        libraries=["m"],
    ),
])
