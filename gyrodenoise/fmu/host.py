"""An FMU instance driven from Python through fmpy's ``FMU2Slave``."""

from __future__ import annotations

from pathlib import Path

from gyrodenoise.errors import InputError


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
