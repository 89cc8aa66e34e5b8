"""The wheels of scripts/build_wheels.py: one per platform (cp311-abi3), built here from the sdist.

* every binary inspected (format, machine, what it links, glibc / minimum macOS, exports), with
  ``auditwheel show`` for the manylinux ones where auditwheel is installed;
* the linux x86_64 wheel installed into a fresh virtual environment with no compiler on the PATH:
  the core only (numpy and scipy are all it pulls), the compiled core imported from the
  wheel and equal to the plain-Python kernels, a short ``gyrodenoise demo``, and the
  ``mavlink`` command saying which extra to install;
* the quick tier of the core's tests (:data:`CORE_TIER`, less :data:`NOT_IN_THE_CORE_WHEEL`) run by
  pytest against that install, from a copy of tests/ outside the checkout (measured ~40 s here:
  ~10 s to install, ~30 s for some 600 tests);
* the aarch64 wheel's core imported by Debian's aarch64 CPython under qemu-aarch64 and compared
  with the x86_64 wheel's (~8 s: the arm64 .debs and numpy's aarch64 wheel fetched, ~3 s run);
* the sdist holds what building needs (the C core, the FMU sources, the model cards) and builds:
  the wheels are made from it in a clean folder.

The macOS and Windows binaries are only inspected here: no macOS; wine is here, but no Windows
CPython can be had (only the package registries are reachable: the embeddable zip and the NuGet
package cannot be fetched, and neither PyPI nor Debian ships a Windows CPython). The build is slow (~1 min: the sdist and a wheel in pip's isolated build
environments, zig for five targets) and needs setuptools from the package index or pip's cache.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import DATA, REPO, SHARED_DATA

sys.path.insert(0, str(REPO / "scripts"))
import build_wheels as bw  # noqa: E402

#: Debian's libc6-arm64-cross: the aarch64 C library qemu-aarch64 loads programs against
AARCH64_SYSROOT = Path("/usr/aarch64-linux-gnu")


def test_check_refuses_what_a_wheel_must_not_carry():
    linux = bw.TARGETS["linux_x86_64"]
    fine = bw.Inspection("ELF", "EM_X86_64", ["libc.so.6", "libm.so.6"], ["PyInit__gdcore"], (2, 14))
    assert bw.check(fine, linux) == []
    new_glibc = bw.Inspection("ELF", "EM_X86_64", ["libm.so.6"], ["PyInit__gdcore"], (2, 29))
    assert "glibc" in " ".join(bw.check(new_glibc, linux))
    stray = bw.Inspection("ELF", "EM_X86_64", ["libpython3.11.so.1.0"], ["PyInit__gdcore", "gd_step"], (2, 17))
    assert len(bw.check(stray, linux)) == 2
    mac = bw.TARGETS["macos_arm64"]
    assert bw.check(bw.Inspection("Mach-O", "Arm64", ["/usr/lib/libSystem.B.dylib"], ["_PyInit__gdcore"],
                                  min_os="14.0"), mac) == ["minimum macOS 14.0, expected 11.0"]
    win = bw.TARGETS["windows_x86_64"]
    assert bw.check(bw.Inspection("PE", "x86_64", ["python311.dll", "KERNEL32.dll"], ["PyInit__gdcore"]), win)


@pytest.fixture(scope="module")
def wheels(tmp_path_factory):
    if shutil.which("llvm-readobj") is None or shutil.which("llvm-nm") is None:
        pytest.skip("llvm-readobj / llvm-nm are needed to inspect the binaries (Debian: llvm)")
    try:
        bw.zig()
    except SystemExit as exc:
        pytest.skip(str(exc))
    out = tmp_path_factory.mktemp("dist")
    try:
        built = bw.build(list(bw.TARGETS.values()), out)
    except SystemExit as exc:
        if "No matching distribution" in str(exc) or "Could not find a version" in str(exc):
            pytest.skip(f"the build backend cannot be fetched here: {str(exc)[-200:]}")
        raise
    return out, {t.name: (whl, insp) for t, whl, insp in built}


@pytest.mark.slow
def test_every_wheel_is_tagged_abi3_and_carries_one_inspected_core(wheels):
    out, built = wheels
    assert set(built) == set(bw.TARGETS)
    for name, (whl, insp) in built.items():
        t = bw.TARGETS[name]
        assert whl.name.endswith(f"-cp311-abi3-{'.'.join(t.platform_tags)}.whl")
        with zipfile.ZipFile(whl) as z:
            binaries = [n for n in z.namelist() if n.endswith((".so", ".pyd", ".dylib", ".dll"))]
            wheel_meta = z.read(next(n for n in z.namelist() if n.endswith(".dist-info/WHEEL"))).decode()
            names = set(z.namelist())
        assert binaries == [f"gyrodenoise/core/{t.binary}"], name
        assert [ln[5:] for ln in wheel_meta.splitlines() if ln.startswith("Tag: ")] == \
            [f"cp311-abi3-{p}" for p in t.platform_tags]
        assert {"gyrodenoise/data/paper_fog.toml", "gyrodenoise/core/gdcore.c", "gyrodenoise/core/gdbias.c",
                "gyrodenoise/fmu/sources/native/gdfmi.c"} <= names
        assert bw.check(insp, t) == [], (name, insp)
        assert insp.exports in (["PyInit__gdcore"], ["_PyInit__gdcore"])


@pytest.mark.slow
def test_auditwheel_finds_the_linux_wheels_manylinux2014(wheels):
    if shutil.which("auditwheel") is None and not _has_module("auditwheel"):
        pytest.skip("auditwheel is not installed (pip install auditwheel)")
    out, built = wheels
    for name in ("linux_x86_64", "linux_aarch64"):
        proc = subprocess.run([sys.executable, "-m", "auditwheel", "show", str(built[name][0])],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        text = " ".join(proc.stdout.split())
        arch = name.split("_", 1)[1]
        assert f'consistent with the following platform tag: "manylinux_2_17_{arch}"' in text, text
        assert "requires no external shared libraries" in text or "libpython" not in text


def _has_module(name):
    import importlib.util
    return importlib.util.find_spec(name) is not None


@pytest.mark.slow
def test_the_sdist_holds_what_the_build_needs(wheels):
    out, _ = wheels
    (sdist,) = out.glob("gyrodenoise-*.tar.gz")
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    need = {"setup.py", "pyproject.toml", "README.md", *(f"gyrodenoise/core/{s}" for s in bw.SOURCES),
            "gyrodenoise/core/gdcore.h", "gyrodenoise/core/gdmethods.h", "gyrodenoise/core/gdsim.h",
            "gyrodenoise/data/paper_fog.toml", "gyrodenoise/fmu/sources/native/gdfmi.h"}
    assert need <= names, need - names
    packaged = {str(p.relative_to(REPO)) for p in (REPO / "gyrodenoise" / "fmu" / "sources").rglob("*")
                if p.is_file() and "__pycache__" not in p.parts and p.suffix in (".c", ".h", ".py")}
    assert packaged <= names, packaged - names


def _venv_with_the_linux_wheel(whl, venv, *extra):
    """A fresh venv at ``venv`` with the wheel ``whl`` (and the distributions ``extra``) installed by
    pip, binaries only, the PATH holding the venv alone (no cc, gcc, clang or zig can be found by
    pip or the package); (its python, the environment of its programs)."""
    if not sys.platform.startswith("linux") or os.uname().machine != "x86_64":
        pytest.skip("the linux x86_64 wheel runs on linux x86_64")
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    py = venv / "bin" / "python"
    env = {"PATH": str(venv / "bin"), "HOME": os.environ.get("HOME", str(venv.parent)), "CC": "no-compiler",
           "PIP_DISABLE_PIP_VERSION_CHECK": "1", "LANG": "C.UTF-8"}
    for k in ("PIP_INDEX_URL", "PIP_EXTRA_INDEX_URL", "PIP_FIND_LINKS", "PIP_NO_INDEX"):
        if k in os.environ:
            env[k] = os.environ[k]
    proc = subprocess.run([str(py), "-c", "import shutil; print([c for c in ('cc', 'gcc', 'clang', 'zig') "
                           "if shutil.which(c)])"], capture_output=True, text=True, env=env, timeout=60)
    assert proc.stdout.strip() == "[]", proc.stdout
    proc = subprocess.run([str(py), "-m", "pip", "install", "-q", "--only-binary", ":all:", str(whl), *extra],
                          capture_output=True, text=True, env=env, cwd=venv.parent, timeout=600)
    if proc.returncode != 0 and ("No matching distribution" in proc.stderr or "Could not find" in proc.stderr):
        pytest.skip(f"a distribution cannot be fetched here: {proc.stderr.strip().splitlines()[-1]}")
    assert proc.returncode == 0, proc.stderr
    return py, env


@pytest.mark.slow
def test_the_linux_wheel_runs_in_a_fresh_venv_without_a_compiler(wheels, tmp_path):
    out, built = wheels
    venv = tmp_path / "venv"
    py, env = _venv_with_the_linux_wheel(built["linux_x86_64"][0], venv)
    proc = subprocess.run([str(py), "-m", "pip", "list", "--format", "json"], capture_output=True, text=True,
                          env=env, timeout=120)
    dists = {d["name"].lower() for d in json.loads(proc.stdout)} - {"pip", "setuptools", "wheel"}
    assert dists == {"gyrodenoise", "numpy", "scipy"}

    # the wheel's core, imported from the venv, equals the plain-Python kernels bit for bit
    check = (
        "import numpy as np, gyrodenoise as gd\n"
        "from gyrodenoise.core import _gdcore, kernels as K\n"
        "from gyrodenoise.core.batch import run, compiled_core\n"
        "import sys; assert compiled_core() and _gdcore.__file__.startswith(sys.prefix), _gdcore.__file__\n"
        "assert _gdcore.__file__.endswith('_gdcore.abi3.so'), _gdcore.__file__\n"
        "z = np.ascontiguousarray(gd.simulate('paper_fog', 3000, seed=1).rate_deg_s)\n"
        "for m in ('shakf', 'kf', 'motion', 'lowpass'):\n"
        "    p = K.make_params(method=m, sample_rate_hz=200.0)\n"
        "    c = run(p, K.init_state(p), z)[0]\n"
        "    py = run(p, K.init_state(p), z, compiled=False)[0]\n"
        "    assert np.array_equal(c, py), m\n"
        "print('ok')\n")
    proc = subprocess.run([str(py), "-c", check], capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=300)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-3000:]

    gd = venv / "bin" / "gyrodenoise"
    proc = subprocess.run([str(gd), "demo", "--hours", "0.01", "--dynamic-s", "4", "--no-plots", "--json",
                           "--out", str(tmp_path / "demo")], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(proc.stdout)
    assert res["static"] and res["dynamic"]
    assert "plain-Python kernels" not in proc.stderr

    proc = subprocess.run([str(gd), "mavlink", str(DATA / "fs-batt.log.tlog"), "--out", str(tmp_path / "m")],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert proc.stderr.strip().endswith("pip install 'gyrodenoise[logs]'"), proc.stderr


#: the folders of the quick tier run against the installed core wheel: the core, the analyses, the
#: simulator, the recordings, the CLI (the FMU, flight-log, model-gap and benchmark tests are the
#: extras' and the checkout's)
CORE_TIER = ("tests/core", "tests/analysis", "tests/simulator", "tests/io", "tests/cli")
#: the quick tests of CORE_TIER the core wheel cannot run (deselected by node-id prefix), and why:
#: each one fails without it; a new test that needs an extra fails the run until it is listed here
NOT_IN_THE_CORE_WHEEL = {
    "tests/core/test_c_core_equals_python.py::test_motion_params_of_the_native_fmu_equal_python":
        "calls gd_motion_params (the FMU's) in the core by ctypes: the wheel's core exports PyInit__gdcore alone",
    "tests/core/test_motion.py::test_real_flight_keeps_the_low_band_motion[px4_sample.ulg]": "[logs]",
    "tests/core/test_one_euro.py::test_bridge_filters_a_log_with_it": "[logs]",
    "tests/core/test_rigid_body_band.py::test_bridge_": "[logs]",
    "tests/io/test_timebase.py::test_real_logs[copter_20211202-132613.tlog": "[logs]",
    "tests/io/test_timebase.py::test_real_logs[sitl_copter_reboot.tlog": "[logs]",
    "tests/analysis/test_plots.py": "[report]",
    "tests/analysis/test_demo_figures.py": "[report]",
    "tests/analysis/test_spectrum.py::test_fleet_report_lists_each_logs_dominant_vibration_peak": "[report]",
    "tests/cli/test_entry_point.py::test_programs_the_tests_start_import_this_checkout":
        "asserts the checkout's package is imported, not an installed one",
}
#: the root conftest.py of the copied tests: the run stops unless gyrodenoise and its compiled core
#: are the venv's (the wheel's), not a checkout's; it writes where they were imported from
WHEEL_GUARD = """\
import sys
from pathlib import Path
import gyrodenoise
from gyrodenoise.core import _gdcore
for _m in (gyrodenoise, _gdcore):
    assert _m.__file__.startswith(sys.prefix + "/"), f"{_m.__name__} from {_m.__file__}, not the venv {sys.prefix}"
Path(__file__).with_name("imported_from").write_text(gyrodenoise.__file__ + "\\n" + _gdcore.__file__ + "\\n")
"""


def test_every_test_left_out_of_the_core_wheels_tier_exists():
    """Each entry of NOT_IN_THE_CORE_WHEEL names a test file of CORE_TIER and, after ``::``, the start
    of a test function in it (a renamed test would leave an entry that deselects nothing)."""
    for node in NOT_IN_THE_CORE_WHEEL:
        path, _, name = node.partition("::")
        assert path.startswith(tuple(f"{d}/" for d in CORE_TIER)) and (REPO / path).is_file(), node
        fn = name.split("[")[0]
        if fn:
            assert re.search(rf"^def {re.escape(fn)}", (REPO / path).read_text(), re.M), node


def quick_tier_outside_the_checkout(dest):
    """Copy tests/ (and benchmarks/, which tests import) into ``dest`` with a pytest.ini of their
    own (no ``pythonpath = .``, no xdist) and :data:`WHEEL_GUARD` as the root conftest.py: pytest
    run there imports gyrodenoise from the interpreter's site-packages. The pytest arguments."""
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    for d in ("tests", "benchmarks"):
        shutil.copytree(REPO / d, dest / d, ignore=skip)
    (dest / "pytest.ini").write_text("[pytest]\nmarkers =\n    slow: slow\n    golden: golden\n")
    (dest / "conftest.py").write_text(WHEEL_GUARD)
    return ["-m", "not slow", "-q", "-p", "no:cacheprovider", *CORE_TIER,
            *(f"--deselect={n}" for n in NOT_IN_THE_CORE_WHEEL)]


@pytest.mark.slow
def test_the_quick_tier_passes_against_the_linux_wheel_installed_without_a_compiler(wheels, tmp_path):
    """The quick tests of :data:`CORE_TIER` run by pytest from a copy outside the checkout, in a
    fresh venv holding the linux x86_64 wheel, pytest, hypothesis and allantools (the Allan
    reference, without its plotting dependencies): the core only, no compiler on the PATH."""
    out, built = wheels
    py, env = _venv_with_the_linux_wheel(built["linux_x86_64"][0], tmp_path / "venv", "pytest", "hypothesis")
    proc = subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps", "--only-binary", ":all:",
                           "allantools"], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "run"
    run.mkdir()
    args = quick_tier_outside_the_checkout(run)
    env["GYRODENOISE_SHARED_DATA"] = str(SHARED_DATA)
    proc = subprocess.run([str(py), "-m", "pytest", *args], capture_output=True, text=True, env=env, cwd=run,
                          timeout=900)
    tail = proc.stdout[-4000:] + proc.stderr[-2000:]
    assert proc.returncode == 0, tail
    site = tmp_path / "venv" / "lib"
    assert [Path(f).parent.relative_to(site).parts[1:] for f in (run / "imported_from").read_text().split()] == \
        [("site-packages", "gyrodenoise"), ("site-packages", "gyrodenoise", "core")]
    passed = re.search(r"(\d+) passed", proc.stdout)
    assert passed and int(passed.group(1)) > 500, tail


#: what the aarch64 and the x86_64 cores compute from the same inputs (saved to the .npz named by
#: argv[1]): the simulator (sim_run), each method's batch run (restarts, record) and per-sample steps
CORE_PROBE = """\
import platform, sys
import numpy as np
import gyrodenoise as gd
from gyrodenoise.core import _gdcore, kernels as K
from gyrodenoise.core.batch import run, run_offline
machine = {"x86_64": "x86_64", "aarch64": "aarch64", "arm64": "aarch64"}[platform.machine()]
assert machine == sys.argv[2] and _gdcore.__file__.startswith(sys.argv[3]), (machine, _gdcore.__file__)
z = np.ascontiguousarray(gd.simulate("paper_fog", 4000, seed=7).rate_deg_s)
restarts = np.zeros(z.size, bool)
restarts[2500] = True
out = {"simulated": z}
for m in ("shakf", "kf", "motion", "lowpass"):
    p = K.make_params(method=m, sample_rate_hz=200.0)
    out[m] = run(p, K.init_state(p), z, restarts)[0]
    d = gd.Denoiser(sample_rate_hz=200.0, method=m)
    out[m + "_step"] = np.array([d.step(v, i == 150) for i, v in enumerate(z[:300])])
out["motion_offline"] = run_offline(K.make_params(method="motion", sample_rate_hz=200.0), z, restarts)
np.savez(sys.argv[1], **out)
"""


#: deg/s: the offline smoother's numpy arithmetic, aarch64 against x86_64 (the C core's passes are exact)
OFFLINE_ATOL = 1e-15


def _apt_arm64(cache):
    """apt-get with its own lists, cache and status under ``cache`` for Debian's arm64 packages (the
    host's apt state and dpkg architectures untouched); skips where apt-get or the archive is absent."""
    if shutil.which("apt-get") is None or shutil.which("dpkg-deb") is None:
        pytest.skip("apt-get / dpkg-deb are needed to fetch Debian's arm64 Python")
    for d in ("lists/partial", "cache/archives/partial"):
        (cache / d).mkdir(parents=True, exist_ok=True)
    (cache / "status").touch()
    opts = ["-q", "-o", "APT::Architecture=arm64", "-o", "APT::Architectures::=arm64",
            "-o", f"Dir::State::Lists={cache / 'lists'}", "-o", f"Dir::Cache={cache / 'cache'}",
            "-o", f"Dir::State::status={cache / 'status'}", "-o", "Debug::NoLocking=1"]
    if os.geteuid() == 0:
        opts += ["-o", "APT::Sandbox::User=root"]
    proc = subprocess.run(["apt-get", *opts, "update"], capture_output=True, text=True, timeout=300)
    if proc.returncode != 0 or "arm64 Packages" not in proc.stdout:
        pytest.skip(f"Debian's arm64 package lists cannot be fetched: {(proc.stderr or proc.stdout)[-300:]}")
    return opts


@pytest.fixture(scope="module")
def aarch64_python(tmp_path_factory):
    """(root, site-packages, python X.Y) of Debian's aarch64 CPython unpacked from its .debs (apt-get
    download, dpkg-deb -x: nothing installed), with numpy's aarch64 wheel (pip download) unpacked
    into the site folder; run under ``qemu-aarch64 -L /usr/aarch64-linux-gnu``."""
    if shutil.which("qemu-aarch64") is None or not (AARCH64_SYSROOT / "lib" / "ld-linux-aarch64.so.1").is_file():
        pytest.skip("qemu-aarch64 and the aarch64 C library are needed (Debian: qemu-user, libc6-arm64-cross)")
    cache = tmp_path_factory.mktemp("arm64")
    opts = _apt_arm64(cache / "apt")
    deps = subprocess.run(["apt-cache", *opts, "depends", "python3-minimal"], capture_output=True, text=True,
                          timeout=60).stdout
    found = re.search(r"python(3\.\d+)-minimal", deps)
    if found is None:
        pytest.skip(f"no python3.X-minimal among python3-minimal's arm64 dependencies: {deps[-300:]}")
    xy = found.group(1)
    debs = cache / "debs"
    debs.mkdir()
    pkgs = [f"python{xy}-minimal", f"libpython{xy}-minimal", f"libpython{xy}-stdlib", "zlib1g", "libexpat1",
            "libffi8", "libgcc-s1", "libstdc++6"]       # numpy's extension modules need libgcc_s, libstdc++
    proc = subprocess.run(["apt-get", *opts, "download", *pkgs], capture_output=True, text=True, cwd=debs,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    root = cache / "root"
    for deb in sorted(debs.glob("*.deb")):
        subprocess.run(["dpkg-deb", "-x", str(deb), str(root)], check=True, timeout=120)
    site = cache / "site"
    wheels = cache / "wheels"
    proc = subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--only-binary", ":all:", "--no-deps",
                           "--platform", "manylinux2014_aarch64", "--platform", "manylinux_2_28_aarch64",
                           "--python-version", xy, "--implementation", "cp", "-d", str(wheels), "numpy"],
                          capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, PIP_DISABLE_PIP_VERSION_CHECK="1"))
    if proc.returncode != 0:
        pytest.skip(f"numpy's aarch64 wheel cannot be fetched: {proc.stderr.strip()[-300:]}")
    for whl in wheels.glob("*.whl"):
        with zipfile.ZipFile(whl) as z:
            z.extractall(site)
    return root, site, xy


def _probe(python, machine, site, out, env, prefix=()):
    proc = subprocess.run([*prefix, str(python), "-c", CORE_PROBE, str(out), machine, str(site)],
                          capture_output=True, text=True, env=env, timeout=600, cwd=out.parent)
    assert proc.returncode == 0, proc.stderr[-3000:]
    with np.load(out) as f:
        return {k: f[k] for k in f.files}


@pytest.mark.slow
def test_the_aarch64_wheels_core_under_qemu_equals_the_x86_64_wheels(wheels, aarch64_python, tmp_path):
    """The aarch64 wheel unpacked beside numpy's aarch64 wheel, imported by Debian's aarch64 CPython
    under qemu-aarch64: the simulator, each method (batch with a restart, per-sample steps) and the
    offline smoother equal the x86_64 wheel's core bit for bit (both built with -ffp-contract=off;
    the Butterworth design is Python's, so lowpass is exact too), the offline smoother to
    :data:`OFFLINE_ATOL` (its numpy part)."""
    if not sys.platform.startswith("linux") or os.uname().machine != "x86_64":
        pytest.skip("the x86_64 wheel's core is the reference: linux x86_64 only")
    out, built = wheels
    root, site, xy = aarch64_python
    for name, dest in (("linux_aarch64", site), ("linux_x86_64", tmp_path / "x86_64")):
        with zipfile.ZipFile(built[name][0]) as z:
            z.extractall(dest)
    lib = f"{root}/usr/lib/aarch64-linux-gnu:{root}/lib/aarch64-linux-gnu"
    env_a = {"PATH": os.environ["PATH"], "PYTHONHOME": str(root / "usr"), "PYTHONPATH": str(site),
             "LD_LIBRARY_PATH": lib, "PYTHONNOUSERSITE": "1", "LANG": "C.UTF-8"}
    a = _probe(root / "usr" / "bin" / f"python{xy}", "aarch64", site, tmp_path / "aarch64.npz", env_a,
               ("qemu-aarch64", "-L", str(AARCH64_SYSROOT)))
    env_x = {"PATH": os.environ["PATH"], "PYTHONPATH": str(tmp_path / "x86_64"), "LANG": "C.UTF-8"}
    x = _probe(sys.executable, "x86_64", tmp_path / "x86_64", tmp_path / "x86_64.npz", env_x)
    assert set(a) == set(x) and len(a) == 10
    differ = {k: float(np.max(np.abs(a[k] - x[k]))) for k in x if not np.array_equal(a[k], x[k], equal_nan=True)}
    # the offline smoother joins the core's passes with numpy (two_filter_rate, _blend), whose aarch64
    # and x86_64 builds differ in the last bits: measured 2.7e-20 deg/s (of 4.6e-3), the same with
    # compiled=False on both platforms, whose compiled and plain-Python results are equal on each
    assert set(differ) <= {"motion_offline"} and differ.get("motion_offline", 0.0) < OFFLINE_ATOL, differ
    dull = [k for k in x if not (np.isfinite(x[k]).all() and np.std(x[k]) > 0)]
    assert not dull, {k: x[k][:5] for k in dull}


@pytest.mark.slow
def test_the_sdist_compiles_its_core_in_a_clean_folder(wheels, tmp_path):
    """pip builds a wheel from the sdist alone (copied into an empty folder), the compiler on:
    the C core it compiles is the abi3 one, in a cp311-abi3 wheel."""
    if shutil.which(os.environ.get("CC", "cc")) is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler here")
    out, _ = wheels
    (sdist,) = out.glob("gyrodenoise-*.tar.gz")
    clean = tmp_path / "clean"
    clean.mkdir()
    shutil.copy2(sdist, clean / sdist.name)
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(clean / "w"),
                           str(clean / sdist.name)], capture_output=True, text=True, cwd=clean, timeout=600,
                          env=dict(os.environ, PIP_DISABLE_PIP_VERSION_CHECK="1"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    (whl,) = (clean / "w").glob("*.whl")
    assert "-cp311-abi3-" in whl.name, whl.name
    with zipfile.ZipFile(whl) as z:
        assert [n for n in z.namelist() if n.endswith(".so")] == ["gyrodenoise/core/_gdcore.abi3.so"]
