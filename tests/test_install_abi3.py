"""The C core is written against CPython's stable ABI (3.11), so that one binary per platform,
tagged cp311-abi3, serves every CPython >= 3.11 (setup.py py_limited_api).

The binding is compiled here under its own ``Py_LIMITED_API`` with every warning an error: a
call outside the limited API (``PyFloat_AS_DOUBLE``, ``PyTuple_SET_ITEM``, a ``tp_name`` read)
is undeclared or an incomplete type there and fails the compile.
"""
import re
import shutil
import subprocess
import sysconfig

import pytest

from tests.helpers import REPO

CORE = REPO / "gyrodenoise" / "core"


def test_the_binding_asks_for_the_3_11_stable_abi():
    src = (CORE / "_gdcoremodule.c").read_text()
    defines = re.findall(r"^#define Py_LIMITED_API (\S+)", src, re.M)
    assert defines == ["0x030B0000"]
    assert src.index("#define Py_LIMITED_API") < src.index("#include <Python.h>")


def test_the_binding_compiles_under_the_limited_api_without_a_warning():
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler here")
    proc = subprocess.run([cc, "-fsyntax-only", "-std=c99", "-Wall", "-Werror", "-I", sysconfig.get_path("include"),
                           "-I", str(CORE), str(CORE / "_gdcoremodule.c")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_setup_builds_an_abi3_extension_in_a_cp311_abi3_wheel():
    src = (REPO / "setup.py").read_text()
    assert "py_limited_api=True" in src
    assert re.search(r'"bdist_wheel":\s*\{"py_limited_api":\s*"cp311"\}', src)


def test_the_core_built_here_is_the_abi3_one():
    from gyrodenoise.core import batch
    if not batch.compiled_core():
        pytest.skip("the C core is not built here")
    from gyrodenoise.core import _gdcore
    assert ".abi3." in _gdcore.__file__ or _gdcore.__file__.endswith(".pyd"), _gdcore.__file__
