"""FogDenoiser: the gyrodenoise filter as an FMI 2.0 co-simulation slave (pythonfmu).

One communication step is one gyro sample: set ``raw_rate`` (and ``restart``),
call fmi2DoStep, read ``filtered_rate`` and the AR model readouts.

The numerical work is the per-sample plain-Python path of the gyrodenoise core
(``gyrodenoise.core.kernels`` through ``gyrodenoise.denoiser.Denoiser``), bundled into
the FMU's resources as the package ``gdcore`` and imported from there under a
private module name, so the FMU neither needs nor picks up an installed
gyrodenoise, numba or scipy. Build it with ``gyrodenoise fmu build``.
"""

import math
import os
import sys

from pythonfmu import Fmi2Causality, Fmi2Slave
from pythonfmu.enums import Fmi2Status

# FMI rules and pythonfmu work-arounds shared by the project's slaves, bundled next
# to this script (resources/ in the FMU; the staging folder at build time)
_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)
import gyrodenoise_pythonfmu_rules as _rules  # noqa: E402
#: the version of the bundled core (gyrodenoise/_version.py, written into gdcore/__init__.py by
#: gyrodenoise fmu build). Read once: pythonfmu executes this file again at every fmi2Instantiate
#: with this module's dict as globals, whose __file__ may name an unzip folder since deleted
_VERSION = globals().get("_VERSION") or _rules.bundled_version(_HERE)
#: the objects the rules keep alive, referenced from this module too: pythonfmu keeps
#: this module's dict to the end (see the bottom of the file), whereas the rules
#: module is cleared with sys.modules at interpreter finalisation
_REFUSED = _rules.REFUSED

#: relative tolerance between the step size and the sample period
STEP_RTOL = 1e-6
#: a step shorter than this fraction of the sample period is no sample: the sliver a master that
#: accumulates its time (t += h) leaves before its stop time; answered OK, outputs unchanged
SLIVER_RTOL = 1e-6
#: format of the FMU state: parameters (the 1-euro filter's included), inputs, output and the
#: core's state; a state of another version is refused (4: the 1-euro filter's parameters, the
#: core's parameter buffer with the sample rate; 5: bias tracking's parameters and state)
STATE_VERSION = 5



class FogDenoiser(Fmi2Slave):
    """Online improved AR(n) model + modified Sage-Husa adaptive Kalman filter."""

    author = "gyrodenoise"
    description = ("Gyro denoiser (online improved AR(n) + KF / modified Sage-Husa AKF, "
                   "Sun et al. 2016). One communication step = one sample.")
    license = "MIT"
    version = _VERSION

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # first the exit-crash work-around, so that a refusal below still ends the host cleanly
        _rules.finalize_before_static_destructors(self.resources, type(self).__name__)
        # runs on Python 3.10 and without numpy (the plain-Python kernels where the bundled
        # C core does not load); anything else missing is a logged refusal, fmi2Instantiate NULL
        self._K, self._M, self._D, variables = _rules.load_core_or_refuse(
            "FogDenoiser", self.resources, "core.kernels", "core.methods", "denoiser", "fmu.variables")

        self._den = None          # the core's Denoiser, built at initialisation
        self._theta0 = 0          # offset of phi_1 in the state buffer
        self._n = 0
        self._n_steps = 0         # samples processed
        self._n_bad_steps = 0     # steps whose size disagreed with sample_period
        self._n_slivers = 0       # steps shorter than SLIVER_RTOL of the period (no sample)
        self._failed = None       # reason why stepping is refused, if any
        self._initialised = False  # fixed parameters are frozen from fmi2ExitInitializationMode on
        self._terminated = False
        self._pending_error = None  # a forbidden call since the last step: the next step is refused

        # the variables (inputs, parameters at their defaults, outputs) as declared in
        # gyrodenoise/fmu/variables.py; the readouts of the filter's state have getters
        getters = {f"phi_{k}": self._phi_getter(k) for k in range(1, variables.MAX_AR_ORDER + 1)}
        getters.update(c=self._get_c, R_hat=self._state_getter("S_R"), Q_hat=self._state_getter("S_Q"),
                       innovation=self._state_getter("S_INNOV"), converged=self._get_converged,
                       n_rejected=self._get_n_rejected, filtered_rate=self._get_filtered_rate,
                       bias_hat=self._get_bias_hat)
        self.filtered_rate = 0.0   # the output of the last step (the first output before the first step)
        self._max_order = variables.MAX_AR_ORDER   # phi_1 .. phi_max declared; phi_k, k > ar_order, reads 0
        self._parameter_names = _rules.register_declared(self, variables, variables.FOG_DENOISER, getters)
        # FMI 2.0 forbids setting an output, and a fixed parameter after initialisation
        _rules.install_write_rules(self, "FogDenoiser", Fmi2Causality.output, Fmi2Causality.parameter,
                                   Fmi2Status.error)

    # ----------------------------------------------------------- readouts
    def _phi_getter(self, k):
        def get():
            if self._den is None or k > self._n:
                return 0.0
            return self._den.state[self._theta0 + k - 1]
        return get

    def _get_c(self):
        return 0.0 if self._den is None else self._K.rls_c(self._den.params, self._den.state)

    def _state_getter(self, name):
        idx = getattr(self._K, name)

        def get():
            return 0.0 if self._den is None else self._den.state[idx]
        return get

    def _get_filtered_rate(self):
        # in initialisation mode: the first output for the inputs and parameters set so far, so that
        # a master that propagates values in initialisation mode (OMSimulator) passes it on
        if getattr(self, "_in_init", False):
            first = self._first_output()
            if first is not None:
                return first
        return self.filtered_rate

    def _first_output(self):
        """The first step's filtered_rate for the inputs and parameters set so far, from a scratch
        filter (None if the parameters cannot build one: fmi2ExitInitializationMode says why)."""
        kept = self._den, self._n, self._theta0
        try:
            self._make_denoiser()
            return float(self._den.step(self.raw_rate, self.restart))
        except Exception:
            return None
        finally:
            self._den, self._n, self._theta0 = kept

    def _get_n_rejected(self):
        return 0 if self._den is None else self._den.n_rejected

    def _get_bias_hat(self):
        return 0.0 if self._den is None else self._den.bias_hat

    def _get_converged(self):
        return self._den is not None and self._den.converged

    # ---------------------------------------------------------- lifecycle
    def _make_denoiser(self):
        """Build the core's Denoiser from the parameters; ValueError if invalid. Every
        parameter is checked against its range whatever the method (the registry's,
        gdcore/core/methods.py, as the native FMUs check it); 0 stands for a default
        computed from the sample rate (cutoff_hz)."""
        M = self._M
        if not (self.sample_period > 0 and math.isfinite(self.sample_period)):
            raise ValueError(f"sample_period must be a finite number > 0 s, got {self.sample_period!r}")
        fs = 1.0 / self.sample_period
        for p in M.fmu_parameters():
            why = p.fmu_error(getattr(self, p.fmu), fs)
            if why is not None:
                raise ValueError(why)
        method = str(self.method).strip().lower()
        M.method(method)
        kw = {p.name: getattr(self, p.fmu) for p in M.fmu_parameters() if p.applies_to(method)}
        kw.update({p.name: None for p in M.fmu_parameters() if p.name in kw and p.default is None and not kw[p.name]})
        self._den = self._D.Denoiser(sample_rate_hz=fs, method=method, **kw)
        self._n = self.ar_order
        self._theta0 = self._K.layout(self.ar_order)[0]

    def exit_initialization_mode(self):
        first = self._first_output()   # the output until the first step
        try:
            self._make_denoiser()
        except ValueError as exc:
            msg = f"FogDenoiser: invalid parameter: {exc}"
            self._failed = msg
            self.log(msg, Fmi2Status.error)
            # pythonfmu turns the exception into fmi2Fatal from fmi2ExitInitializationMode
            # (the guard keeps the instance's objects alive, see gyrodenoise_pythonfmu_rules)
            raise ValueError(msg) from None
        self.filtered_rate = first
        self._failed = None
        self._initialised = True
        if self._D.core_name() == "C":
            self.log("FogDenoiser: filter runs on the bundled C core", Fmi2Status.ok)
        else:
            self.log("FogDenoiser: the bundled C core does not fit this platform "
                     f"({self._D.core_fallback_reason()}); falling back to the plain-Python kernels "
                     "(same numbers, ~100x slower per step)", Fmi2Status.warning)

    def do_step(self, current_time, step_size):
        if self._terminated:
            self.log("FogDenoiser: fmi2DoStep after fmi2Terminate refused", Fmi2Status.error)
            return False
        if self._pending_error is not None:
            msg, self._pending_error = self._pending_error, None
            self.log(f"{msg}; this step is refused", Fmi2Status.error)
            return False
        if self._den is None:
            self.log(self._failed or "FogDenoiser: fmi2DoStep before initialisation", Fmi2Status.error)
            return False
        z = self.raw_rate
        if not math.isfinite(current_time):
            self.log(f"FogDenoiser: currentCommunicationPoint {current_time!r} s is not finite; step refused",
                     Fmi2Status.error)
            return False
        if not (step_size > 0.0 and math.isfinite(step_size)):
            # FMI 2.0: the communication step size must be > 0 (and a NaN would pass the
            # size test below and be processed as a sample)
            self.log(f"FogDenoiser: communication step size {step_size!r} s at t={current_time!r} s "
                     f"is not a positive finite number; step refused", Fmi2Status.error)
            return False
        if step_size < SLIVER_RTOL * self.sample_period:
            return self._sliver(current_time, step_size, self.sample_period)
        if abs(step_size - self.sample_period) > STEP_RTOL * self.sample_period:
            self._n_bad_steps += 1
            if self.strict_step_size:
                self.log(f"FogDenoiser: step size {step_size!r} s at t={current_time!r} s differs from "
                         f"sample_period {self.sample_period!r} s; step refused (strict_step_size)",
                         Fmi2Status.error)
                return False
            if self._n_bad_steps == 1 or self._n_bad_steps % 100000 == 0:
                self.log(f"FogDenoiser: step size {step_size!r} s at t={current_time!r} s differs from "
                         f"sample_period {self.sample_period!r} s; one step = one sample, so the filter's "
                         f"time base is wrong ({self._n_bad_steps} such step(s) so far)", Fmi2Status.warning)
        den = self._den
        saved = den.state[:]
        try:
            self.filtered_rate = den.step(z, self.restart)
        except Exception as exc:  # keep the instance usable: restore the state
            den.state = saved
            self.log(f"FogDenoiser: step at t={current_time!r} s failed: {type(exc).__name__}: {exc}",
                     Fmi2Status.error)
            return False
        self._n_steps += 1
        if not math.isfinite(z):
            # a dropout: processed as gd.denoise and Denoiser.step process it (the core heals
            # a non-finite state by restarting the filter); the run goes on. pythonfmu 0.7.0's
            # fmi2DoStep answers only fmi2OK or fmi2Discard: the warning is the log's status
            self.log(f"FogDenoiser: raw_rate is {z!r} at t={current_time!r} s: a dropout, processed "
                     f"as gd.denoise processes it (a non-finite filter state restarts the filter, which "
                     f"passes the raw samples through while it warms up again; "
                     f"{int(den.state[self._K.S_NHEAL])} such restart(s) so far); filtered_rate = "
                     f"{self.filtered_rate!r}; the run goes on", Fmi2Status.warning)
        return True

    def _sliver(self, current_time, step_size, period):
        """A step below SLIVER_RTOL of the period: no sample, the outputs stay as they are."""
        self._n_slivers += 1
        self.log(f"FogDenoiser: step size {step_size!r} s at t={current_time!r} s is below {SLIVER_RTOL} of "
                 f"sample_period {period!r} s: no sample (a master's accumulated time), outputs unchanged",
                 Fmi2Status.ok)
        return True

    def terminate(self):
        self._terminated = True
        if self._n_slivers:
            self.log(f"FogDenoiser: {self._n_slivers} step(s) shorter than {SLIVER_RTOL} of the sample period took "
                     f"no sample (a master's accumulated time)", Fmi2Status.ok)
        if self._n_bad_steps:
            self.log(f"FogDenoiser: {self._n_bad_steps} step(s) had a step size "
                     f"different from sample_period {self.sample_period!r} s ({self._n_steps} sample(s) taken)",
                     Fmi2Status.warning)

    # -------------------------------------------------------------- state
    def _get_fmu_state(self):
        """Everything needed to continue: parameters, inputs, output and the filter's arrays."""
        return {
            "version": STATE_VERSION,
            "params": {name: getattr(self, name) for name in self._parameter_names},
            "raw_rate": self.raw_rate, "restart": self.restart,
            "filtered_rate": self.filtered_rate,
            "filter": None if self._den is None else self._den.get_state(),
            "n_steps": self._n_steps, "n_bad_steps": self._n_bad_steps,
        }

    def _set_fmu_state(self, state):
        # all or nothing: a state that cannot be applied is refused, the instance unchanged
        _rules.set_state_or_refuse(self, "FogDenoiser", state, self._apply_state, Fmi2Status.error)

    def _apply_state(self, state):
        if state.get("version") != STATE_VERSION:
            raise ValueError(f"state version {state.get('version')!r}, expected {STATE_VERSION}")
        for name in self._parameter_names:
            setattr(self, name, state["params"][name])
        self.raw_rate = float(state["raw_rate"])
        self.restart = bool(state["restart"])
        self.filtered_rate = float(state["filtered_rate"])
        self._n_steps = int(state["n_steps"])
        self._n_bad_steps = int(state["n_bad_steps"])
        if state["filter"] is None:
            self._den = None
        else:
            self._make_denoiser()
            self._den.set_state(state["filter"])
        self._failed = None
        self._initialised = self._den is not None

    @staticmethod
    def _fmu_state_to_bytes(state):
        # pythonfmu's JSON with a checksum (see gyrodenoise_pythonfmu_rules.state_to_bytes)
        return _rules.state_to_bytes(state)

    @staticmethod
    def _fmu_state_from_bytes(state):
        # a corrupted or truncated state (checksum, JSON) becomes a marker: fmi2SetFMUstate
        # with it is refused with the reason (see gyrodenoise_pythonfmu_rules)
        return _rules.state_from_bytes(Fmi2Slave._fmu_state_from_bytes, state)


_rules.install_sequence_rules(FogDenoiser, "FogDenoiser", Fmi2Status.error)
_rules.guard(FogDenoiser, "FogDenoiser", Fmi2Status.error)


if locals() is not globals():
    # pythonfmu's exporter (findClass in PySlaveInstance.cpp) executes this file a second
    # time at every fmi2Instantiate, with the module's dict as globals and a new dict as
    # locals, and then Py_DECREFs the module dict, which PyModule_GetDict lent it (a
    # borrowed reference): one reference too many per instantiation, and a double free
    # of the dict at interpreter finalisation. One reference is added back here for each
    # such execution (the dict lives until the interpreter ends anyway).
    globals().setdefault("_PYTHONFMU_MODULE_DICT_REFS", []).append(globals())
