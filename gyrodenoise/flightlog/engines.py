"""Denoising engines: the native core (the C core, batch) and the FogDenoiser FMU (fmpy).

Both filter one axis of one stream, a 1-D array in deg/s (or counts when the
unit is unknown), with the restart flags of the stream, and return the
filtered array (``filter``), or with it the bias that bias tracking removed after
each sample (``filter_with_bias``: what the range check needs, the output being the
filter's clamped value less that bias). Each call is a fresh denoiser instance:
every stream and axis gets its own.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from gyrodenoise.core.kernels import DEFAULT_METHOD
from gyrodenoise.core.methods import BY_NAME, BY_PARAM, METHODS, PARAMS
from gyrodenoise.errors import InputError

ENGINES = ("native", "fmu")


def _params(method: str, ar_order: int, rate_hz: float, warmup_s: float | None = None,
            filter_kw: dict | None = None) -> list[float]:
    from gyrodenoise.core import kernels as K
    kw = dict(filter_kw or {})
    if warmup_s is not None:
        kw["warmup_s"] = float(warmup_s)
    return K.make_params(ar_order=ar_order, method=method, sample_rate_hz=rate_hz, **kw)


def warmup_samples(method: str, ar_order: int, rate_hz: float, warmup_s: float | None = None,
                   filter_kw: dict | None = None) -> int:
    """Samples after each restart that the core passes through raw (its warm-up rule,
    :func:`gyrodenoise.core.kernels.raw_warmup_samples`)."""
    from gyrodenoise.core import kernels as K
    try:
        return K.raw_warmup_samples(_params(method, ar_order, rate_hz, warmup_s, filter_kw))
    except ValueError:          # e.g. a cutoff this rate cannot take: the warm-up without it
        kw = {k: v for k, v in (filter_kw or {}).items() if not BY_PARAM[k].methods}   # a method's own
        return K.raw_warmup_samples(_params(method, ar_order, rate_hz, warmup_s, kw))


class _Settings:
    """What both engines tell of their filter at a sample rate."""

    def filter_with_bias(self, x, restarts, rate_hz):
        """(the filtered array, the bias that bias tracking removed after each sample or None
        when it is off): the output is the filter's clamped value less that bias, and the range
        check (:func:`gyrodenoise.flightlog.checks.check_filtered`) needs both."""
        return self.filter(x, restarts, rate_hz), self.bias_removed(x, restarts, rate_hz)

    def warmup_samples(self, rate_hz):
        return warmup_samples(self.method, self.ar_order, rate_hz, self.warmup_s, self.filter_kw)

    def check_rate(self, rate_hz):
        """ValueError (one line, the core's) when the filter cannot run at ``rate_hz``
        (a --cutoff-hz not below half of it)."""
        _params(self.method, self.ar_order, rate_hz, self.warmup_s, self.filter_kw)

    def cutoff_hz(self, rate_hz):
        """The low-pass's effective -3 dB cutoff at ``rate_hz`` (the default is
        min(20 Hz, rate / 4)); None for the other methods or a rate it cannot take."""
        from gyrodenoise.core import kernels as K
        if not BY_PARAM["cutoff_hz"].applies_to(self.method):
            return None
        try:
            return float(_params(self.method, self.ar_order, rate_hz, self.warmup_s, self.filter_kw)[K.P_LP_CUTOFF])
        except ValueError:
            return None


class NativeEngine(_Settings):
    """The core through :class:`gyrodenoise.denoiser.Denoiser` (causal), or for a whole
    record (files) its offline forms: ``zero_phase`` (the low-pass forwards then
    backwards) and ``offline`` (``method="motion"``: the forward and backward runs of
    the bank blended, :func:`gyrodenoise.core.batch.run_offline`), each session on its own."""

    name = "native"

    def __init__(self, method=DEFAULT_METHOD, ar_order=3, warmup_s=None, filter_kw=None, zero_phase=False,
                 offline=False):
        if offline and (method not in BY_NAME or BY_NAME[method].offline != "smoother"):
            owners = [m.name for m in METHODS if m.offline == "smoother"]
            raise InputError(f"the offline form is defined for --method {', '.join(owners)} only, not {method}")
        self.method = method
        self.ar_order = int(ar_order)
        self.warmup_s = warmup_s
        self.filter_kw = dict(filter_kw or {})
        self.zero_phase = bool(zero_phase)
        self.offline = bool(offline)
        #: False when an output sample depends on later samples of its session
        self.causal = not (self.zero_phase or self.offline)
        self.kw = {} if warmup_s is None else {"warmup_s": float(warmup_s)}
        self.kw.update(filter_kw or {})

    def filter(self, x, restarts, rate_hz):
        x = np.ascontiguousarray(x, dtype=np.float64)
        restarts = None if restarts is None else np.asarray(restarts, dtype=bool)
        if not self.causal:           # forwards and backwards, per session (offline files only)
            from gyrodenoise.denoiser import denoise
            return np.asarray(denoise(x, rate_hz, method=self.method, ar_order=self.ar_order,
                                      restarts=restarts, zero_phase=self.zero_phase, offline=self.offline,
                                      **self.kw))
        from gyrodenoise.denoiser import Denoiser
        d = Denoiser(sample_rate_hz=rate_hz, method=self.method, ar_order=self.ar_order, **self.kw)
        return np.asarray(d.process(x, restarts))

    def bias_removed(self, x, restarts, rate_hz):
        """The bias that bias tracking removed after each sample (the causal run's ``bias_hat``,
        :func:`gyrodenoise.denoiser.run_with_bias`; the offline form takes it off the samples
        before the smoother), None when it is off."""
        from gyrodenoise.core import kernels as K
        from gyrodenoise.denoiser import run_with_bias
        p = K.make_params(ar_order=self.ar_order, method=self.method, sample_rate_hz=rate_hz, **self.kw)
        if not p[K.P_BIAS] > 0.0:
            return None
        return run_with_bias(p, np.ascontiguousarray(x, dtype=np.float64),
                             None if restarts is None else np.asarray(restarts, dtype=bool))[1]

    def close(self):
        pass


def default_fmu_path() -> Path:
    """``$GYRODENOISE_FMU``, else ``build/FogDenoiser.fmu`` of the source tree or the cwd."""
    env = os.environ.get("GYRODENOISE_FMU")
    if env:
        return Path(env)
    repo = Path(__file__).resolve().parents[1] / "build" / "FogDenoiser.fmu"
    if repo.is_file():
        return repo
    return Path("build") / "FogDenoiser.fmu"


class FmuEngine(_Settings):
    """The FogDenoiser FMU driven by fmpy's ``FMU2Slave``, one communication
    step per sample (step size = the sample period the FMU is given)."""

    name = "fmu"
    #: the FMU steps one sample at a time: always the causal filter
    causal = True

    #: core parameter name -> FMU parameter name (the registry's; they differ for the low-pass order)
    FMU_NAMES = {p.name: p.fmu for p in PARAMS if p.fmu}

    def __init__(self, method=DEFAULT_METHOD, ar_order=3, fmu_path=None, warmup_s=None, filter_kw=None,
                 zero_phase=False):
        if zero_phase:
            raise InputError("--zero-phase: the FMU filters causally, one sample per step; "
                             "use --engine native for a zero-phase low-pass")
        self.method = method
        self.ar_order = int(ar_order)
        self.warmup_s = warmup_s
        self.filter_kw = dict(filter_kw or {})   # FMU parameter name -> value
        self.path = Path(fmu_path) if fmu_path else default_fmu_path()
        if not self.path.is_file():
            raise InputError(f"{self.path}: FogDenoiser FMU not found (build it with "
                             f"'gyrodenoise fmu build', or pass --fmu PATH)")
        from fmpy import extract, read_model_description
        try:
            self.md = read_model_description(str(self.path))
        except Exception as exc:  # noqa: BLE001 - fmpy raises many kinds
            raise InputError(f"{self.path}: not a readable FMU ({exc})") from None
        self.vars = {v.name: v for v in self.md.modelVariables}
        for need in ("raw_rate", "restart", "filtered_rate"):
            if need not in self.vars:
                raise InputError(f"{self.path}: FMU has no variable {need!r}")
        if self.md.coSimulation is None:
            raise InputError(f"{self.path}: FMU does not support co-simulation")
        self._tmp = tempfile.mkdtemp(prefix="gd_fmu_")
        self.unzipdir = extract(str(self.path), unzipdir=self._tmp)

    def _set_param(self, fmu, name, value):
        v = self.vars.get(name)
        if v is None:
            return False
        vr = [v.valueReference]
        if v.type == "Integer":
            fmu.setInteger(vr, [int(value)])
        elif v.type == "Real":
            fmu.setReal(vr, [float(value)])
        elif v.type == "String":
            fmu.setString(vr, [str(value)])
        elif v.type == "Boolean":
            fmu.setBoolean(vr, [bool(value)])
        return True

    def filter(self, x, restarts, rate_hz):
        return self.filter_with_bias(x, restarts, rate_hz)[0]

    def filter_with_bias(self, x, restarts, rate_hz):
        """(filtered, bias): ``bias`` the FMU's output ``bias_hat`` after each step (read in the
        same run), None when bias tracking is off."""
        from fmpy.fmi2 import FMU2Slave
        x = np.asarray(x, dtype=np.float64)
        n = len(x)
        r = np.zeros(n, dtype=bool) if restarts is None else np.asarray(restarts, dtype=bool)
        h = 1.0 / float(rate_hz)
        fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                        modelIdentifier=self.md.coSimulation.modelIdentifier,
                        instanceName="gyro")
        fmu.instantiate()
        try:
            fmu.setupExperiment(startTime=0.0)
            self._set_param(fmu, "ar_order", self.ar_order)
            self._set_param(fmu, "method", self.method)
            if self.warmup_s is not None and not self._set_param(fmu, "warmup_s", self.warmup_s):
                raise InputError(f"{self.path}: FMU has no parameter 'warmup_s' (--warmup-s)")
            for name, value in self.filter_kw.items():
                if not self._set_param(fmu, self.FMU_NAMES.get(name, name), value):
                    raise InputError(f"{self.path}: FMU has no parameter {name!r} "
                                     f"(--{name.replace('_', '-')})")
            if not self._set_param(fmu, "sample_period", h):
                self._set_param(fmu, "sample_rate_hz", rate_hz)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            vr_in = [self.vars["raw_rate"].valueReference]
            vr_rs = [self.vars["restart"].valueReference]
            vr_out = [self.vars["filtered_rate"].valueReference]
            tracking = bool(self.filter_kw.get("bias_tracking")) and "bias_hat" in self.vars
            if tracking:              # the output bias_hat read with the filtered rate
                vr_out = vr_out + [self.vars["bias_hat"].valueReference]
            out = np.empty((n, len(vr_out)))
            set_real, set_bool, get_real, do_step = fmu.setReal, fmu.setBoolean, fmu.getReal, fmu.doStep
            xs, rs = x.tolist(), r.tolist()
            for i in range(n):
                set_real(vr_in, [xs[i]])
                set_bool(vr_rs, [rs[i]])
                do_step(currentCommunicationPoint=i * h, communicationStepSize=h)
                out[i] = get_real(vr_out)
            fmu.terminate()
        finally:
            fmu.freeInstance()
        return out[:, 0].copy(), out[:, 1].copy() if tracking else None

    def close(self):
        shutil.rmtree(self._tmp, ignore_errors=True)


def make_engine(name, method=DEFAULT_METHOD, ar_order=3, fmu_path=None, warmup_s=None, filter_kw=None,
                zero_phase=False, offline=False):
    """``filter_kw``: further core filter parameters (e.g. outlier_sigma, outlier_run,
    cutoff_hz, order), passed to the Denoiser or set as FMU parameters of the same
    names (``order``: ``lowpass_order``). ``zero_phase``: the native low-pass
    forwards and backwards (offline files). ``offline``: the native motion filter's
    offline form (files); the FMU engine ignores it: it is causal (``engine.causal``)."""
    if name == "native":
        return NativeEngine(method, ar_order, warmup_s, filter_kw, zero_phase, offline)
    if name == "fmu":
        return FmuEngine(method, ar_order, fmu_path, warmup_s, filter_kw, zero_phase)
    raise InputError(f"--engine: unknown engine {name!r} (choose from {', '.join(ENGINES)})")
