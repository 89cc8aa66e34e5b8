"""The quick tier (``pytest -m "not slow"``) builds no FMU: every fixture of the tests that
calls an FMU builder of the package (or ``gyrodenoise fmu build``) requests one of
tests/conftest.py's SLOW_FIXTURES, which put its tests in the slow tier. Checked from the
tests' source text; a test function that builds inside itself is not a fixture and is left
to its own marks (a build that fails at once, such as one without a compiler, is quick)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.conftest import SLOW_FIXTURES

TESTS = Path(__file__).resolve().parent
#: the package's FMU builders (gyrodenoise.fmu.build, .native, .native3)
BUILDERS = frozenset({"build_fmu", "build_all", "build_native_fmu", "build_native_fmus"})


def _is_fixture(fn):
    for d in fn.decorator_list:
        target = d.func if isinstance(d, ast.Call) else d
        if (isinstance(target, ast.Attribute) and target.attr == "fixture") or \
                (isinstance(target, ast.Name) and target.id == "fixture"):
            return True
    return False


_BUILDS = re.compile(r"\b(?:%s)\s*\(|[\"']fmu[\"'],\s*[\"']build[\"']" % "|".join(sorted(BUILDERS)))


def _builds(text, fn):
    """Does the function call an FMU builder or run `... fmu build`?"""
    return bool(_BUILDS.search(ast.get_source_segment(text, fn) or ""))


def building_fixtures():
    """[(file, fixture, its parameters)] of every fixture under tests/ that builds FMUs."""
    out = []
    for path in sorted(TESTS.rglob("*.py")):
        text = path.read_text()
        if "build" not in text or "fixture" not in text:
            continue
        tree = ast.parse(text, str(path))
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)) and _is_fixture(fn) and _builds(text, fn):
                out.append((path.relative_to(TESTS), fn.name, {a.arg for a in fn.args.args}))
    return out


def test_every_fixture_that_builds_fmus_puts_its_tests_in_the_slow_tier():
    found = building_fixtures()
    names = {name for _, name, _ in found}
    assert {"native_build", "fmus", "fmu_dir"} <= names, names     # the scan sees them
    quick = [f"{path}: {name}" for path, name, params in found
             if name not in SLOW_FIXTURES and not params & SLOW_FIXTURES]
    assert not quick, ("fixtures that build FMUs in the quick tier (request `builds_fmus`, "
                       f"tests/conftest.py): {quick}")
