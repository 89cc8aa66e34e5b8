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

    Calls the FMI functions directly with preallocated ctypes buffers (fmpy's
    convenience wrappers allocate per call); statuses are still checked by fmpy.
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
    set_real, set_bool, do_step, get_real = s.fmi2SetReal, s.fmi2SetBoolean, s.fmi2DoStep, s.fmi2GetReal

    def step(value, restart, t, h):
        x[0] = value
        flag[0] = 1 if restart else 0
        set_real(c, vr_r, 1, x)
        set_bool(c, vr_b, 1, flag)
        do_step(c, t, h, 1)
        get_real(c, vr_o, 1, y)
        return y[0]
    return step


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
                   seed=0, card="paper_fog", method="shakf", ar_order=3, tol=1e-9,
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
