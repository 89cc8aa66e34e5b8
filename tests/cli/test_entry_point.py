"""The console-script entry (``gyrodenoise.cli:entry``) leaves with ``os._exit``
after flushing: nothing it writes may be lost or differ from an in-process run."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.cli import main


@pytest.mark.slow
def test_entry_output_equals_in_process_main(tmp_path):
    rec = gd.simulate("paper_fog", 20_000, seed=11)
    src = tmp_path / "in.csv"
    np.savetxt(src, np.column_stack([rec.time_s, rec.rate_deg_s]), delimiter=",",
               header="time,rate", comments="", fmt="%.12g")
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "denoise", str(src), "-o", str(a)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert main(["denoise", str(src), "-o", str(b)]) == 0
    assert a.read_bytes() == b.read_bytes()
    assert len(a.read_text().splitlines()) == 20_001

    # a large JSON on a pipe arrives whole, exit status kept
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "allan", str(src), "--json"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    obj = json.loads(p.stdout)
    assert len(obj["tau_s"]) == len(obj["adev_deg_h"]) > 10


def test_entry_keeps_error_status(tmp_path):
    p = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "allan", str(tmp_path / "missing.csv")],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "missing.csv" in p.stderr


def test_api_functions_survive_cli_imports():
    """Building the CLI imports every subcommand module; none may shadow an API
    function of the package (a submodule ``gyrodenoise.gap`` once replaced gd.gap)."""
    from gyrodenoise.cli import build_parser
    build_parser()
    for name in gd.__all__:
        if name != "__version__":
            obj = getattr(gd, name)
            assert callable(obj) and not isinstance(obj, type(gd)), name


def test_programs_the_tests_start_import_this_checkout(tmp_path):
    """python -m gyrodenoise.cli and the console script, started from another folder, import
    the package of the checkout under test (tests/conftest.py puts it first on PYTHONPATH),
    not an installed copy of another checkout."""
    from tests.helpers import REPO
    p = subprocess.run([sys.executable, "-c", "import gyrodenoise; print(gyrodenoise.__file__)"],
                       capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert Path(p.stdout.strip()).resolve() == REPO / "gyrodenoise" / "__init__.py"
