"""FMUs of the project: build them, and the fmpy-scripted validation run.

``gyrodenoise fmu build`` packages ``fmu_src/fogdenoiser_fmu.py`` and
``fmu_src/simulatedfog_fmu.py`` with pythonfmu into ``FogDenoiser.fmu`` and
``SimulatedFog.fmu``. The FMUs carry a copy of the plain-Python part of the core
(package ``gdcore`` in their resources), so they run wherever Python and numpy
are, from any directory, without this package installed.

``gyrodenoise fmu run`` runs SimulatedFog -> FogDenoiser with fmpy's
``FMU2Slave`` (one communication step per sample) and checks the result against
the core's batch path. No maths here: the FMUs and this module only call the core.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from .errors import InputError
from .kernels import DEFAULT_METHOD

PACKAGE_DIR = Path(__file__).resolve().parent
REPO_DIR = PACKAGE_DIR.parent
FMU_SRC = REPO_DIR / "fmu_src"

#: (model name, slave script, core modules bundled)
FMUS = {
    "FogDenoiser": ("fogdenoiser_fmu.py", ("kernels.py", "denoiser.py", "errors.py")),
    "SimulatedFog": ("simulatedfog_fmu.py", ("errors.py", "simulator.py")),
}

CORE_INIT = '''"""Plain-Python part of the gyrodenoise core, bundled into an FMU.

Copied from gyrodenoise {version} by ``gyrodenoise fmu build``; the FMU's slave imports
it under a private name. Only the per-sample path is here (no numba, no scipy).
"""
__version__ = "{version}"
'''


def _fmu_src_dir(src_dir=None):
    d = Path(src_dir) if src_dir is not None else FMU_SRC
    if not d.is_dir():
        raise InputError(f"{d}: FMU sources not found (fmu_src/ of the gyrodenoise source tree)")
    return d


def stage_core(dest, modules):
    """Write the minimal core package ``gdcore`` into ``dest``; return its path."""
    from . import __version__
    pkg = Path(dest) / "gdcore"
    pkg.mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text(CORE_INIT.format(version=__version__))
    for name in modules:
        src = PACKAGE_DIR / name
        if not src.is_file():
            raise InputError(f"{src}: core module missing, cannot bundle it into the FMU")
        shutil.copy2(src, pkg / name)
    if "simulator.py" in modules:   # the embedded model cards (load_card by name)
        (pkg / "data").mkdir(exist_ok=True)
        for card in sorted((PACKAGE_DIR / "data").glob("*.toml")):
            shutil.copy2(card, pkg / "data" / card.name)
    return pkg


def build_fmu(name, out_dir="build", src_dir=None, python=None):
    """Build one FMU (``name`` in :data:`FMUS`) into ``out_dir``; return its path.

    pythonfmu runs in a subprocess so that it imports the staged copy of the
    slave script, never the source tree or a module cached in this process.
    """
    if name not in FMUS:
        raise InputError(f"unknown FMU {name!r}; known: {', '.join(FMUS)}")
    script, modules = FMUS[name]
    src = _fmu_src_dir(src_dir) / script
    if not src.is_file():
        raise InputError(f"{src}: slave script not found")
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"gd_fmu_{name}_") as tmp:
        stage = Path(tmp) / "stage"
        stage.mkdir()
        shutil.copy2(src, stage / script)
        pkg = stage_core(stage, modules)
        cmd = [python or sys.executable, "-m", "pythonfmu", "build",
               "-f", str(stage / script), "-d", str(out),
               "--handle-state", "--serialize-state", str(pkg)]
        env = dict(os.environ)
        env.pop("PYTHONPATH", None)
        proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"pythonfmu build of {name} failed ({proc.returncode}):\n"
                               f"{proc.stdout}\n{proc.stderr}")
    path = out / f"{name}.fmu"
    if not path.is_file():
        raise RuntimeError(f"pythonfmu did not write {path}")
    return path


def stale_reason(fmu_path, src_dir=None):
    """Why the FMU at ``fmu_path`` no longer matches the source tree, or None.

    Compares the bundled core modules and slave script with the current files.
    """
    import zipfile
    name = Path(fmu_path).stem
    if name not in FMUS:
        return None
    script, modules = FMUS[name]
    if not Path(fmu_path).is_file():
        return "missing"
    wanted = {f"resources/gdcore/{m}": PACKAGE_DIR / m for m in modules}
    src = _fmu_src_dir(src_dir) / script
    if src.is_file():
        wanted[f"resources/{script}"] = src
    with zipfile.ZipFile(fmu_path) as z:
        names = set(z.namelist())
        for arc, local in wanted.items():
            if arc not in names or z.read(arc) != local.read_bytes():
                return f"{arc} differs from {local}"
    return None


def build_all(out_dir="build", src_dir=None, names=None):
    """Build the FMUs (all by default); return {name: path}."""
    return {n: build_fmu(n, out_dir, src_dir) for n in (names or FMUS)}


# ------------------------------------------------------------------ fmpy host
class FmuInstance:
    """One FMU instance through fmpy's ``FMU2Slave``: variables by name, typed
    setting of parameters, and the FMU's log messages collected in ``messages``
    as (status, category, text). ``unzipdir`` may be shared by several instances.
    """

    def __init__(self, fmu_path, instance_name=None, unzipdir=None, logging_on=True):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        self.path = Path(fmu_path)
        if not self.path.is_file():
            raise InputError(f"{self.path}: no such FMU (run 'gyrodenoise fmu build' first)")
        self.md = read_model_description(str(self.path))
        self.unzipdir = unzipdir or extract(str(self.path))
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.vr = {name: v.valueReference for name, v in self.variables.items()}
        self.messages = []
        self._callbacks = self._make_callbacks()
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                               modelIdentifier=self.md.coSimulation.modelIdentifier,
                               instanceName=instance_name or self.md.modelName)
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=logging_on)

    def _make_callbacks(self):
        from fmpy import calloc, free
        from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

        def logger(env, instance, status, category, message):
            self.messages.append((int(status), (category or b"").decode("utf-8", "replace"),
                                  (message or b"").decode("utf-8", "replace")))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        return cb

    def set(self, **values):
        """Set variables by name, each with the setter of its declared type."""
        for name, value in values.items():
            if name not in self.variables:
                raise InputError(f"{self.path.name}: no variable {name!r}")
            vt = self.variables[name].type
            vr = [self.vr[name]]
            if vt == "Real":
                self.slave.setReal(vr, [float(value)])
            elif vt in ("Integer", "Enumeration"):
                self.slave.setInteger(vr, [int(value)])
            elif vt == "Boolean":
                self.slave.setBoolean(vr, [bool(value)])
            else:
                self.slave.setString(vr, [str(value)])

    def get(self, name):
        vt = self.variables[name].type
        vr = [self.vr[name]]
        if vt == "Real":
            return self.slave.getReal(vr)[0]
        if vt in ("Integer", "Enumeration"):
            return self.slave.getInteger(vr)[0]
        if vt == "Boolean":
            return bool(self.slave.getBoolean(vr)[0])
        return self.slave.getString(vr)[0].decode("utf-8")

    def initialize(self, start_time=0.0, **params):
        """setupExperiment, parameters, enter/exit initialisation mode."""
        self.slave.setupExperiment(startTime=start_time)
        self.set(**params)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def errors(self):
        """Logged messages of status error or worse."""
        return [m for m in self.messages if m[0] >= 3]

    def free(self, terminate=True):
        if self.slave is None:
            return
        try:
            if terminate:
                self.slave.terminate()
        finally:
            self.slave.freeInstance()
            self.slave = None


def _stepper(inst, in_real, in_bool, out_real):
    """A fast one-sample step for ``inst``: ``f(x, flag, t, h) -> output``.

    Calls the FMI functions of the FMU's library directly with preallocated
    ctypes buffers (fmpy's wrappers cost ~5 µs a call); a status worse than
    fmi2Warning raises :class:`FmuStepError` with the FMU's logged errors.
    """
    from fmpy.fmi2 import fmi2Boolean, fmi2Real, fmi2ValueReference
    s = inst.slave
    c = s.component
    vr_r = (fmi2ValueReference * 1)(inst.vr[in_real])
    vr_b = (fmi2ValueReference * 1)(inst.vr[in_bool])
    vr_o = (fmi2ValueReference * 1)(inst.vr[out_real])
    x = (fmi2Real * 1)()
    flag = (fmi2Boolean * 1)()
    y = (fmi2Real * 1)()
    # the library's functions, argtypes already declared by fmpy
    set_real, set_bool = s._functions["fmi2SetReal"], s._functions["fmi2SetBoolean"]
    do_step, get_real = s._functions["fmi2DoStep"], s._functions["fmi2GetReal"]

    def step(value, restart, t, h):
        x[0] = value
        flag[0] = 1 if restart else 0
        st = (set_real(c, vr_r, 1, x) | set_bool(c, vr_b, 1, flag)
              | do_step(c, t, h, 1) | get_real(c, vr_o, 1, y))
        if st > 1:
            raise FmuStepError(inst, t)
        return y[0]
    return step


class FmuStepError(RuntimeError):
    """A step of an FMU failed; the message holds what the FMU logged."""

    def __init__(self, inst, t):
        errs = "; ".join(m[2] for m in inst.errors()) or "no message logged"
        super().__init__(f"{inst.path.name} failed at t={t} s: {errs}")


def _resolve_card(card):
    from .simulator import load_card
    return load_card(card)


def _fmu_paths(fmu_dir):
    d = Path(fmu_dir)
    paths = {n: d / f"{n}.fmu" for n in FMUS}
    missing = [str(p) for p in paths.values() if not p.is_file()]
    if missing:
        raise InputError(f"{', '.join(missing)}: not found (run 'gyrodenoise fmu build --out {d}')")
    return paths


def _restart_mask(n, fs, restart_at_s):
    import numpy as np
    rs = np.zeros(n, dtype=bool)
    if restart_at_s is not None:
        k = int(round(restart_at_s * fs))
        if not 0 < k < n:
            raise InputError(f"--restart-at {restart_at_s} s is outside the run (0, {n / fs} s)")
        rs[k] = True
    return rs


def _denoiser_params(method, ar_order, fs, extra=None):
    p = {"method": method, "ar_order": int(ar_order), "sample_period": 1.0 / fs}
    p.update(extra or {})
    return p


def compare_with_core(measured, filtered, true_rate, restarts, card, seed, method, ar_order,
                      denoiser_kw=None):
    """Check an FMU run against the core: the simulator's batch record for the
    same card and seed, and ``gyrodenoise.denoise`` on the FMU's own raw samples.
    Returns the differences and the Allan terms of raw, FMU-filtered and
    batch-filtered records with their reduction ratios."""
    import numpy as np
    import gyrodenoise as gd
    fs = card.sample_rate_hz
    n = len(measured)
    rec = gd.simulate(card, n, seed=seed, true_rate_deg_s=true_rate, restarts=restarts)
    ref = gd.denoise(measured, fs, method=method, ar_order=ar_order, restarts=restarts,
                     **(denoiser_kw or {}))
    d_meas = float(np.max(np.abs(np.asarray(measured) - rec.rate_deg_s)))
    d_filt = float(np.max(np.abs(np.asarray(filtered) - ref)))
    a_raw = gd.allan(np.asarray(measured), fs).terms
    a_fmu = gd.allan(np.asarray(filtered), fs).terms
    a_ref = gd.allan(ref, fs).terms

    def ratios(a, b):
        return {k: (a[k] / b[k] if b[k] > 0 else None) for k in a}

    red_fmu, red_ref = ratios(a_raw, a_fmu), ratios(a_raw, a_ref)
    rel = max((abs(a_fmu[k] - a_ref[k]) / max(abs(a_ref[k]), 1e-300) for k in a_ref
               if a_ref[k] or a_fmu[k]), default=0.0)
    return {
        "max_abs_diff_measured_vs_simulate_deg_s": d_meas,
        "max_abs_diff_filtered_vs_denoise_deg_s": d_filt,
        "allan": {"raw": a_raw, "fmu_filtered": a_fmu, "batch_filtered": a_ref},
        "reduction_fmu": red_fmu, "reduction_batch": red_ref,
        "allan_max_rel_diff": float(rel),
    }


def validation_run(fmu_dir="build", duration_s=600.0, rate_deg_s=0.0, restart_at_s=None,
                   seed=0, card="paper_fog", method=DEFAULT_METHOD, ar_order=3, tol=1e-9,
                   keep_arrays=False, denoiser_kw=None):
    """SimulatedFog -> FogDenoiser through fmpy ``FMU2Slave``, one step per sample.

    Each step: SimulatedFog gets ``true_rate`` and ``restart`` and steps; its
    ``measured_rate`` goes into FogDenoiser's ``raw_rate`` (with the same
    ``restart``), which steps. The result is compared with the core
    (:func:`compare_with_core`); ``ok`` is true when both outputs agree within
    ``tol`` and the Allan reductions agree.
    """
    import time
    import numpy as np
    card_obj = _resolve_card(card)
    fs = card_obj.sample_rate_hz
    h = 1.0 / fs
    n = int(round(duration_s * fs))
    if n < 2:
        raise InputError(f"--duration {duration_s} s gives fewer than 2 samples at {fs} Hz")
    paths = _fmu_paths(fmu_dir)
    restarts = _restart_mask(n, fs, restart_at_s)
    truth = np.full(n, float(rate_deg_s))
    fog = FmuInstance(paths["SimulatedFog"], "fog")
    den = FmuInstance(paths["FogDenoiser"], "denoiser")
    try:
        fog.initialize(card=card_obj.text, seed=int(seed))
        den.initialize(**_denoiser_params(method, ar_order, fs, denoiser_kw))
        fog_step = _stepper(fog, "true_rate", "restart", "measured_rate")
        den_step = _stepper(den, "raw_rate", "restart", "filtered_rate")
        measured = np.empty(n)
        filtered = np.empty(n)
        t0 = time.perf_counter()
        tl, rl = truth.tolist(), restarts.tolist()
        for k in range(n):
            t = k * h
            z = fog_step(tl[k], rl[k], t, h)
            measured[k] = z
            filtered[k] = den_step(z, rl[k], t, h)
        elapsed = time.perf_counter() - t0
        converged = den.get("converged")
        readouts = {name: den.get(name) for name in
                    [f"phi_{i}" for i in range(1, int(ar_order) + 1)] + ["c", "R_hat", "innovation"]}
        errors = fog.errors() + den.errors()
    finally:
        fog.free()
        den.free()
    res = {"case": {"duration_s": n / fs, "n_samples": n, "sample_rate_hz": fs,
                    "true_rate_deg_s": float(rate_deg_s), "restart_at_s": restart_at_s,
                    "seed": int(seed), "card": card_obj.name, "method": method,
                    "ar_order": int(ar_order)},
           "elapsed_s": elapsed, "two_fmu_steps_per_s": n / elapsed,
           "converged_at_end": bool(converged), "final_readouts": readouts,
           "fmu_errors": [m[2] for m in errors]}
    res.update(compare_with_core(measured, filtered, truth, restarts, card_obj, seed, method,
                                 ar_order, denoiser_kw))
    res["tolerance_deg_s"] = tol
    res["ok"] = bool(res["max_abs_diff_measured_vs_simulate_deg_s"] <= tol
                     and res["max_abs_diff_filtered_vs_denoise_deg_s"] <= tol
                     and res["allan_max_rel_diff"] <= 1e-6 and not errors)
    if keep_arrays:
        res["arrays"] = {"measured": measured, "filtered": filtered, "true_rate": truth,
                         "restarts": restarts}
    return res


# ------------------------------------------------------- SSP and libcosimpy
def _xml_attr(value):
    from xml.sax.saxutils import quoteattr
    return quoteattr(str(value)).replace("\n", "&#10;").replace("\r", "&#13;").replace("\t", "&#9;")


def _ssv_parameters(params, var_types):
    rows = []
    for name, value in params.items():
        kind = var_types[name]
        if kind == "Boolean":
            v = "true" if value else "false"
        elif kind == "Real":
            v = repr(float(value))
        elif kind == "Integer":
            v = str(int(value))
        else:
            v = str(value)
        rows.append(f'                  <ssv:Parameter name={_xml_attr(name)}>'
                    f'<ssv:{kind} value={_xml_attr(v)}/></ssv:Parameter>')
    return "\n".join(rows)


def system_parameters(card, seed=0, method=DEFAULT_METHOD, ar_order=3, rate_deg_s=0.0, denoiser_kw=None):
    """Parameter values of the two-FMU system: {instance: {variable: value}}."""
    card_obj = _resolve_card(card)
    fs = card_obj.sample_rate_hz
    return card_obj, {
        "fog": {"card": card_obj.text, "seed": int(seed), "true_rate": float(rate_deg_s)},
        "denoiser": _denoiser_params(method, ar_order, fs, denoiser_kw),
    }


def write_ssp(path, fmu_dir="build", card="paper_fog", seed=0, method=DEFAULT_METHOD, ar_order=3,
              rate_deg_s=0.0, duration_s=600.0, denoiser_kw=None):
    """Write an SSP 1.0 archive of SimulatedFog -> FogDenoiser; return its path.

    The archive holds ``SystemStructure.ssd`` and both FMUs under ``resources/``;
    the connections are ``fog.measured_rate -> denoiser.raw_rate`` and
    ``fog.restarted -> denoiser.restart``; the parameters are bound inline;
    the step size (the card's sample period) is given in the OSP annotation of
    the default experiment (libcosim reads it) and is what any SSP master should use.
    """
    import zipfile
    from fmpy import read_model_description
    paths = _fmu_paths(fmu_dir)
    card_obj, params = system_parameters(card, seed, method, ar_order, rate_deg_s, denoiser_kw)
    h = 1.0 / card_obj.sample_rate_hz
    comps = []
    for inst, model in (("fog", "SimulatedFog"), ("denoiser", "FogDenoiser")):
        md = read_model_description(str(paths[model]))
        types = {v.name: v.type for v in md.modelVariables}
        conns = "\n".join(
            f'          <ssd:Connector name={_xml_attr(v.name)} kind="{v.causality}">'
            f'<ssc:{v.type}/></ssd:Connector>'
            for v in md.modelVariables if v.causality in ("input", "output", "parameter"))
        comps.append(f'''      <ssd:Component name="{inst}" type="application/x-fmu-sharedlibrary" source="resources/{model}.fmu">
        <ssd:Connectors>
{conns}
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="{inst}_parameters">
                <ssv:Parameters>
{_ssv_parameters(params[inst], types)}
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>''')
    comps_xml = "\n".join(comps)
    ssd = f'''<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="gyrodenoise_fmu_chain"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations">
  <ssd:System name="fog_chain" description="SimulatedFog (model card {_xml_attr(card_obj.name)[1:-1]}, seed {int(seed)}) -> FogDenoiser; one step = one sample">
    <ssd:Elements>
{comps_xml}
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="fog" startConnector="measured_rate" endElement="denoiser" endConnector="raw_rate"/>
      <ssd:Connection startElement="fog" startConnector="restarted" endElement="denoiser" endConnector="restart"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0.0" stopTime="{float(duration_s)!r}">
    <ssd:Annotations>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm>
          <osp:FixedStepAlgorithm baseStepSize="{h!r}"/>
        </osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
'''
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", ssd)
        for model, p in paths.items():
            z.write(p, f"resources/{model}.fmu")
    return path


def cosim_run(fmu_dir="build", duration_s=60.0, rate_deg_s=0.0, restart_at_s=None, seed=0,
              card="paper_fog", method=DEFAULT_METHOD, ar_order=3, ssp=None, tol=1e-9,
              keep_arrays=False, denoiser_kw=None):
    """The two-FMU system in libcosim (Open Simulation Platform) via libcosimpy.

    ``ssp=None`` builds the system from Python (local slaves, connections,
    initial values); ``ssp=PATH`` writes an SSP archive there (:func:`write_ssp`)
    and loads the system from it. A restart is injected with an override
    manipulator on ``fog.restart`` for one step.

    libcosim's fixed-step master is of Jacobi type: FogDenoiser receives in step
    k what SimulatedFog produced in step k-1 (and in step 0 SimulatedFog's
    initial output, 0 deg/s). The check is therefore that the denoiser's
    received samples are SimulatedFog's delayed by one step, that those equal
    ``gyrodenoise.simulate``, and that the denoiser's output equals
    ``gyrodenoise.denoise`` on the samples it received.
    """
    import time
    import numpy as np
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    log_output_level(CosimLogLevel.WARNING)

    card_obj, params = system_parameters(card, seed, method, ar_order, rate_deg_s, denoiser_kw)
    fs = card_obj.sample_rate_hz
    h_ns = int(round(1e9 / fs))
    if abs(h_ns * 1e-9 * fs - 1.0) > 1e-9:
        raise InputError(f"sample rate {fs} Hz is not a whole number of nanoseconds per sample "
                         "(libcosim's time unit)")
    n = int(round(duration_s * fs))
    paths = _fmu_paths(fmu_dir)
    from fmpy import read_model_description
    vrs = {m: {v.name: (v.valueReference, v.type) for v in read_model_description(str(p)).modelVariables}
           for m, p in paths.items()}
    fvr, dvr = vrs["SimulatedFog"], vrs["FogDenoiser"]

    if ssp is not None:
        ssp_path = write_ssp(ssp, fmu_dir, card_obj, seed, method, ar_order, rate_deg_s, duration_s,
                             denoiser_kw)
        ex = CosimExecution.from_ssp_file(str(ssp_path))
        fog = ex.slave_index_from_instance_name("fog")
        den = ex.slave_index_from_instance_name("denoiser")
    else:
        ex = CosimExecution.from_step_size(h_ns)
        fog = ex.add_local_slave(CosimLocalSlave(str(paths["SimulatedFog"]), "fog"))
        den = ex.add_local_slave(CosimLocalSlave(str(paths["FogDenoiser"]), "denoiser"))
        setters = {"Real": ex.real_initial_value, "Integer": ex.integer_initial_value,
                   "Boolean": ex.boolean_initial_value, "String": ex.string_initial_value}
        for idx, inst, table in ((fog, "fog", fvr), (den, "denoiser", dvr)):
            for name, value in params[inst].items():
                vr, kind = table[name]
                setters[kind](idx, vr, value)
        ex.connect_real_variables(fog, fvr["measured_rate"][0], den, dvr["raw_rate"][0])
        ex.connect_boolean_variables(fog, fvr["restarted"][0], den, dvr["restart"][0])
    if fog < 0 or den < 0:
        raise RuntimeError("libcosim: the system has no instances 'fog' and 'denoiser'")

    obs = CosimObserver.create_time_series(buffer_size=n + 16)
    ex.add_observer(obs)
    last = CosimObserver.create_last_value()
    ex.add_observer(last)
    for idx, vr in ((fog, fvr["measured_rate"][0]), (den, dvr["raw_rate"][0]),
                    (den, dvr["filtered_rate"][0])):
        obs.start_time_series(idx, vr, CosimVariableType.REAL)
    man = CosimManipulator.create_override()
    ex.add_manipulator(man)

    restarts = _restart_mask(n, fs, restart_at_s)
    t0 = time.perf_counter()
    ok = True
    if restart_at_s is None:
        ok &= ex.step(n)
    else:
        k = int(np.flatnonzero(restarts)[0])
        ok &= ex.step(k)
        man.slave_boolean_values(fog, [fvr["restart"][0]], [True])
        ok &= ex.step(1)
        man.slave_boolean_values(fog, [fvr["restart"][0]], [False])
        ok &= ex.step(n - k - 1)
    elapsed = time.perf_counter() - t0
    if not ok:
        from libcosimpy.CosimExecution import get_last_error_message  # type: ignore[attr-defined]
        raise RuntimeError(f"libcosim: stepping failed: {get_last_error_message()}")

    def series(idx, vr):
        times, _, values = obs.time_series_real_samples(idx, vr, from_step=1, sample_count=n)
        return np.asarray(times, dtype=float) * 1e-9, np.asarray(values, dtype=float)

    times, measured = series(fog, fvr["measured_rate"][0])
    _, received = series(den, dvr["raw_rate"][0])
    _, filtered = series(den, dvr["filtered_rate"][0])
    converged = bool(last.last_boolean_values(den, [dvr["converged"][0]])[0])
    ex.stop()
    del ex
    if not (len(measured) == len(received) == len(filtered) == n):
        raise RuntimeError(f"libcosim observer returned {len(measured)}/{len(received)}/"
                           f"{len(filtered)} samples, expected {n}")
    truth = np.full(n, float(rate_deg_s))
    # what the denoiser received: SimulatedFog's initial output, then its samples one step late
    rec_restarts = np.concatenate(([False], restarts[:-1]))
    res = {"case": {"master": "libcosim (SSP)" if ssp is not None else "libcosim (Python)",
                    "duration_s": n / fs, "n_samples": n, "sample_rate_hz": fs,
                    "true_rate_deg_s": float(rate_deg_s), "restart_at_s": restart_at_s,
                    "seed": int(seed), "card": card_obj.name, "method": method,
                    "ar_order": int(ar_order)},
           "elapsed_s": elapsed, "two_fmu_steps_per_s": n / elapsed, "converged_at_end": converged,
           "step_size_s": float(np.median(np.diff(times))) if n > 1 else None,
           "first_received_deg_s": float(received[0]),
           "max_abs_diff_received_vs_delayed_measured_deg_s":
               float(np.max(np.abs(received[1:] - measured[:-1]))) if n > 1 else 0.0}
    cmp_ = compare_with_core(measured, measured, truth, restarts, card_obj, seed, method, ar_order,
                             denoiser_kw)
    res["max_abs_diff_measured_vs_simulate_deg_s"] = cmp_["max_abs_diff_measured_vs_simulate_deg_s"]
    import gyrodenoise as gd
    ref = gd.denoise(received, fs, method=method, ar_order=ar_order, restarts=rec_restarts,
                     **(denoiser_kw or {}))
    res["max_abs_diff_filtered_vs_denoise_deg_s"] = float(np.max(np.abs(filtered - ref)))
    res["tolerance_deg_s"] = tol
    res["ok"] = bool(res["max_abs_diff_received_vs_delayed_measured_deg_s"] == 0.0
                     and abs(res["step_size_s"] * fs - 1.0) < 1e-9
                     and res["max_abs_diff_measured_vs_simulate_deg_s"] <= tol
                     and res["max_abs_diff_filtered_vs_denoise_deg_s"] <= tol)
    if keep_arrays:
        res["arrays"] = {"measured": measured, "received": received, "filtered": filtered,
                         "time_s": times, "restarts": restarts}
    return res


# ---------------------------------------------------------------------- CLI
def register_cli(subparsers):
    """Add ``gyrodenoise fmu build`` and ``gyrodenoise fmu run``."""
    p = subparsers.add_parser("fmu", help="build and check the FMUs (FMI 2.0 co-simulation)",
                              description="Build FogDenoiser.fmu and SimulatedFog.fmu, and run the "
                                          "two-FMU validation against the core.")
    sub = p.add_subparsers(dest="fmu_command", metavar="ACTION")
    b = sub.add_parser("build", help="build build/FogDenoiser.fmu and build/SimulatedFog.fmu",
                       description="Package fmu_src/*.py with pythonfmu (in a subprocess) and the "
                                   "plain-Python core into FMI 2.0 co-simulation FMUs.")
    b.add_argument("--out", default="build", metavar="DIR", help="output folder (default: build/)")
    b.set_defaults(func=_cmd_build)
    r = sub.add_parser("run", help="SimulatedFog -> FogDenoiser validation run (fmpy or libcosim)",
                       description="Run SimulatedFog -> FogDenoiser one sample per step and compare "
                                   "with the core's batch output (1e-9) and Allan reduction. Without "
                                   "--rate, runs a static and a constant-rate case, each with a "
                                   "restart in the middle. Exit status 1 when a check fails.")
    r.add_argument("--fmu-dir", default="build", metavar="DIR",
                   help="folder of the FMUs (default: build/; built there when missing)")
    r.add_argument("--duration", type=float, default=600.0, metavar="S",
                   help="length of each case, s (default 600)")
    r.add_argument("--rate", type=float, default=None, metavar="DEG_S",
                   help="run one case at this constant true rate, deg/s")
    r.add_argument("--constant-rate", type=float, default=10.0, metavar="DEG_S",
                   help="true rate of the constant-rate case, deg/s (default 10)")
    r.add_argument("--restart-at", type=float, default=None, metavar="S",
                   help="time of the restart, s (default: the middle); negative: no restart")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--card", default="paper_fog", help="model card path or embedded name")
    r.add_argument("--method", default=DEFAULT_METHOD, choices=["motion", "shakf", "kf", "sh_classic", "lowpass", "none"])
    r.add_argument("--ar-order", type=int, default=3)
    r.add_argument("--master", default="fmpy", choices=["fmpy", "libcosim", "ssp"],
                   help="fmpy FMU2Slave loop (default), libcosim built from Python, or "
                        "libcosim from an SSP file written next to the FMUs")
    r.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    r.set_defaults(func=_cmd_run)
    p.set_defaults(func=lambda args: (p.print_help(sys.stderr), 2)[1])


def _cmd_build(args):
    paths = build_all(args.out)
    for name, path in paths.items():
        print(f"{name}: {path}")
    return 0


def _cmd_run(args):
    import json
    fmu_dir = Path(args.fmu_dir)
    _resolve_card(args.card)          # a bad card is a user error before anything runs
    reasons = {n: stale_reason(fmu_dir / f"{n}.fmu") for n in FMUS}
    if any(reasons.values()):
        why = "; ".join(f"{n}: {r}" for n, r in reasons.items() if r)
        print(f"gyrodenoise: (re)building the FMUs in {fmu_dir}/ ({why})", file=sys.stderr)
        build_all(fmu_dir)
    if args.duration <= 0:
        raise InputError(f"--duration must be > 0 s, got {args.duration}")
    if args.rate is not None:
        cases = {"constant_rate": args.rate}
    else:
        cases = {"static": 0.0, "constant_rate": args.constant_rate}
    if args.restart_at is None:
        restart_at = args.duration / 2
    else:
        restart_at = None if args.restart_at < 0 else args.restart_at
    results = {}
    for case, rate in cases.items():
        kw = dict(duration_s=args.duration, rate_deg_s=rate, restart_at_s=restart_at, seed=args.seed,
                  card=args.card, method=args.method, ar_order=args.ar_order)
        print(f"gyrodenoise: fmu run: {case} ({args.master})", file=sys.stderr)
        if args.master == "fmpy":
            results[case] = validation_run(fmu_dir, **kw)
        else:
            ssp = fmu_dir / "gyrodenoise_fog_chain.ssp" if args.master == "ssp" else None
            results[case] = cosim_run(fmu_dir, ssp=ssp, **kw)
    ok = all(r["ok"] for r in results.values())
    if args.json:
        from .cli import emit_json
        emit_json({"master": args.master, "cases": results, "ok": ok})
    else:
        print(_format_results(results))
        print("ok" if ok else "FAILED: FMU output differs from the core", flush=True)
    return 0 if ok else 1


def _format_results(results):
    lines = []
    for case, r in results.items():
        c = r["case"]
        lines.append(f"== {case}: {c['duration_s']:g} s at {c['sample_rate_hz']:g} Hz, true rate "
                     f"{c['true_rate_deg_s']:g} deg/s, restart at {c['restart_at_s']} s, "
                     f"{c['method']} AR({c['ar_order']}), seed {c['seed']}")
        lines.append(f"   {r['elapsed_s']:.2f} s, {r['two_fmu_steps_per_s']:.0f} two-FMU steps/s")
        lines.append(f"   max |FMU measured - simulate|  = {r['max_abs_diff_measured_vs_simulate_deg_s']:.3g} deg/s")
        lines.append(f"   max |FMU filtered - denoise|   = {r['max_abs_diff_filtered_vs_denoise_deg_s']:.3g} deg/s")
        if "allan" in r:
            a = r["allan"]
            lines.append("   Allan term      raw        FMU filt   batch filt  reduction FMU / batch")
            for k in ("N", "B", "K", "R", "Q"):
                rf, rb = r["reduction_fmu"][k], r["reduction_batch"][k]
                fmt = lambda v: "-" if v is None else f"{v:.3g}"  # noqa: E731
                lines.append(f"   {k}  {a['raw'][k]:11.4g} {a['fmu_filtered'][k]:11.4g} "
                             f"{a['batch_filtered'][k]:11.4g}   {fmt(rf)} / {fmt(rb)}")
        lines.append(f"   {'ok' if r['ok'] else 'FAILED'}")
    return "\n".join(lines)
