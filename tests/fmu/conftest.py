"""Fixtures of the FMU tests over a module's ``built`` fixture ((FMU path, unzipped folder)):
its model description and the value reference of each variable."""
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402


@pytest.fixture(scope="module")
def md(built):
    return read_model_description(str(built[0]))


@pytest.fixture(scope="module")
def vr(md):
    return {v.name: v.valueReference for v in md.modelVariables}
