"""FogDenoiserNative.fmu, and the build of any native FMU.

A native FMU is an FMI 2.0 co-simulation FMU with no Python and no libpython at run time.
FogDenoiserNative's binary is the project's C core (``gyrodenoise/core/gdcore.c``), the FMI
layer shared by the native FMUs (``gyrodenoise/fmu/sources/native/gdfmi.c``) and the
denoiser's hooks (``gyrodenoise/fmu/sources/native/fogdenoiser_native.c``), compiled here
and linked against libm only. Same variables (names, types, causality, variability, units)
and same outputs as the pythonfmu ``FogDenoiser.fmu``: both are built from
:data:`gyrodenoise.fmu.variables.FOG_DENOISER`.

:func:`build_native_fmu` builds any :class:`~gyrodenoise.fmu.nativemodel.NativeModel`
(SimulatedFogNative: :mod:`gyrodenoise.fmu.simnative`), :func:`build_native_fmus` both.
The ``modelDescription.xml`` and the C header ``<model>_vars.h`` (value references, start
values, GUID, the variable table the C layer checks calls against) are generated from the
model's variables, so XML and binary cannot drift.

>>> from gyrodenoise.fmu.native import build_native_fmu
>>> build_native_fmu("build")            # doctest: +SKIP
PosixPath('build/FogDenoiserNative.fmu')
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

from gyrodenoise._version import __version__
from gyrodenoise.errors import InputError
from gyrodenoise.fmu.nativemodel import CORE_DIR, LAYER_FILES, NATIVE_SRC, NativeModel
from gyrodenoise.fmu.simnative import SIMULATED_FOG_NATIVE
from gyrodenoise.fmu.variables import (DEFAULT_STEP_SIZE_S, FOG_DENOISER, FOG_DENOISER_IMU_XYZ, MAX_AR_ORDER, UNITS,
                                       format_value, initial)

MODEL_NAME = "FogDenoiserNative"
C_SOURCE = "fogdenoiser_native.c"
UNITY_SOURCE = "fogdenoiser_native_all.c"   # includes C_SOURCE and gdcore.c: the one file compiled

DENOISER_DESCRIPTION = ("Gyro denoiser (online improved AR(n) + KF / modified Sage-Husa AKF, Sun et "
                        "al. 2016, or the motion filter), native C: no Python needed. One communication "
                        "step = one sample.")

LOG_CATEGORIES = [
    ("logStatusWarning", "Messages with status fmi2Warning (needs logging on)."),
    ("logStatusDiscard", "Messages with status fmi2Discard (needs logging on)."),
    ("logStatusError", "Messages with status fmi2Error (always passed to the logger)."),
    ("logStatusFatal", "Messages with status fmi2Fatal (always passed to the logger)."),
    ("logAll", "All messages, information included (needs logging on)."),
]


#: FogDenoiserNative: the denoiser's hooks (fogdenoiser_native.c) over the core gdcore.c
DENOISER = NativeModel(MODEL_NAME, DENOISER_DESCRIPTION, FOG_DENOISER, DEFAULT_STEP_SIZE_S, C_SOURCE,
                       UNITY_SOURCE, (CORE_DIR / "gdcore.c", CORE_DIR / "gdcore.h", CORE_DIR / "gdmethods.h",
                                                       CORE_DIR / "gdbias.c", CORE_DIR / "gdbias.h"), UNITS,
                       header_lines=(f"#define GD_MAX_AR_ORDER {MAX_AR_ORDER}",),
                       extra_sources=("fogdenoiser_params.c",))
#: FogDenoiserImuNative: the 3-axis denoiser (FogDenoiserImuNative3's hooks) with one scalar variable an
#: axis, FMI 2.0, for hosts without FMI 3.0 arrays
IMU_XYZ = DENOISER.replace(
    name="FogDenoiserImuNative", variables=FOG_DENOISER_IMU_XYZ, c_source="fogdenoiser_imu_xyz_native.c",
    unity="fogdenoiser_imu_xyz_native_all.c", extra_sources=DENOISER.extra_sources + ("fogdenoiser_imu_native.c",),
    description="Gyro denoiser for a whole IMU (three gyro axes x, y, z, three independent filters: "
                "filtered_rate_x = gd.denoise of raw_rate_x, ...), one scalar variable an axis, native C: no "
                "Python needed. One communication step = one sample.")
#: every FMI 2.0 native FMU
NATIVE_MODELS = (DENOISER, SIMULATED_FOG_NATIVE, IMU_XYZ)


def value_references():
    """{variable name: value reference} of FogDenoiserNative."""
    return DENOISER.value_references()


def _model_header(spec, guid):
    return ['<?xml version="1.0" encoding="UTF-8"?>',
            f'<fmiModelDescription fmiVersion="2.0" modelName="{spec.name}" guid="{guid}" '
            f'description={quoteattr(spec.description)} author="gyrodenoise" version="{__version__}" license="MIT" '
            'generationTool="gyrodenoise.fmu.native" variableNamingConvention="flat" '
            'numberOfEventIndicators="0">',
            f'  <CoSimulation modelIdentifier="{spec.name}" needsExecutionTool="false" '
            'canHandleVariableCommunicationStepSize="false" canInterpolateInputs="false" '
            'maxOutputDerivativeOrder="0" canRunAsynchronuously="false" '
            'canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="false" '
            'canGetAndSetFMUstate="true" canSerializeFMUstate="true" '
            'providesDirectionalDerivative="false">',
            '    <SourceFiles>',
            f'      <File name="{spec.unity}"/>',
            '    </SourceFiles>',
            '  </CoSimulation>']


def _scalar_variable(vr, v):
    attrs = [f'name="{v.name}"', f'valueReference="{vr}"', f'description={quoteattr(v.description)}',
             f'causality="{v.causality}"']
    if v.variability:
        attrs.append(f'variability="{v.variability}"')
    if v.causality == "output":
        attrs.append(f'initial="{initial(v, pythonfmu=False)}"')
    tattrs = []
    if v.start is not None:
        tattrs.append(f'start={quoteattr(format_value(v.start, v.type))}')
    if v.unit:
        tattrs.append(f'unit="{v.unit}"')
    for key in ("min", "max"):
        if getattr(v, key) is not None:
            tattrs.append(f'{key}="{format_value(getattr(v, key), v.type)}"')
    return [f'    <ScalarVariable {" ".join(attrs)}>',
            f'      <{v.type}{" " if tattrs else ""}{" ".join(tattrs)}/>',
            '    </ScalarVariable>']


def _model_structure(spec):
    outputs = [vr + 1 for vr, v in enumerate(spec.variables) if v.causality == "output"]
    calculated = [vr + 1 for vr, v in enumerate(spec.variables) if initial(v, pythonfmu=False) == "calculated"]
    out = ['  <ModelStructure>', '    <Outputs>']
    out += [f'      <Unknown index="{i}"/>' for i in outputs]
    out += ['    </Outputs>']
    if calculated:
        out += ['    <InitialUnknowns>']
        out += [f'      <Unknown index="{i}"/>' for i in calculated]
        out += ['    </InitialUnknowns>']
    return out + ['  </ModelStructure>']


def model_description(guid, spec=None):
    """modelDescription.xml (text) for ``guid`` (of FogDenoiserNative unless ``spec`` is given)."""
    spec = DENOISER if spec is None else spec
    out = _model_header(spec, guid) + ['  <UnitDefinitions>']
    for unit, base in spec.units.items():
        attrs = " ".join(f'{k}="{v}"' for k, v in base.items())
        out += [f'    <Unit name="{unit}">', f'      <BaseUnit {attrs}/>', '    </Unit>']
    out += ['  </UnitDefinitions>', '  <LogCategories>']
    out += [f'    <Category name="{n}" description={quoteattr(d)}/>' for n, d in LOG_CATEGORIES]
    out += ['  </LogCategories>',
            f'  <DefaultExperiment startTime="0.0" stepSize="{spec.step_size!r}"/>',
            '  <ModelVariables>']
    for vr, v in enumerate(spec.variables):
        out += _scalar_variable(vr, v)
    out += ['  </ModelVariables>', *_model_structure(spec), '</fmiModelDescription>', '']
    return "\n".join(out)


def _c_literal(value, type_):
    if type_ == "Real":
        return repr(float(value))
    if type_ == "Boolean":
        return "1" if value else "0"
    if type_ == "String":
        return '"' + str(value).replace("\\", "\\\\").replace('"', '\\"') + '"'
    return str(int(value))


def vars_header(guid, spec=None):
    """The C header with the GUID, value references, start values and the variable table."""
    spec = DENOISER if spec is None else spec
    guard = spec.vars_header.upper().replace(".", "_")
    lines = ["/* generated by gyrodenoise/fmu/native.py from the variable table: do not edit */",
             f"#ifndef {guard}", f"#define {guard}",
             f'#define GD_MODEL_IDENTIFIER "{spec.name}"', f'#define GD_GUID "{guid}"',
             *(spec.header_lines() if callable(spec.header_lines) else spec.header_lines),
             f"#define GD_N_VARS {len(spec.variables)}"]
    kinds = {"input": "K_INPUT", "output": "K_OUTPUT", "parameter": "K_PARAMETER"}
    for vr, v in enumerate(spec.variables):
        lines.append(f"#define VR_{v.name} {vr}u")
        if v.start is not None:
            lines.append(f"#define START_{v.name} {_c_literal(v.start, v.type)}")
    rows = ", ".join(f'{{"{v.name}", T_{v.type.upper()}, {kinds[v.causality]}, {v.size}}}' for v in spec.variables)
    lines += [f"#define GD_VARIABLE_TABLE {{{rows}}}", "#endif", ""]
    return "\n".join(lines)


def _sources(spec=None):
    """{file name: bytes} of the C sources that go into the binary and the FMU."""
    spec = DENOISER if spec is None else spec
    files = {name: NATIVE_SRC / name for name in (spec.c_source, spec.unity, *LAYER_FILES, *spec.extra_sources)}
    files.update({p.name: p for p in spec.core_files})
    missing = [str(p) for p in files.values() if not p.is_file()]
    if missing:
        raise InputError(f"native FMU sources missing: {', '.join(missing)}")
    return {name: path.read_bytes() for name, path in files.items()}


def fmi_headers_dir():
    """Directory of the FMI 2.0 C headers (shipped with fmpy)."""
    try:
        import fmpy
    except ImportError as exc:  # pragma: no cover - fmpy is a dependency
        raise InputError(f"fmpy is needed for the FMI 2.0 C headers: {exc}") from None
    d = Path(fmpy.__file__).resolve().parent / "c-code"
    if not (d / "fmi2Functions.h").is_file():
        raise InputError(f"FMI 2.0 headers not found in {d}")
    return d


# ------------------------------------------------------------ platforms
#: FMI 2.0 platform folder -> (binary extension, zig target, other cross compilers tried first)
#: linux64 targets glibc 2.17 (RHEL/CentOS 7, Ubuntu 14.04 and later); darwin64 is x86_64
#: macOS (runs on Apple silicon under Rosetta 2), minimum version DARWIN_MIN.
#: FMI 2.0 names x86 platforms only ("64" stands for 64-bit x86); for any other platform FMI
#: 2.0.4 (section 2.3) says the FMI 3.0 platform tuples should be used: aarch64-linux (glibc
#: 2.17, as linux64: Raspberry Pi OS 64-bit, Jetson) and aarch64-darwin (Apple silicon, from
#: macOS DARWIN_AARCH64_MIN, the first arm64 macOS).
DARWIN_MIN = "10.13"
DARWIN_AARCH64_MIN = "11.0"
PLATFORMS = {
    "linux64": (".so", "x86_64-linux-gnu.2.17", ()),
    "win64": (".dll", "x86_64-windows-gnu", ("x86_64-w64-mingw32-gcc",)),
    "darwin64": (".dylib", f"x86_64-macos.{DARWIN_MIN}", ()),
    "aarch64-linux": (".so", "aarch64-linux-gnu.2.17", ()),
    "aarch64-darwin": (".dylib", f"aarch64-macos.{DARWIN_AARCH64_MIN}", ()),
}
#: -ffp-contract=off on every target: no a*b+c fused into one fma (clang and zig contract by
#: default on aarch64, where fma is an instruction), so every platform does the same IEEE
#: operations as the x86_64 build and the Python extension
COMMON_FLAGS = ["-O2", "-ffp-contract=off", "-std=c99", "-shared", "-fvisibility=hidden", "-Wall",
                "-g0", "-DGD_LIBM_LINKED"]
PLATFORM_FLAGS = {
    "linux64": ["-fPIC", "-Wl,-z,defs", "-s"],
    "win64": ["-s"],
    "darwin64": ["-Wl,-undefined,error"],
    "aarch64-linux": ["-fPIC", "-Wl,-z,defs", "-s"],
    "aarch64-darwin": ["-Wl,-undefined,error"],
}
GCC_ONLY_FLAGS = ["-fschedule-insns", "-fsched-pressure"]   # as setup.py (clang ignores them)


def host_platform():
    """The FMI 2.0 platform folder of this machine (a key of :data:`PLATFORMS`), or None if it
    is not one we build for."""
    if sys.maxsize <= 2 ** 32:
        return None
    machine = platform.machine().lower()
    arch = {"x86_64": "x86_64", "amd64": "x86_64", "aarch64": "aarch64", "arm64": "aarch64"}.get(machine)
    system = ("linux" if sys.platform.startswith("linux") else "windows" if sys.platform == "win32"
              else "darwin" if sys.platform == "darwin" else None)
    return _FOLDERS.get((arch, system))


#: (architecture, system) -> FMI 2.0 platform folder
_FOLDERS = {("x86_64", "linux"): "linux64", ("x86_64", "windows"): "win64", ("x86_64", "darwin"): "darwin64",
            ("aarch64", "linux"): "aarch64-linux", ("aarch64", "darwin"): "aarch64-darwin"}


def zig_command():
    """The command prefix that runs ``zig`` (the ``ziglang`` PyPI package, or zig on PATH), or None."""
    import importlib.util
    if importlib.util.find_spec("ziglang") is not None:
        return [sys.executable, "-m", "ziglang"]
    z = shutil.which("zig")
    return [z] if z else None


def compiler_for(plat):
    """(command prefix, description) of the C compiler used for ``plat``; InputError if none.

    linux64: zig's ``cc`` for glibc 2.17 (the ``ziglang`` package: ``pip install ziglang``);
    without it, when building on Linux, the system gcc, whose binary then needs the build
    machine's glibc. ``GYRODENOISE_CC`` names the compiler for this machine's platform.
    win64: mingw-w64 gcc if installed, else zig. darwin64, aarch64-linux, aarch64-darwin: zig.
    """
    if plat not in PLATFORMS:
        raise InputError(f"unknown FMU platform {plat!r}; known: {', '.join(PLATFORMS)}")
    _ext, target, others = PLATFORMS[plat]
    cc_env = os.environ.get("GYRODENOISE_CC")
    if plat == host_platform() and cc_env:
        exe = shutil.which(cc_env)
        if exe is None:
            raise InputError(f"GYRODENOISE_CC={cc_env}: not found on PATH (the native FMUs are "
                             "compiled at build time)")
        return [exe], f"{cc_env} (GYRODENOISE_CC)"
    for name in others:
        exe = shutil.which(name)
        if exe:
            return [exe], name
    zig = zig_command()
    if zig is not None:
        return zig + ["cc", "-target", target], f"zig cc -target {target}"
    if plat in ("linux64", "aarch64-linux") and host_platform() == plat and shutil.which("gcc"):
        return [shutil.which("gcc")], "gcc (no zig: the binary needs this machine's glibc, not 2.17)"
    hint = {"win64": "pip install ziglang, or apt-get install mingw-w64"}.get(
        plat, "pip install ziglang" if plat != host_platform() else "pip install ziglang, or install gcc")
    raise InputError(f"no C compiler for {plat}: {hint} (the native FMUs are compiled at build time)")


def _compile(plat, cc, src_dir, out, spec=None):
    """Compile the unity source for ``plat`` into ``out``; InputError (one line) on failure."""
    spec = DENOISER if spec is None else spec
    is_gcc = "-target" not in cc and Path(cc[0]).name.endswith("gcc")
    flags = list(COMMON_FLAGS) + PLATFORM_FLAGS[plat]
    if is_gcc:
        flags += GCC_ONLY_FLAGS + (["-static-libgcc"] if plat == "win64" else [])
    cmd = [*cc, *flags, f"-I{src_dir}", f"-I{fmi_headers_dir()}", "-o", str(out),
           str(src_dir / spec.unity), "-lm"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=out.parent)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise InputError(f"{cc[0]} could not be run for {spec.name} ({plat}): {exc}") from None
    if proc.returncode != 0:
        first = next((ln for ln in proc.stderr.splitlines() if "error" in ln), proc.stderr.strip()[:200])
        raise InputError(f"compiling {spec.name} for {plat} failed (exit {proc.returncode}): {first}")


def _find_compilers(platforms, report):
    """{platform: (command prefix, description)} for ``platforms`` (None: every platform a
    compiler is found for, this machine's at least); skipped ones are noted in ``report``."""
    wanted = list(platforms) if platforms is not None else list(PLATFORMS)
    required = set(wanted) if platforms is not None else {host_platform()}
    if not wanted:
        raise InputError("no FMU platform requested")
    compilers = {}
    for plat in wanted:
        try:
            compilers[plat] = compiler_for(plat)
        except InputError as exc:
            if plat in required:
                raise
            report[plat] = f"skipped: {exc}"
    if not compilers:
        raise InputError("no C compiler found for any FMU platform (pip install ziglang)")
    return compilers


def _guid(spec, sources, resources):
    """The FMU's GUID: a hash of its sources, resources and variables (same inputs, same GUID)."""
    digest = hashlib.sha256()
    for name in sorted(sources):
        digest.update(name.encode() + b"\0" + sources[name])
    for name in sorted(resources):
        digest.update(b"resources/" + name.encode() + b"\0" + resources[name])
    digest.update(_description("", spec).encode())
    return "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "gyrodenoise:" + spec.name + ":" + digest.hexdigest())) + "}"


def _description(guid, spec):
    """modelDescription.xml of ``spec`` in its FMI version's form (an FMI 3.0 model brings its
    writer: :func:`gyrodenoise.fmu.native3.model_description3`)."""
    return spec.xml_writer(guid, spec) if spec.xml_writer else model_description(guid, spec)


def _binary_folder(plat, spec):
    """The folder under binaries/ of ``plat``'s binary: the FMI 2.0 platform name (a key of
    :data:`PLATFORMS`), or for an FMI 3.0 FMU its platform tuple (e.g. x86_64-linux: the model
    brings the mapping, :func:`gyrodenoise.fmu.native3.fmi3_platform_folder`)."""
    return spec.binary_folder(plat) if spec.binary_folder else plat


def _write_fmu(target, xml, binaries, sources, resources, documentation=None):
    """Zip the FMU into ``target`` (through a ``.part`` file, replaced at the end); ``binaries``:
    {folder under binaries/: path}, ``documentation``: {path in documentation/: bytes}."""
    part = target.with_name(target.name + ".part")
    with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", xml)
        for folder, binary in binaries.items():
            z.write(binary, f"binaries/{folder}/{binary.name}")
        for name in sorted(documentation or {}):
            z.writestr(f"documentation/{name}", documentation[name])
        for name in sorted(sources):
            z.writestr(f"sources/{name}", sources[name])
        for name in sorted(resources):
            z.writestr(f"resources/{name}", resources[name])
    os.replace(part, target)


def build_native_fmu(out_dir="build", platforms=None, report=None, spec=None):
    """Compile a native FMU (FogDenoiserNative unless ``spec`` says otherwise: see
    :data:`NATIVE_MODELS`) and write ``out_dir/<name>.fmu``; returns its path.

    ``platforms``: the FMI 2.0 platform folders to put binaries in (see :data:`PLATFORMS`); a
    missing compiler is then an error. None: every platform a compiler is found for, this
    machine's at least (the others are skipped, with the reason in ``report``). ``report`` (a
    dict), if given, receives {platform: compiler used, or "skipped: reason"}.

    Raises :class:`~gyrodenoise.errors.InputError` (one line) if a needed compiler is missing
    or a compilation fails.
    """
    spec = DENOISER if spec is None else spec
    report = {} if report is None else report
    compilers = _find_compilers(platforms, report)
    sources = _sources(spec)
    resources = spec.resources() if spec.resources else {}
    guid = _guid(spec, sources, resources)
    sources[spec.vars_header] = vars_header(guid, spec).encode()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{spec.name}.fmu"
    with tempfile.TemporaryDirectory(prefix="fognative_") as tmp:
        tmp = Path(tmp)
        src = tmp / "sources"
        src.mkdir()
        for name, data in sources.items():
            (src / name).write_bytes(data)
        binaries = {}
        for plat, (cc, what) in compilers.items():
            (tmp / plat).mkdir()
            binary = tmp / plat / f"{spec.name}{PLATFORMS[plat][0]}"
            _compile(plat, cc, src, binary, spec)
            binaries[_binary_folder(plat, spec)] = binary
            report[plat] = what
        from gyrodenoise.fmu.reference import reference_documents
        _write_fmu(target, _description(guid, spec), binaries, sources, resources, reference_documents(spec.name))
    return target


def native_stale_reason(fmu_path, spec=None):
    """Why the native FMU at ``fmu_path`` no longer matches the package's sources (its sources/
    and resources/ against the current files), or None."""
    spec = DENOISER if spec is None else spec
    if not Path(fmu_path).is_file():
        return "missing"
    wanted = {f"sources/{n}": data for n, data in _sources(spec).items()}
    if spec.resources:
        wanted.update({f"resources/{n}": data for n, data in spec.resources().items()})
    with zipfile.ZipFile(fmu_path) as z:
        names = set(z.namelist())
        for arc, data in wanted.items():
            if arc not in names or z.read(arc) != data:
                return f"{arc} differs from the package's sources"
    return None


def build_native_fmus(out_dir="build", platforms=None, report=None):
    """Build every FMI 2.0 native FMU (:data:`NATIVE_MODELS`) into ``out_dir``; returns {name: path}.
    ``platforms`` and ``report`` as for :func:`build_native_fmu` (the same compilers serve all).
    The FMI 3.0 ones too: :func:`gyrodenoise.fmu.native3.build_native_fmus`."""
    return {spec.name: build_native_fmu(out_dir, platforms, report, spec) for spec in NATIVE_MODELS}


def main(argv=None):  # pragma: no cover - convenience: python -m gyrodenoise.fmu.native [out_dir]
    args = sys.argv[1:] if argv is None else argv
    try:
        for path in build_native_fmus(args[0] if args else "build").values():
            print(path)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
