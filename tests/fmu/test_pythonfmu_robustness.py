"""The pythonfmu FMUs (FogDenoiser.fmu, SimulatedFog.fmu) where the host or the state is wrong.

* A serialized FMU state that was truncated, or had a byte changed (a digit of a number, which
  still parses as JSON), is refused at fmi2SetFMUstate with the reason logged; the instance
  is left as it was and goes on from a good state. pythonfmu 0.7.0 answers fmi2SetFMUstate
  with fmi2OK (the slave returned) or fmi2Fatal (it raised), nothing else: the refusal is
  fmi2Fatal (status 4); the slaves keep the instance alive and usable after it.
* A host Python that cannot run the FMU (numpy not importable: blocked here by a
  sitecustomize in a C host's embedded interpreter; Python 3.10 where this machine has its
  libpython) is refused at fmi2Instantiate (NULL) with the reason logged, never a crash; and
  the process exits cleanly. A host whose Python really lacks numpy, and one that does not
  preload libpython (pythonfmu's binary then fails to load: the host's dlopen reports
  "undefined symbol: _Py_NoneStruct"), are not run here.
"""
import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise import fmu as F
from gyrodenoise.fmu import native
from tests.helpers import CHOST

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi1 import FMICallException  # noqa: E402

H = 0.005
FS = 1.0 / H
FMI_FATAL = 4

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

IO = {"FogDenoiser": ("raw_rate", "filtered_rate"), "SimulatedFog": ("true_rate", "measured_rate")}


@pytest.fixture(scope="module")
def fmu_dir(fmu_build):
    out, proc = fmu_build
    if proc.returncode != 0:
        pytest.skip(f"gyrodenoise fmu build failed: {proc.stderr[-500:]}")
    return out


def _inputs(name, n, seed=8):
    if name == "FogDenoiser":
        return gd.simulate("paper_fog", n, seed=seed, true_rate_deg_s=1.0).rate_deg_s
    return 2.0 * np.sin(2 * np.pi * 0.5 * np.arange(n) * H)


def _step(a, name, value, k):
    inp, out = IO[name]
    a.set(**{inp: float(value)})
    a.slave.doStep(k * H, H)
    return a.get(out)


def _corruptions(blob):
    """(what, bytes) of a serialized state: truncations and changed bytes."""
    text = blob.decode("utf-8")
    at = text.index('"n_steps": ') + len('"n_steps": ')       # a digit of a number: still JSON
    digit = text[:at] + str((int(text[at]) + 1) % 10) + text[at + 1:]
    flipped = bytearray(blob)
    flipped[len(blob) // 3] ^= 0x01                             # one bit in the middle
    return [("truncated by half", blob[: len(blob) // 2]), ("last byte cut", blob[:-1]),
            ("empty", b""), ("a digit changed", digit.encode("utf-8")), ("one bit flipped", bytes(flipped)),
            ("no checksum", json.dumps({k: v for k, v in json.loads(blob).items() if k != "sha256"}).encode())]


# ----------------------------------------------------------- FMU states
@pytest.mark.parametrize("name", list(IO))
def test_corrupted_or_truncated_state_refused_instance_usable(fmu_dir, name):
    z = _inputs(name, 120)
    ref = F.FmuInstance(fmu_dir / f"{name}.fmu", "ref")
    try:
        ref.initialize(**({"sample_period": H} if name == "FogDenoiser" else {"seed": 3}))
        expected = [_step(ref, name, z[k], k) for k in range(len(z))]
    finally:
        ref.free()

    a = F.FmuInstance(fmu_dir / f"{name}.fmu", "a")
    try:
        a.initialize(**({"sample_period": H} if name == "FogDenoiser" else {"seed": 3}))
        got = [_step(a, name, z[k], k) for k in range(60)]
        st = a.slave.getFMUstate()
        blob = bytes(a.slave.serializeFMUstate(st))
        a.slave.freeFMUstate(st)
        assert "sha256" in json.loads(blob)
        k = 60
        for what, bad in _corruptions(blob):
            n_logged = len(a.messages)
            marker = a.slave.deSerializeFMUstate(bad)
            with pytest.raises(FMICallException) as exc:
                a.slave.setFMUstate(marker)
            a.slave.freeFMUstate(marker)
            assert exc.value.status == FMI_FATAL, what
            reasons = [m for s, _, m in a.messages[n_logged:] if s >= 3]
            assert any("fmi2SetFMUstate refused" in m and "corrupted serialized FMU state" in m
                       and "the instance is unchanged" in m for m in reasons), (what, reasons)
            # the instance is unchanged: the next sample continues the run
            got.append(_step(a, name, z[k], k))
            k += 1
        # and a good state restores
        good = a.slave.deSerializeFMUstate(blob)
        a.slave.setFMUstate(good)
        a.slave.freeFMUstate(good)
        again = [_step(a, name, z[j], j) for j in range(60, len(z))]
    finally:
        a.free()
    assert got == expected[:k]
    assert again == expected[60:]


def test_state_of_another_version_refused_instance_unchanged(fmu_dir):
    z = _inputs("FogDenoiser", 40)
    a = F.FmuInstance(fmu_dir / "FogDenoiser.fmu", "v")
    try:
        a.initialize(sample_period=H)
        first = [_step(a, "FogDenoiser", z[k], k) for k in range(20)]
        st = a.slave.getFMUstate()
        blob = json.loads(bytes(a.slave.serializeFMUstate(st)))
        a.slave.freeFMUstate(st)
        blob["version"] = 99
        del blob["sha256"]
        blob["sha256"] = hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()
        other = a.slave.deSerializeFMUstate(json.dumps(blob).encode())
        with pytest.raises(FMICallException) as exc:
            a.slave.setFMUstate(other)
        a.slave.freeFMUstate(other)
        assert exc.value.status == FMI_FATAL
        assert any("state version 99, expected" in m for _, _, m in a.messages)
        rest = [_step(a, "FogDenoiser", z[k], k) for k in range(20, 40)]
    finally:
        a.free()
    np.testing.assert_array_equal(first + rest, gd.denoise(z, FS))


# ----------------------------------------------------------- a host Python that cannot run them
def _libpython(python):
    """(libpython path, prefix) of another Python on this machine (on PATH, or a sibling of
    this one's install, as pyenv lays them out), or (None, None)."""
    siblings = sorted(Path(sys.base_prefix).parent.glob(f"*/bin/{python}"))
    for exe in [shutil.which(python), *map(str, siblings)]:
        if exe is None:
            continue
        found = _libpython_of(exe)
        if found[0] is not None:
            return found
    return None, None


def _libpython_of(exe):
    out = subprocess.run([exe, "-c", "import sysconfig, sys; print(sysconfig.get_config_var('LIBDIR')); "
                          "print(sysconfig.get_config_var('LDLIBRARY')); print(sys.prefix)"],
                         capture_output=True, text=True)
    if out.returncode != 0:
        return None, None
    libdir, name, prefix = out.stdout.split("\n")[:3]
    path = Path(libdir) / name
    return (path, prefix) if ".so" in name and path.is_file() else (None, None)


def _this_libpython():
    libdir, name = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("LDLIBRARY")
    path = Path(libdir or "") / (name or "")
    return path if name and ".so" in name and path.is_file() else None


@pytest.fixture(scope="module")
def unzipped(fmu_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("robust_unz")
    for name in IO:
        with zipfile.ZipFile(fmu_dir / f"{name}.fmu") as zf:
            zf.extractall(out / name)
    return out


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed: the C host cannot be built")
    exe = tmp_path_factory.mktemp("robust_host") / "host"
    subprocess.run(["gcc", "-std=c99", "-O2", f"-I{native.fmi_headers_dir()}", str(CHOST / "host.c"),
                    "-o", str(exe), "-ldl", "-lm"], check=True, capture_output=True, text=True)
    return exe


BLOCK_NUMPY = '''import sys
class _Block:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" or name.startswith("numpy."):
            raise ModuleNotFoundError("No module named 'numpy' (blocked by the test)", name=name)
sys.meta_path.insert(0, _Block())
'''


def _run_host(host, d, libpython, env_extra, name, stdin="0.5 0\n0.25 0\n"):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(LD_PRELOAD=str(libpython), **env_extra)
    args = ["--in", "true_rate", "--out", "measured_rate"] if name == "SimulatedFog" else []
    return subprocess.run([str(host), str(d), "run", "--log", *args], input=stdin, capture_output=True,
                          text=True, env=env, timeout=120)


@pytest.mark.slow
def test_host_python_without_numpy(unzipped, host, tmp_path):
    lib = _this_libpython()
    if lib is None:
        pytest.skip("no shared libpython for this Python")
    (tmp_path / "sitecustomize.py").write_text(BLOCK_NUMPY)
    env = {"PYTHONPATH": str(tmp_path)}
    for _ in range(3):      # refused, and the process exits cleanly every time
        proc = _run_host(host, unzipped / "SimulatedFog", lib, env, "SimulatedFog")
        assert proc.returncode == 100, (proc.returncode, proc.stderr[-2000:])   # the host's "NULL" exit
        assert "fmi2Instantiate returned NULL" in proc.stderr
        assert "SimulatedFog: needs numpy in the host's Python environment" in proc.stderr, proc.stderr
    # FogDenoiser needs no numpy: it runs, with the library's numbers
    proc = _run_host(host, unzipped / "FogDenoiser", lib, env, "FogDenoiser")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert [float(v) for v in proc.stdout.split()] == list(gd.denoise([0.5, 0.25], FS))


@pytest.mark.slow
def test_host_python_3_10(unzipped, host):
    lib, prefix = _libpython("python3.10")
    if lib is None:
        pytest.skip("no Python 3.10 with a shared libpython on this machine")
    for _ in range(3):
        proc = _run_host(host, unzipped / "SimulatedFog", lib, {"PYTHONHOME": prefix}, "SimulatedFog")
        assert proc.returncode == 100, (proc.returncode, proc.stderr[-2000:])
        assert "SimulatedFog: needs Python >= 3.11 with numpy in the host's environment" in proc.stderr, \
            proc.stderr
