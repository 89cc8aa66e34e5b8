"""Build the binary wheels of gyrodenoise for every platform, here, with one command:

    python scripts/build_wheels.py [--out dist] [--targets linux_x86_64,...]

One wheel per platform serves every CPython >= 3.11: the C core is compiled against the stable
ABI (``_gdcoremodule.c`` defines ``Py_LIMITED_API`` 0x030B0000), tagged ``cp311-abi3``.

How: ``python -m build --sdist`` makes the source distribution, from which ``pip wheel`` builds
the package once (so the sdist is known to build) with the compiler hidden (``CC=false``: setup.py's
extension is optional, so the wheel holds the Python modules, the sources and the model cards,
no binary); then, for each target of :data:`TARGETS`, zig (the ``ziglang`` package, as for the
FMUs: gyrodenoise/fmu/native.py) cross-compiles ``gdcore.c gdbias.c gdsim.c _gdcoremodule.c`` into the
extension, which joins a copy of that wheel under the target's tags (WHEEL and RECORD
rewritten). Python's headers are this interpreter's (the limited API is the same on every
platform; its pyconfig.h fits the 64-bit little-endian POSIX targets); Windows gets a
pyconfig.h of its own (:data:`WIN64_PYCONFIG`) and an import library of ``python3.dll`` that
``zig dlltool`` makes from the symbols the extension imports (every one in the stable ABI,
which python3.dll exports).

Each binary is then inspected (:func:`inspect`, printed): its format and machine, the
libraries it needs, the highest glibc symbol version (Linux), the minimum OS (macOS), its
exports (only ``PyInit__gdcore``). Nothing is executed here; tests/test_install_wheels.py
installs the linux x86_64 wheel and runs it, and the aarch64 core under qemu.
"""
from __future__ import annotations

import argparse
import base64
import contextlib
import hashlib
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CORE = REPO / "gyrodenoise" / "core"
SOURCES = ("gdcore.c", "gdbias.c", "gdsim.c", "_gdcoremodule.c")
#: the flags of setup.py that hold the numbers (no fused multiply-add: the C core equals the
#: plain-Python kernels bit for bit); -fvisibility=hidden: only PyInit__gdcore is exported;
#: -fno-unroll-loops: zig's clang unrolls the per-call checks and restarts of step(), measured
#: (CPU time, linux x86_64, Denoiser.step shakf/kf/motion/lowpass) 185/184/249/100 ns/call with
#: unrolling, 156/152/234/90 without, gcc's setup.py build 164/157/204/89; batch unchanged
FLAGS = ["-O2", "-ffp-contract=off", "-fno-unroll-loops", "-std=c99", "-shared", "-fvisibility=hidden", "-g0",
         "-Wall"]
ABI_TAG = "cp311-abi3"
GLIBC_MAX = (2, 17)                # manylinux2014
MACOS_MIN = {"x86_64": "10.13", "aarch64": "11.0"}


#: Python's symbols are bound when the interpreter loads the extension; the install name is the
#: file's own (not this machine's build folder)
MACHO_FLAGS = ("-Wl,-undefined,dynamic_lookup", "-Wl,-install_name,_gdcore.abi3.so", "-s")


@dataclass(frozen=True)
class Target:
    """One platform a wheel is built for."""
    name: str                      # --targets
    zig: str                       # zig cc -target
    platform_tags: tuple[str, ...]  # the wheel's platform tags (compressed into its name)
    binary: str                    # the extension's file name in gyrodenoise/core
    flags: tuple[str, ...]
    kind: str                      # "elf", "macho", "pe": how inspect() reads it


TARGETS = {t.name: t for t in (
    Target("linux_x86_64", "x86_64-linux-gnu.2.17",
           ("manylinux_2_17_x86_64", "manylinux2014_x86_64"), "_gdcore.abi3.so", ("-fPIC", "-s", "-lm"), "elf"),
    Target("linux_aarch64", "aarch64-linux-gnu.2.17",
           ("manylinux_2_17_aarch64", "manylinux2014_aarch64"), "_gdcore.abi3.so", ("-fPIC", "-s", "-lm"), "elf"),
    Target("macos_x86_64", f"x86_64-macos.{MACOS_MIN['x86_64']}",
           ("macosx_10_13_x86_64",), "_gdcore.abi3.so", MACHO_FLAGS, "macho"),
    Target("macos_arm64", f"aarch64-macos.{MACOS_MIN['aarch64']}",
           ("macosx_11_0_arm64",), "_gdcore.abi3.so", MACHO_FLAGS, "macho"),
    Target("windows_x86_64", "x86_64-windows-gnu", ("win_amd64",), "_gdcore.pyd", ("-s",), "pe"),
)}

#: pyconfig.h for the win64 extension (what Python.h asks of the platform under the limited
#: API: an LLP64 Windows, Python in a DLL whose symbols are imported)
WIN64_PYCONFIG = """\
/* pyconfig.h for gyrodenoise's stable-ABI extension built for win64 (zig cc, mingw-w64):
   written by scripts/build_wheels.py */
#ifndef Py_CONFIG_H
#define Py_CONFIG_H
#define MS_WIN32
#define MS_WIN64
#define MS_WINDOWS
#define NT_THREADS
#define WITH_THREAD
#define Py_ENABLE_SHARED 1
#define HAVE_DECLSPEC_DLL
#define Py_WINVER 0x0A00
#define SIZEOF_SHORT 2
#define SIZEOF_INT 4
#define SIZEOF_LONG 4
#define SIZEOF_LONG_LONG 8
#define SIZEOF_DOUBLE 8
#define SIZEOF_FLOAT 4
#define SIZEOF_VOID_P 8
#define SIZEOF_SIZE_T 8
#define SIZEOF_TIME_T 8
#define SIZEOF_WCHAR_T 2
#define SIZEOF_OFF_T 4
#define SIZEOF_FPOS_T 8
#define SIZEOF__BOOL 1
#define ALIGNOF_LONG 4
#define ALIGNOF_SIZE_T 8
#define HAVE_WCHAR_H 1
#define HAVE_STDDEF_H 1
#define DOUBLE_IS_LITTLE_ENDIAN_IEEE754 1
#define HAVE_PY_SSIZE_T 1
#include <basetsd.h>
typedef __int64 Py_ssize_t;
#endif
"""


def zig():
    """The command prefix that runs zig (the ziglang package, else zig on PATH)."""
    import importlib.util
    if importlib.util.find_spec("ziglang") is not None:
        return [sys.executable, "-m", "ziglang"]
    if shutil.which("zig"):
        return [shutil.which("zig")]
    raise SystemExit("build_wheels: zig is needed (pip install ziglang, or gyrodenoise[fmu])")


def _run(cmd, **kw):
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    if proc.returncode != 0:
        raise SystemExit(f"build_wheels: {' '.join(map(str, cmd[:6]))} ... failed (exit {proc.returncode}):\n"
                         f"{proc.stderr.strip()[-3000:]}")
    return proc.stdout


# ------------------------------------------------------------------ compiling
def compile_core(target: Target, work: Path) -> Path:
    """Cross-compile the C core for ``target`` into ``work``; the binary's path."""
    work.mkdir(parents=True, exist_ok=True)
    out = work / target.binary
    inc = ["-I", sysconfig.get_path("include"), "-I", str(CORE)]
    srcs = [str(CORE / s) for s in SOURCES]
    if target.kind != "pe":
        _run([*zig(), "cc", "-target", target.zig, *FLAGS, *inc, "-o", out, *srcs, *target.flags])
        return out
    # Windows: Python's headers with our pyconfig.h in their folder (Python.h includes it by
    # "pyconfig.h": its own folder first); objects, then python3.lib from what they import
    headers = work / "include"
    shutil.copytree(sysconfig.get_path("include"), headers, dirs_exist_ok=True)
    (headers / "pyconfig.h").write_text(WIN64_PYCONFIG)
    inc = ["-I", str(headers), "-I", str(CORE)]
    objs = []
    for s in srcs:
        obj = work / (Path(s).stem + ".obj")
        _run([*zig(), "cc", "-target", target.zig, *[f for f in FLAGS if f != "-shared"], *inc, "-c", "-o", obj, s])
        objs.append(obj)
    lib = python3_import_library(objs, work)
    _run([*zig(), "cc", "-target", target.zig, "-shared", "-s", "-o", out, *objs, lib])
    return out


def python3_import_library(objs, work: Path) -> Path:
    """An import library of python3.dll (the stable ABI's DLL) for the symbols ``objs`` import."""
    names = set()
    for obj in objs:
        for line in _run(["llvm-nm", "--undefined-only", obj]).splitlines():
            sym = line.split()[-1]
            if sym.startswith("__imp_"):
                names.add(sym[len("__imp_"):])
    data = re.compile(r"^(PyExc_\w+|_Py_\w+Struct|Py\w+_Type)$")
    lines = ["LIBRARY python3.dll", "EXPORTS"] + [f"    {n}{' DATA' if data.match(n) else ''}" for n in sorted(names)]
    (work / "python3.def").write_text("\n".join(lines) + "\n")
    lib = work / "python3.lib"
    _run([*zig(), "dlltool", "-m", "i386:x86-64", "-D", "python3.dll", "-d", work / "python3.def", "-l", lib])
    return lib


# ------------------------------------------------------------------ the wheels
def sdist(src: Path, out_dir: Path) -> Path:
    """The source distribution (python -m build --sdist: the C core, the FMU sources, the model
    cards, setup.py and pyproject.toml inside: the wheels are built from it)."""
    before = set(out_dir.glob("gyrodenoise-*.tar.gz"))
    with _one_sdist_at_a_time(src):
        _run([sys.executable, "-m", "build", "--sdist", "--outdir", out_dir, src])
    (new,) = set(out_dir.glob("gyrodenoise-*.tar.gz")) - before or sorted(before)[-1:]
    return new


@contextlib.contextmanager
def _one_sdist_at_a_time(src: Path):
    """Hold an exclusive lock on this source tree while its sdist is built: setuptools stages
    the sdist in ``src/gyrodenoise-<version>/`` and ``src/*.egg-info``, so two builds of one
    tree at once (two test workers) remove each other's files ("could not create ...")."""
    try:
        import fcntl
    except ImportError:          # not POSIX: no lock (one build at a time is up to the caller)
        yield
        return
    key = hashlib.sha256(str(Path(src).resolve()).encode()).hexdigest()[:16]
    with open(Path(tempfile.gettempdir()) / f"gyrodenoise-sdist-{key}.lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def base_wheel(source: Path, work: Path) -> Path:
    """The package's wheel built by pip from ``source`` (the sdist) with no compiler (CC=false):
    modules, sources, cards, no binary."""
    env = dict(os.environ, CC="false", CXX="false", LDSHARED="false", PIP_DISABLE_PIP_VERSION_CHECK="1")
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", work, source], env=env, cwd=work.parent)
    (whl,) = work.glob("gyrodenoise-*.whl")
    with zipfile.ZipFile(whl) as z:
        stray = [n for n in z.namelist() if re.search(r"\.(so|pyd|dylib|dll)$", n)]
    if stray:
        raise SystemExit(f"build_wheels: the base wheel holds a binary ({stray}): the compiler was not hidden")
    return whl


def _record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def platform_wheel(base: Path, target: Target, binary: Path, out_dir: Path) -> Path:
    """A copy of ``base`` with the binary in gyrodenoise/core and the target's tags."""
    with zipfile.ZipFile(base) as z:
        files = {n: z.read(n) for n in z.namelist()}
    dist_info = next(n.split("/")[0] for n in files if n.endswith(".dist-info/WHEEL"))
    dist, version = dist_info[:-len(".dist-info")].split("-")
    files = {n: d for n, d in files.items() if not n.startswith("gyrodenoise/core/_gdcore.")}
    files[f"gyrodenoise/core/{target.binary}"] = binary.read_bytes()
    wheel_meta = [ln for ln in files[f"{dist_info}/WHEEL"].decode().splitlines()
                  if not ln.startswith(("Tag:", "Root-Is-Purelib:"))]
    wheel_meta.append("Root-Is-Purelib: false")
    wheel_meta += [f"Tag: {ABI_TAG}-{p}" for p in target.platform_tags]
    files[f"{dist_info}/WHEEL"] = ("\n".join(wheel_meta) + "\n").encode()
    record = f"{dist_info}/RECORD"
    files.pop(record)
    lines = [_record_line(n, d) for n, d in files.items()] + [f"{record},,"]
    files[record] = ("\n".join(lines) + "\n").encode()
    path = out_dir / f"{dist}-{version}-{ABI_TAG}-{'.'.join(target.platform_tags)}.whl"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for n, d in files.items():
            info = zipfile.ZipInfo(n, date_time=(2020, 1, 1, 0, 0, 0))
            info.external_attr = (0o755 if n.endswith((".so", ".pyd")) else 0o644) << 16
            z.writestr(info, d, zipfile.ZIP_DEFLATED)
    return path


# ------------------------------------------------------------------ inspection
@dataclass
class Inspection:
    """What a binary is and links, read from its headers (nothing executed)."""
    format: str
    machine: str
    needed: list[str]
    exports: list[str]
    glibc_max: tuple[int, ...] | None = None    # the highest GLIBC_x.y symbol version it needs (ELF)
    min_os: str | None = None                   # macOS: LC_BUILD_VERSION minos / LC_VERSION_MIN_MACOSX

    def line(self):
        extra = (f"glibc <= {'.'.join(map(str, self.glibc_max))}" if self.glibc_max else
                 f"min macOS {self.min_os}" if self.min_os else "")
        return (f"{self.format} {self.machine}; needs {', '.join(self.needed) or '(nothing)'}"
                f"{'; ' + extra if extra else ''}; exports {', '.join(self.exports)}")


def inspect(path: Path, kind: str) -> Inspection:
    """Read the binary's headers with llvm-readobj / llvm-objdump / llvm-nm."""
    return {"elf": _inspect_elf, "macho": _inspect_macho, "pe": _inspect_pe}[kind](path)


def _inspect_elf(path):
    hdr = _run(["llvm-readobj", "--file-headers", "--needed-libs", "--dyn-syms", path])
    machine = re.search(r"Machine: (\S+)", hdr).group(1)
    needed = re.findall(r"^\s+(lib\S+)$", hdr.split("NeededLibraries")[1].split("}")[0], re.M)
    versions = {tuple(map(int, v.split("."))) for v in re.findall(r"@GLIBC_([0-9.]+)", hdr)}
    exports = _run(["llvm-nm", "-D", "--defined-only", path]).split()
    exports = [s for s in exports[2::3]]
    return Inspection("ELF", machine, needed, exports, max(versions) if versions else None)


def _inspect_macho(path):
    heads = _run(["llvm-objdump", "--macho", "--private-headers", path])
    commands = re.split(r"^\s+cmd ", heads, flags=re.M)[1:]       # one load command each
    cputype = re.search(r"CpuType: (\S+)", _run(["llvm-readobj", "--file-headers", path])).group(1)
    minos = None
    needed = []
    for c in commands:
        if c.startswith("LC_BUILD_VERSION"):
            minos = re.search(r"minos (\d+\.\d+)", c).group(1)
        elif c.startswith("LC_VERSION_MIN_MACOSX"):
            minos = re.search(r"version (\d+\.\d+)", c).group(1)
        elif c.startswith(("LC_LOAD_DYLIB", "LC_LOAD_WEAK_DYLIB", "LC_REEXPORT_DYLIB")):
            needed.append(re.search(r"name (\S+) \(offset", c).group(1))
    # the linker's own (in every dylib): the image header, the dso handle
    linker = {"___dso_handle", "__mh_dylib_header", "__mh_bundle_header"}
    exports = [s.split()[-1] for s in _run(["llvm-nm", "--defined-only", "--extern-only", path]).splitlines()
               if s.split()[-1] not in linker]
    return Inspection("Mach-O", cputype, needed, exports, min_os=minos)


def _inspect_pe(path):
    heads = _run(["llvm-objdump", "-p", path])
    machine = _run(["llvm-objdump", "-f", path])
    arch = re.search(r"architecture: (\S+)", machine).group(1)
    needed = re.findall(r"DLL Name: (\S+)", heads)
    exports_part = heads.split("Export Table:")[1] if "Export Table:" in heads else ""
    exports = re.findall(r"^\s+\d+\s+0x[0-9a-f]+\s+(\w+)$", exports_part, re.M)
    return Inspection("PE", arch, needed, exports)


def check(insp: Inspection, target: Target):
    """The problems of an inspected binary for ``target`` (empty: fine)."""
    problems = []
    if insp.exports != ["PyInit__gdcore"] and insp.exports != ["_PyInit__gdcore"]:
        problems.append(f"exports {insp.exports}, expected PyInit__gdcore only")
    if target.kind == "elf":
        stray = [n for n in insp.needed if not re.match(r"lib(c|m|pthread|dl)\.so\.\d$", n)]
        if stray:
            problems.append(f"needs {stray} beyond glibc")
        if insp.glibc_max and insp.glibc_max > GLIBC_MAX:
            problems.append(f"needs glibc {insp.glibc_max} > {GLIBC_MAX}")
    elif target.kind == "macho":
        arch = target.zig.split("-")[0]
        if insp.min_os != MACOS_MIN[arch]:
            problems.append(f"minimum macOS {insp.min_os}, expected {MACOS_MIN[arch]}")
        if [n for n in insp.needed if not n.startswith("/usr/lib/libSystem")]:
            problems.append(f"needs {insp.needed} beyond libSystem")
    elif target.kind == "pe":
        stray = [n for n in insp.needed if not (n.lower() == "python3.dll" or n.lower() == "kernel32.dll"
                                                or n.lower().startswith("api-ms-win-crt-")
                                                or n.lower() in ("msvcrt.dll", "ucrtbase.dll"))]
        if stray:
            problems.append(f"needs {stray} beyond python3.dll and the C runtime")
        if not any(n.lower() == "python3.dll" for n in insp.needed):
            problems.append("does not import python3.dll (the stable ABI's DLL)")
    return problems


def build(targets, out_dir: Path, src: Path = REPO):
    """Build the wheels of ``targets`` into ``out_dir``; [(target, wheel path, Inspection)]."""
    out_dir.mkdir(parents=True, exist_ok=True)
    results = []
    with tempfile.TemporaryDirectory(prefix="gd_wheels_") as tmp:
        tmp = Path(tmp)
        (tmp / "base").mkdir()
        base = base_wheel(sdist(src, out_dir), tmp / "base")
        for t in targets:
            binary = compile_core(t, tmp / t.name)
            insp = inspect(binary, t.kind)
            problems = check(insp, t)
            if problems:
                raise SystemExit(f"build_wheels: {t.name}: {'; '.join(problems)}")
            results.append((t, platform_wheel(base, t, binary, out_dir), insp))
    return results


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="dist", help="folder of the wheels (default: dist)")
    ap.add_argument("--targets", default=",".join(TARGETS), help=f"comma-separated, of {', '.join(TARGETS)}")
    args = ap.parse_args(argv)
    names = [n.strip() for n in args.targets.split(",") if n.strip()]
    bad = [n for n in names if n not in TARGETS]
    if bad or not names:
        ap.error(f"--targets: unknown {', '.join(bad) or '(none given)'}; known: {', '.join(TARGETS)}")
    out = Path(args.out)
    for t, whl, insp in build([TARGETS[n] for n in names], out):
        print(f"{whl.name}  {whl.stat().st_size / 1e6:.2f} MB\n    {insp.line()}")
    sd = max(out.glob("gyrodenoise-*.tar.gz"), key=lambda p: p.stat().st_mtime)
    print(f"{sd.name}  {sd.stat().st_size / 1e6:.2f} MB (the wheels were built from it)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
