"""An installed (non-editable) gyrodenoise builds its FMUs, away from the source checkout.

The package is installed with pip into a temporary folder from a copy of the checkout's
pyproject.toml, setup.py, README.md and gyrodenoise/ (pip builds the wheel in its isolated
build environment: setuptools from the package index, as any install does; the runtime
dependencies are this environment's, ``--no-deps``). ``gyrodenoise fmu build`` then runs from
a working directory outside the checkout with PYTHONPATH naming only the installed copy: every
file the build reads (slave scripts, the variable declaration, the core's modules and C
sources, the native FMI layer, the model cards) must come from the package itself.
"""
import os
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from tests.helpers import REPO

FMU_NAMES = ("FogDenoiser", "SimulatedFog", "FogDenoiserNative", "SimulatedFogNative")


def _install(tmp_path):
    """pip install a copy of the package into tmp_path/site; returns the site folder."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy2(REPO / name, src / name)
    ignore = shutil.ignore_patterns("*.so", "*.pyd", "__pycache__", "*.egg-info", "build")
    shutil.copytree(REPO / "gyrodenoise", src / "gyrodenoise", ignore=ignore)
    site = tmp_path / "site"
    env = dict(os.environ, PIP_DISABLE_PIP_VERSION_CHECK="1")
    env.pop("PYTHONPATH", None)
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(site),
                           str(src)], capture_output=True, text=True, env=env, timeout=600, cwd=tmp_path)
    if proc.returncode != 0 and "setuptools" in proc.stderr and "No matching distribution" in proc.stderr:
        pytest.skip(f"pip cannot fetch the build backend here: {proc.stderr.strip().splitlines()[-1]}")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    shutil.rmtree(src)                     # nothing of the copy is left to read
    return site


@pytest.mark.slow
def test_installed_package_builds_the_fmus_outside_the_checkout(tmp_path):
    site = _install(tmp_path)
    assert (site / "gyrodenoise" / "fmu" / "variables.py").is_file()
    work = tmp_path / "elsewhere"          # the working directory: neither the checkout nor the site
    work.mkdir()
    out = tmp_path / "fmus"
    env = {k: v for k, v in os.environ.items() if not k.startswith("GYRODENOISE_")}
    env["PYTHONPATH"] = str(site)
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import gyrodenoise; "
            "assert gyrodenoise.__file__.startswith(sys.argv[1]), gyrodenoise.__file__; "
            "from gyrodenoise.cli import main; sys.exit(main(['fmu', 'build', '--out', sys.argv[2], '--platforms', 'linux64']))")
    proc = subprocess.run([sys.executable, "-c", code, str(site), str(out)], capture_output=True, text=True,
                          env=env, cwd=work, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr[-3000:]
    for name in FMU_NAMES:
        assert f"{name}: {out / name}.fmu" in proc.stdout, proc.stdout
        assert (out / f"{name}.fmu").is_file()
    assert not any(work.iterdir()), "the build wrote into its working directory"

    # the bundled files are the installed package's
    installed = site / "gyrodenoise"
    with zipfile.ZipFile(out / "FogDenoiser.fmu") as z:
        assert z.read("resources/gdcore/fmu/variables.py") == (installed / "fmu" / "variables.py").read_bytes()
        assert z.read("resources/fogdenoiser_fmu.py") == (installed / "fmu" / "sources" /
                                                           "fogdenoiser_fmu.py").read_bytes()
    with zipfile.ZipFile(out / "SimulatedFogNative.fmu") as z:
        assert z.read("sources/gdsim.c") == (installed / "core" / "gdsim.c").read_bytes()
        assert "resources/cards/paper_fog.gdcard" in z.namelist()

    # they load and run: the native and the pythonfmu denoiser give the same outputs
    from fmpy import simulate_fmu
    from fmpy.validation import validate_fmu
    t = np.arange(40) * 0.005
    signal = np.array(list(zip(t, 0.3 * np.sin(7.0 * t), t == 0.1)),
                      dtype=[("time", float), ("raw_rate", float), ("restart", bool)])
    runs = {}
    for name in ("FogDenoiserNative", "FogDenoiser"):
        path = str(out / f"{name}.fmu")
        assert validate_fmu(path) == [], name
        runs[name] = simulate_fmu(path, stop_time=t[-1], output_interval=0.005, input=signal,
                                  start_values={"method": "shakf", "ar_order": 2}, output=["filtered_rate"])
    assert np.array_equal(runs["FogDenoiserNative"]["filtered_rate"], runs["FogDenoiser"]["filtered_rate"])
    assert np.all(np.isfinite(runs["FogDenoiserNative"]["filtered_rate"]))
