"""FogDenoiserNative.fmu: the denoiser as a native FMI 2.0 co-simulation FMU (issue 14).

No Python and no libpython at run time: the binary is the project's C core
(``gyrodenoise/core/gdcore.c``), the FMI layer shared by the native FMUs
(``gyrodenoise/fmu/sources/native/gdfmi.c``) and the denoiser's hooks
(``gyrodenoise/fmu/sources/native/fogdenoiser_native.c``), compiled here and linked against libm
only. Same variables (names, types, causality, variability) and same outputs as
the pythonfmu ``FogDenoiser.fmu``. :class:`NativeModel` describes one native FMU;
:func:`build_native_fmu` builds any of them (SimulatedFogNative:
:mod:`gyrodenoise.fmu.simnative`), :func:`build_native_fmus` both.

:data:`VARIABLES` is the one table both files are generated from: the
``modelDescription.xml`` and the C header ``fogdenoiser_native_vars.h`` (value
references, start values, GUID, the variable table the C layer checks calls
against), so XML and binary cannot drift.

>>> from gyrodenoise.fmu.native import build_native_fmu
>>> build_native_fmu("build")            # doctest: +SKIP
PosixPath('build/FogDenoiserNative.fmu')
"""

from __future__ import annotations

import hashlib
import math
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

from gyrodenoise.errors import InputError
from gyrodenoise.fmu.model_description import BELOW_ONE, POSITIVE_MIN

MODEL_NAME = "FogDenoiserNative"
MAX_ORDER = 6                    # phi_1 .. phi_6 declared; phi_k for k > ar_order reads 0
STEP_SIZE = 0.005                # DefaultExperiment stepSize, s (200 Hz)
PACKAGE_DIR = Path(__file__).resolve().parents[1]
NATIVE_SRC = Path(__file__).resolve().parent / "sources" / "native"
CORE_DIR = PACKAGE_DIR / "core"
C_SOURCE = "fogdenoiser_native.c"
UNITY_SOURCE = "fogdenoiser_native_all.c"   # includes C_SOURCE and gdcore.c: the one file compiled
VARS_HEADER = "fogdenoiser_native_vars.h"

DEG = math.pi / 180.0
#: FMI unit name -> BaseUnit attributes (SI: rad, s)
UNITS = {
    "deg/s": {"rad": "1", "s": "-1", "factor": repr(DEG)},
    "deg2/s2": {"rad": "2", "s": "-2", "factor": repr(DEG * DEG)},
    "s": {"s": "1"},
    "Hz": {"s": "-1"},
}

METHOD_DOC = ("Filter, one of: 'motion' (default: follows manoeuvres, averages at rest), 'shakf' "
              "(modified Sage-Husa AKF, the paper), 'kf' (conventional KF), 'sh_classic' (classic "
              "Sage-Husa), 'lowpass' (Butterworth, cutoff_hz and lowpass_order) or 'none' (output = "
              "input); case and surrounding blanks ignored; any other value is refused at "
              "fmi2ExitInitializationMode")


class NativeModel:
    """What makes one native FMU: its name, variables, C sources and resources.

    ``build_native_fmu`` compiles any of them with the same compilers and flags; the
    FMI layer (``gyrodenoise/fmu/sources/native/gdfmi.c``) is shared, the model file gives the hooks.
    """

    def __init__(self, name, description, variables, step_size, c_source, unity, core_files,
                 units, header_lines=(), resources=None):
        self.name = name
        self.description = description
        self.variables = variables
        self.step_size = step_size
        self.c_source = c_source
        self.unity = unity
        self.vars_header = c_source.replace(".c", "_vars.h")
        self.core_files = core_files
        self.units = units
        self.header_lines = header_lines  # lines, or a function () -> lines (read at build time)
        self.resources = resources        # None or a function () -> {path in resources/: bytes}

    def value_references(self):
        return {v["name"]: i for i, v in enumerate(self.variables)}


DENOISER_DESCRIPTION = ("Gyro denoiser (online improved AR(n) + KF / modified Sage-Husa AKF, Sun et "
                        "al. 2016, or the motion filter), native C: no Python needed. One communication "
                        "step = one sample.")


def _var(name, type_, causality, description, start=None, unit=None, min=None, max=None,
         variability=None):
    return dict(name=name, type=type_, causality=causality, description=description, start=start,
                unit=unit, min=min, max=max, variability=variability)


def _par(name, type_, start, description, unit=None, min=None, max=None):
    return _var(name, type_, "parameter", description, start=start, unit=unit, min=min, max=max,
                variability="fixed")


#: The variables, in value-reference order (valueReference = position).
VARIABLES = (
    [_var("raw_rate", "Real", "input", "Raw angular rate of the gyro", start=0.0, unit="deg/s"),
     _var("restart", "Boolean", "input", "True on the first sample after a gyro restart: the "
          "filter re-identifies the AR model from that sample on", start=False, variability="discrete"),
     _var("filtered_rate", "Real", "output", "Filtered angular rate; the raw sample during the "
          "warm-up after each restart", unit="deg/s")]
    + [_var(f"phi_{k}", "Real", "output", f"AR coefficient phi_{k} of the improved AR(n) model, "
            f"Eq. (4) (0 when {k} > ar_order, and for the methods motion and lowpass)") for k in range(1, MAX_ORDER + 1)]
    + [_var("c", "Real", "output", "Constant term c of the improved AR model, Eq. (4) (0 for the methods motion "
          "and lowpass)", unit="deg/s"),
       _var("R_hat", "Real", "output", "Estimated measurement-noise variance (motion: the sensor's white-noise "
          "estimate)", unit="deg2/s2"),
       _var("Q_hat", "Real", "output", "Estimated process-noise variance (motion: of the rate increment per "
          "sample)", unit="deg2/s2"),
       _var("innovation", "Real", "output", "Last innovation v_k = z_k - H X_pred", unit="deg/s"),
       _var("converged", "Boolean", "output", "True once the AR model has converged since the "
            "last restart (the output is filtered from then on)", variability="discrete"),
       _par("ar_order", "Integer", 3, f"Order n of the AR model, 1..{MAX_ORDER}", min=1, max=MAX_ORDER),
       _par("method", "String", "motion", METHOD_DOC),
       _par("sample_period", "Real", 0.005, "Sample period, > 0; every communication step must "
            "have this size", unit="s", min=POSITIVE_MIN),
       _par("lam", "Real", 1.0, "RLS forgetting factor, 0 < lam <= 1", min=POSITIVE_MIN, max=1.0),
       _par("b", "Real", 0.99, "Sage-Husa forgetting factor, 0 < b < 1", min=POSITIVE_MIN, max=BELOW_ONE),
       _par("gamma", "Real", 3.0, "Convergence-criterion strictness, Eq. (32), gamma >= 1", min=1.0),
       _par("q0", "Real", 0.0, "Process-noise variance, 0 = automatic", unit="deg2/s2", min=0.0),
       _par("r0", "Real", 0.0, "Measurement-noise variance, 0 = automatic", unit="deg2/s2", min=0.0),
       _par("p0_rls", "Real", 1.0e4, "Initial RLS covariance (diagonal), > 0", min=POSITIVE_MIN),
       _par("p0_kf", "Real", 1.0, "Initial filter covariance (diagonal), > 0", unit="deg2/s2", min=POSITIVE_MIN),
       _par("warmup_s", "Real", 1.0, "Warm-up after each restart (raw passed through), >= 0; at "
            "least 10 (ar_order + 1) samples", unit="s", min=0.0),
       _par("r_floor", "Real", 1.0e-18, "Lower bound of R and of the automatic noise levels, > 0",
            unit="deg2/s2", min=POSITIVE_MIN),
       _par("outlier_sigma", "Real", 5.0, "Outlier gate: a sample with |innovation| > "
            "outlier_sigma sqrt(S) is kept out of the filter; 0 = off (the paper's filter), else >= 2",
            min=0.0),
       _par("outlier_run", "Integer", 20, "Consecutive rejected samples after which the filter "
            "re-opens (restarts) on a real rate change, >= 1", min=1),
       _par("cutoff_hz", "Real", 0.0, "method 'lowpass': -3 dB cutoff, below half the sample "
            "rate; 0 = 20 Hz, at most a quarter of the sample rate; checked (finite, >= 0) whatever the "
            "method", unit="Hz", min=0.0),
       _par("lowpass_order", "Integer", 2, "method 'lowpass': Butterworth order, 1..8", min=1, max=8),
       _var("n_rejected", "Integer", "output", "Samples kept out of the filter by the outlier gate "
            "since initialisation", variability="discrete"),
       _par("strict_step_size", "Boolean", False, "If true, a step whose size differs from "
            "sample_period is refused (fmi2Discard); if false it is processed and a warning is logged"),
       _par("max_motion_hz", "Real", 0.0, "method 'motion', rigid-body option: the band of interest; "
            "content above it counts as error (a 4th-order Butterworth before the bank, flat to it, -3 dB "
            "at twice it, at most 0.45 / sample_period); 0 = off, else below half the sample rate; checked (finite, >= 0, below half the "
            "sample rate) whatever the method", unit="Hz", min=0.0)])

LOG_CATEGORIES = [
    ("logStatusWarning", "Messages with status fmi2Warning (needs logging on)."),
    ("logStatusDiscard", "Messages with status fmi2Discard (needs logging on)."),
    ("logStatusError", "Messages with status fmi2Error (always passed to the logger)."),
    ("logStatusFatal", "Messages with status fmi2Fatal (always passed to the logger)."),
    ("logAll", "All messages, information included (needs logging on)."),
]


#: FogDenoiserNative: the denoiser's hooks (fogdenoiser_native.c) over the core gdcore.c
DENOISER = NativeModel(MODEL_NAME, DENOISER_DESCRIPTION, VARIABLES, STEP_SIZE, C_SOURCE, UNITY_SOURCE,
                       (CORE_DIR / "gdcore.c", CORE_DIR / "gdcore.h"), UNITS,
                       header_lines=(f"#define GD_MAX_AR_ORDER {MAX_ORDER}",))


def value_references():
    """{variable name: value reference} of FogDenoiserNative."""
    return DENOISER.value_references()


def _fmt(value, type_):
    if type_ == "Real":
        return repr(float(value))
    if type_ == "Boolean":
        return "true" if value else "false"
    return str(value)


def model_description(guid, spec=None):
    """modelDescription.xml (text) for ``guid`` (of FogDenoiserNative unless ``spec`` is given)."""
    spec = DENOISER if spec is None else spec
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<fmiModelDescription fmiVersion="2.0" modelName="{spec.name}" guid="{guid}" '
           f'description={quoteattr(spec.description)} author="gyrodenoise" version="0.1.0" license="MIT" '
           'generationTool="gyrodenoise.fmu.native" variableNamingConvention="flat" '
           'numberOfEventIndicators="0">',
           f'  <CoSimulation modelIdentifier="{spec.name}" needsExecutionTool="false" '
           'canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" '
           'maxOutputDerivativeOrder="0" canRunAsynchronuously="false" '
           'canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="false" '
           'canGetAndSetFMUstate="true" canSerializeFMUstate="true" '
           'providesDirectionalDerivative="false">',
           '    <SourceFiles>',
           f'      <File name="{spec.unity}"/>',
           '    </SourceFiles>',
           '  </CoSimulation>',
           '  <UnitDefinitions>']
    for unit, base in spec.units.items():
        attrs = " ".join(f'{k}="{v}"' for k, v in base.items())
        out += [f'    <Unit name="{unit}">', f'      <BaseUnit {attrs}/>', '    </Unit>']
    out += ['  </UnitDefinitions>', '  <LogCategories>']
    out += [f'    <Category name="{n}" description={quoteattr(d)}/>' for n, d in LOG_CATEGORIES]
    out += ['  </LogCategories>',
            f'  <DefaultExperiment startTime="0.0" stepSize="{spec.step_size!r}"/>',
            '  <ModelVariables>']
    for vr, v in enumerate(spec.variables):
        attrs = [f'name="{v["name"]}"', f'valueReference="{vr}"',
                 f'description={quoteattr(v["description"])}', f'causality="{v["causality"]}"']
        if v["variability"]:
            attrs.append(f'variability="{v["variability"]}"')
        if v["causality"] == "output":
            attrs.append(f'initial="{v.get("initial") or "calculated"}"')
        tattrs = []
        if v["start"] is not None:
            tattrs.append(f'start={quoteattr(_fmt(v["start"], v["type"]))}')
        if v["unit"]:
            tattrs.append(f'unit="{v["unit"]}"')
        for key in ("min", "max"):
            if v[key] is not None:
                tattrs.append(f'{key}="{_fmt(v[key], v["type"])}"')
        out += [f'    <ScalarVariable {" ".join(attrs)}>',
                f'      <{v["type"]}{" " if tattrs else ""}{" ".join(tattrs)}/>',
                '    </ScalarVariable>']
    outputs = [vr + 1 for vr, v in enumerate(spec.variables) if v["causality"] == "output"]
    calculated = [vr + 1 for vr, v in enumerate(spec.variables)
                  if v["causality"] == "output" and (v.get("initial") or "calculated") != "exact"]
    out += ['  </ModelVariables>', '  <ModelStructure>', '    <Outputs>']
    out += [f'      <Unknown index="{i}"/>' for i in outputs]
    out += ['    </Outputs>']
    if calculated:
        out += ['    <InitialUnknowns>']
        out += [f'      <Unknown index="{i}"/>' for i in calculated]
        out += ['    </InitialUnknowns>']
    out += ['  </ModelStructure>', '</fmiModelDescription>', '']
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
        lines.append(f"#define VR_{v['name']} {vr}u")
        if v["start"] is not None:
            lines.append(f"#define START_{v['name']} {_c_literal(v['start'], v['type'])}")
    rows = ", ".join(f'{{"{v["name"]}", T_{v["type"].upper()}, {kinds[v["causality"]]}}}'
                     for v in spec.variables)
    lines += [f"#define GD_VARIABLE_TABLE {{{rows}}}", "#endif", ""]
    return "\n".join(lines)


#: the shared FMI layer, in every native FMU
LAYER_FILES = ("gdfmi.c", "gdfmi.h", "gdfmi_libm.h")


def _sources(spec=None):
    """{file name: bytes} of the C sources that go into the binary and the FMU."""
    spec = DENOISER if spec is None else spec
    files = {name: NATIVE_SRC / name for name in (spec.c_source, spec.unity, *LAYER_FILES)}
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
DARWIN_MIN = "10.13"
PLATFORMS = {
    "linux64": (".so", "x86_64-linux-gnu.2.17", ()),
    "win64": (".dll", "x86_64-windows-gnu", ("x86_64-w64-mingw32-gcc",)),
    "darwin64": (".dylib", f"x86_64-macos.{DARWIN_MIN}", ()),
}
COMMON_FLAGS = ["-O2", "-ffp-contract=off", "-std=c99", "-shared", "-fvisibility=hidden", "-Wall",
                "-g0", "-DGD_LIBM_LINKED"]
PLATFORM_FLAGS = {
    "linux64": ["-fPIC", "-Wl,-z,defs", "-s"],
    "win64": ["-s"],
    "darwin64": ["-Wl,-undefined,error"],
}
GCC_ONLY_FLAGS = ["-fschedule-insns", "-fsched-pressure"]   # as setup.py (clang ignores them)


def host_platform():
    """The FMI 2.0 platform folder of this machine, or None if it is not one we build for."""
    bits64 = sys.maxsize > 2 ** 32
    machine = platform.machine().lower()
    if not bits64 or machine not in ("x86_64", "amd64"):
        return None
    if sys.platform.startswith("linux"):
        return "linux64"
    if sys.platform == "win32":
        return "win64"
    if sys.platform == "darwin":
        return "darwin64"
    return None


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
    win64: mingw-w64 gcc if installed, else zig. darwin64: zig.
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
    if plat == "linux64" and host_platform() == "linux64" and shutil.which("gcc"):
        return [shutil.which("gcc")], "gcc (no zig: the binary needs this machine's glibc, not 2.17)"
    hint = {"win64": "pip install ziglang, or apt-get install mingw-w64",
            "darwin64": "pip install ziglang"}.get(plat, "pip install ziglang, or install gcc")
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
    sources = _sources(spec)
    resources = spec.resources() if spec.resources else {}
    digest = hashlib.sha256()
    for name in sorted(sources):
        digest.update(name.encode() + b"\0" + sources[name])
    for name in sorted(resources):
        digest.update(b"resources/" + name.encode() + b"\0" + resources[name])
    digest.update(model_description("", spec).encode())
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "gyrodenoise:" + spec.name + ":"
                                + digest.hexdigest())) + "}"
    sources[spec.vars_header] = vars_header(guid, spec).encode()
    xml = model_description(guid, spec)
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
            binaries[plat] = binary
            report[plat] = what
        part = target.with_name(target.name + ".part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", xml)
            for plat, binary in binaries.items():
                z.write(binary, f"binaries/{plat}/{binary.name}")
            for name in sorted(sources):
                z.writestr(f"sources/{name}", sources[name])
            for name in sorted(resources):
                z.writestr(f"resources/{name}", resources[name])
        os.replace(part, target)
    return target


def native_stale_reason(fmu_path, spec=None):
    """Why the native FMU at ``fmu_path`` no longer matches the source tree (its sources/ and
    resources/ against the current files), or None."""
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
                return f"{arc} differs from the source tree"
    return None


def build_native_fmus(out_dir="build", platforms=None, report=None):
    """Build every native FMU (:data:`NATIVE_MODELS`) into ``out_dir``; returns {name: path}.
    ``platforms`` and ``report`` as for :func:`build_native_fmu` (the same compilers serve all)."""
    from gyrodenoise.fmu.simnative import SIMULATED_FOG_NATIVE
    return {spec.name: build_native_fmu(out_dir, platforms, report, spec)
            for spec in (DENOISER, SIMULATED_FOG_NATIVE)}


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
