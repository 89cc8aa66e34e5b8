"""A slim core and extras by user (pyproject.toml [project.optional-dependencies],
gyrodenoise/_extras.py): ``pip install gyrodenoise`` brings numpy and scipy only; a command
whose extra is missing says in one line which one to install, exit 2, no traceback.

A missing distribution is imitated by ``sys.modules[name] = None`` (import raises ImportError and
``importlib.util.find_spec`` answers None, as for a module that is not installed);
tests/test_install_wheels.py installs the core alone into a fresh virtual environment.
"""
import re
import sys
import tomllib

import pytest

from gyrodenoise._extras import EXTRAS, MissingExtra, extra_of, missing, require
from tests.helpers import DATA, REPO, run_main

PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
OPTIONAL = PROJECT["optional-dependencies"]


def _names(reqs):
    """Distribution names (with their own extras, as 'dask[distributed]') of requirement strings."""
    return [re.match(r"[A-Za-z0-9_.\-]+(\[[^\]]*\])?", r).group(0).lower() for r in reqs]


def _hide(monkeypatch, *modules):
    for m in modules:
        monkeypatch.setitem(sys.modules, m, None)


def test_the_core_needs_numpy_and_scipy_only():
    assert sorted(_names(PROJECT["dependencies"])) == ["numpy", "scipy"]


def test_every_extra_of_the_code_is_one_of_the_project_and_installs_its_modules():
    by_user = set(OPTIONAL) - {"all", "test", "docs"}
    assert set(EXTRAS) == by_user
    for extra, modules in EXTRAS.items():
        names = _names(OPTIONAL[extra])
        for m in modules:
            assert m in names or any(n.endswith(f"[{m}]") for n in names), (extra, m, names)


def test_all_is_every_extra_and_test_pulls_all():
    (everything,) = _names(OPTIONAL["all"])
    assert everything.startswith("gyrodenoise[") and set(everything[12:-1].split(",")) == set(EXTRAS)
    assert "gyrodenoise[all]" in _names(OPTIONAL["test"])


def test_require_names_the_missing_modules_and_the_extra_in_one_line(monkeypatch):
    _hide(monkeypatch, "pyulog", "tqdm")
    assert missing("logs") == ["pyulog", "tqdm"]
    assert missing("logs", "pymavlink") == []
    require("logs", "pymavlink")
    with pytest.raises(MissingExtra) as exc:
        require("logs", what="gyrodenoise mavlink")
    assert str(exc.value) == "gyrodenoise mavlink needs pyulog, tqdm, not installed: pip install 'gyrodenoise[logs]'"
    with pytest.raises(ValueError, match="not a module of the extra"):
        require("logs", "matplotlib")
    assert extra_of("matplotlib.pyplot") == "report" and extra_of("numpy") is None


def _one_line_install(status, err, extra):
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("gyrodenoise: error: ") and lines[0].endswith(f"pip install 'gyrodenoise[{extra}]'")
    return lines[0]


def test_mavlink_without_the_logs_extra(monkeypatch, tmp_path):
    _hide(monkeypatch, "pymavlink")
    status, _, err = run_main("mavlink", DATA / "fs-batt.log.tlog", "--out", tmp_path / "o", "--no-plots")
    assert "needs pymavlink," in _one_line_install(status, err, "logs")
    assert not (tmp_path / "o").exists()


def test_mavlink_plots_without_the_report_extra(monkeypatch, tmp_path):
    _hide(monkeypatch, "plotly")
    status, _, err = run_main("mavlink", DATA / "ardusub_small.BIN", "--out", tmp_path / "o")
    assert "(or --no-plots)" in _one_line_install(status, err, "report")


def test_fmu_build_without_the_fmu_extra(monkeypatch, tmp_path):
    _hide(monkeypatch, "fmpy")
    status, _, err = run_main("fmu", "build", "--out", tmp_path / "f")
    assert "gyrodenoise fmu build needs fmpy," in _one_line_install(status, err, "fmu")


def test_gap_figure_without_the_report_extra(monkeypatch, tmp_path):
    _hide(monkeypatch, "matplotlib")
    status, _, err = run_main("gap", "--allan", DATA / "missing.csv", "--model", "paper_fog",
                              "--out", tmp_path / "new.toml")
    assert "(or --no-plot)" in _one_line_install(status, err, "report")


def test_gap_fmu_engine_without_the_fmu_extra(monkeypatch, tmp_path):
    _hide(monkeypatch, "pythonfmu")
    status, _, err = run_main("gap", DATA / "missing.csv", "--model", "paper_fog", "--no-plot", "--engine", "fmu",
                              "--out", tmp_path / "new.toml")
    assert "needs pythonfmu," in _one_line_install(status, err, "fmu")
    assert "or --engine native" in err


def test_mavlink_urls_without_the_cluster_extra(monkeypatch, tmp_path):
    _hide(monkeypatch, "fsspec")
    status, _, err = run_main("mavlink", "memory://logs/a.tlog", "--out", tmp_path / "o", "--no-plots")
    assert "URL memory://logs/a.tlog" in _one_line_install(status, err, "cluster")
