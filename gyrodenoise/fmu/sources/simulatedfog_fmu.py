"""SimulatedFog: the gyrodenoise model-card gyro as an FMI 2.0 co-simulation slave (pythonfmu).

One communication step is one sample. The sample at the start time is taken at
fmi2ExitInitializationMode from the inputs set before it (``measured_rate`` and
``restarted`` are ``initial="calculated"``: a Jacobi master passes sample 0 to the next FMU
at the first step, not a placeholder); each fmi2DoStep takes the sample at the end of the
step from the inputs set before it: set ``true_rate`` (and ``restart``), call fmi2DoStep,
read ``measured_rate``. Sample k (``gyrodenoise.simulate``'s k-th) is the output at
t = k h, as in SimulatedFogNative.fmu. The sensor errors come from the core's
simulator (``gyrodenoise.simulator.SimStream`` over ``gdsim.c``), bundled into the FMU's
resources as the package ``gdcore`` with the C core extension built for the building
Python (its plain-Python twin ``core/simkernels.py`` where that extension does not load,
same numbers), so for the same card and seed the FMU, SimulatedFogNative.fmu and
``gyrodenoise.simulate`` give the same numbers. Needs numpy on the host (scipy,
numba and an installed gyrodenoise are not needed). Build it with
``gyrodenoise fmu build``.
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

#: relative tolerance between the step size and the card's sample period
STEP_RTOL = 1e-6
#: a step shorter than this fraction of the sample period is no sample: the sliver a master that
#: accumulates its time (t += h) leaves before its stop time; answered OK, outputs unchanged
SLIVER_RTOL = 1e-6
#: format of the FMU state: parameters, inputs, outputs and the state buffer of gdsim.c; a
#: state of another version is refused
STATE_VERSION = 2



class SimulatedFog(Fmi2Slave):
    """A gyro described by a model card: measured = true rate + simulated sensor errors."""

    author = "gyrodenoise"
    description = ("Simulated gyro from a gyrodenoise model card (TOML): measured_rate = true_rate + "
                   "sensor errors. One communication step = one sample.")
    license = "MIT"
    version = _VERSION

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # first the exit-crash work-around, so that a refusal below still ends the host cleanly
        _rules.finalize_before_static_destructors(self.resources, type(self).__name__)
        # the model cards are TOML (tomllib: Python 3.11) and the simulator needs numpy: a host
        # Python without them is a logged refusal (fmi2Instantiate returns NULL), not a crash
        _rules.check_host("SimulatedFog", (3, 11), ("numpy",))
        self._S, variables = _rules.load_core_or_refuse("SimulatedFog", self.resources, "simulator",
                                                        "fmu.variables")

        self._sim = None
        self._period = None
        self._n_steps = 0
        self._n_bad_steps = 0
        self._n_slivers = 0         # steps shorter than SLIVER_RTOL of the period (no sample)
        self._failed = None         # reason why stepping is refused, if any
        self._initialised = False   # fixed parameters are frozen from fmi2ExitInitializationMode on
        self._terminated = False
        self._pending_error = None  # a forbidden call since the last step: the next step is refused

        # the variables (inputs, parameters at their defaults, outputs) as declared in
        # gyrodenoise/fmu/variables.py
        self.measured_rate, self.restarted = 0.0, False   # until fmi2ExitInitializationMode takes sample 0
        self._parameter_names = _rules.register_declared(
            self, variables, variables.SIMULATED_FOG,
            {"measured_rate": lambda: self._output("measured_rate"), "restarted": lambda: self._output("restarted")})
        # FMI 2.0 forbids setting an output, and a fixed parameter after
        # initialisation. pythonfmu would set them silently and cannot return
        # fmi2Error from a setter: the write is refused with a logged error and
        # the next fmi2DoStep is refused (fmi2Discard) with the reason.
        _rules.install_write_rules(self, "SimulatedFog", Fmi2Causality.output, Fmi2Causality.parameter,
                                   Fmi2Status.error)

    # ----------------------------------------------------------- readouts
    def _output(self, name):
        """An output; in initialisation mode sample 0's for the inputs and parameters set so far (from a
        scratch stream), so that a master that propagates values in initialisation mode (OMSimulator)
        passes sample 0 on."""
        if getattr(self, "_in_init", False):
            first = self._first_sample()
            if first is not None:
                return first[name]
        return getattr(self, name)

    def _first_sample(self):
        """{"measured_rate", "restarted"} of sample 0 for the inputs and parameters set so far, or None
        (a non-finite true rate, invalid parameters: fmi2ExitInitializationMode says why)."""
        kept = self._sim, self._period
        try:
            w = float(self.true_rate)
            if not math.isfinite(w):
                return None
            self._make_stream()
            restart = bool(self.restart)
            return {"measured_rate": float(self._sim.step(w, restart)), "restarted": restart}
        except Exception:
            return None
        finally:
            self._sim, self._period = kept

    # ---------------------------------------------------------- lifecycle
    def _make_stream(self):
        """Parse the card and build the core's SimStream; ValueError (InputError) if invalid."""
        if isinstance(self.seed, bool) or int(self.seed) < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        text = str(self.card)
        if "\n" in text or "[" in text:
            card = self._S.parse_card(text, source="parameter card")
        else:
            card = self._S.load_card(self._card_path(text.strip()))
        self._sim = self._S.SimStream(card, seed=int(self.seed))
        self._period = 1.0 / card.sample_rate_hz

    def _card_path(self, name):
        """A card file path, or a bundled card's name resolved in *this* instance's resources.

        The bundled core is imported once per process (same contents, same module), so its
        ``models_dir()`` is the folder of the first unzipped copy, which the host may have
        deleted since: a bundled card is looked up in this instance's own resources.
        """
        if os.path.exists(name):
            return name
        base = os.path.basename(name)
        bundled = os.path.join(self.resources, "gdcore", "data",
                               base if base.endswith(".toml") else base + ".toml")
        return bundled if os.path.isfile(bundled) else name

    def exit_initialization_mode(self):
        try:
            w = self.true_rate
            if not math.isfinite(w):
                raise ValueError(f"true_rate is {w!r}: the first sample (taken at fmi2ExitInitializationMode) "
                                 f"needs a finite true rate")
            self._make_stream()
        except ValueError as exc:
            msg = f"SimulatedFog: invalid parameter: {exc}"
            self._failed = msg
            self.log(msg, Fmi2Status.error)
            # pythonfmu turns the exception into fmi2Fatal from fmi2ExitInitializationMode
            # (the guard below keeps the instance's objects alive)
            raise ValueError(msg) from None
        # the sample at the start time, from the inputs set during initialisation: measured_rate
        # is valid from here on (a Jacobi master passes it on before the first step), and each
        # step produces the sample at its end
        restart = bool(self.restart)
        self.measured_rate = self._sim.step(w, restart)
        self.restarted = restart
        self._failed = None
        self._initialised = True
        if self._sim.compiled:
            self.log("SimulatedFog: sensor model runs on the bundled C core (gdsim.c)", Fmi2Status.ok)
        else:
            self.log("SimulatedFog: the bundled C core does not load on this platform; the sensor model "
                     "runs on its plain-Python twin (same numbers, ~160x slower per sample on paper_fog)",
                     Fmi2Status.ok)

    def do_step(self, current_time, step_size):
        if self._terminated:
            self.log("SimulatedFog: fmi2DoStep after fmi2Terminate refused", Fmi2Status.error)
            return False
        if self._pending_error is not None:
            msg, self._pending_error = self._pending_error, None
            self.log(f"{msg}; this step is refused", Fmi2Status.error)
            return False
        sim = self._sim
        if sim is None:
            self.log(self._failed or "SimulatedFog: fmi2DoStep before initialisation", Fmi2Status.error)
            return False
        period = self._period
        if not math.isfinite(current_time):
            self.log(f"SimulatedFog: currentCommunicationPoint {current_time!r} s is not finite; step refused",
                     Fmi2Status.error)
            return False
        if not (step_size > 0.0 and math.isfinite(step_size)):
            # FMI 2.0: the communication step size must be > 0 (and a NaN would pass the
            # size test below and be processed as a sample)
            self.log(f"SimulatedFog: communication step size {step_size!r} s at t={current_time!r} s "
                     f"is not a positive finite number; step refused", Fmi2Status.error)
            return False
        if step_size < SLIVER_RTOL * period:
            return self._sliver(current_time, step_size, period)
        if abs(step_size - period) > STEP_RTOL * period:
            self._n_bad_steps += 1
            if self.strict_step_size:
                self.log(f"SimulatedFog: step size {step_size!r} s at t={current_time!r} s differs from the "
                         f"card's sample period {period!r} s; step refused (strict_step_size)",
                         Fmi2Status.error)
                return False
            if self._n_bad_steps == 1 or self._n_bad_steps % 100000 == 0:
                self.log(f"SimulatedFog: step size {step_size!r} s at t={current_time!r} s differs from the "
                         f"card's sample period {period!r} s; one step = one sample, so the simulated time "
                         f"base is wrong ({self._n_bad_steps} such step(s) so far)", Fmi2Status.warning)
        w = self.true_rate
        if not math.isfinite(w):
            self.log(f"SimulatedFog: true_rate is {w!r} at t={current_time!r} s; sample refused",
                     Fmi2Status.error)
            return False
        restart = bool(self.restart)
        try:
            self.measured_rate = sim.step(w, restart)
        except Exception as exc:
            self.log(f"SimulatedFog: step at t={current_time!r} s failed: {type(exc).__name__}: {exc}",
                     Fmi2Status.error)
            return False
        self.restarted = restart
        self._n_steps += 1
        return True

    def _sliver(self, current_time, step_size, period):
        """A step below SLIVER_RTOL of the period: no sample, the outputs stay as they are."""
        self._n_slivers += 1
        self.log(f"SimulatedFog: step size {step_size!r} s at t={current_time!r} s is below {SLIVER_RTOL} of "
                 f"the card's sample period {period!r} s: no sample (a master's accumulated time), outputs unchanged",
                 Fmi2Status.ok)
        return True

    def terminate(self):
        self._terminated = True
        if self._n_slivers:
            self.log(f"SimulatedFog: {self._n_slivers} step(s) shorter than {SLIVER_RTOL} of the sample period took "
                     f"no sample (a master's accumulated time)", Fmi2Status.ok)
        if self._n_bad_steps:
            self.log(f"SimulatedFog: {self._n_bad_steps} step(s) had a step size "
                     f"different from the card's sample period {self._period!r} s ({self._n_steps} sample(s) taken)",
                     Fmi2Status.warning)

    # -------------------------------------------------------------- state
    def _get_fmu_state(self):
        """Parameters, inputs, outputs and the simulator's generator state and buffers."""
        return {
            "version": STATE_VERSION,
            "params": {name: getattr(self, name) for name in self._parameter_names},
            "true_rate": self.true_rate, "restart": self.restart,
            "measured_rate": self.measured_rate, "restarted": self.restarted,
            "sim": None if self._sim is None else self._sim.get_state(),
            "n_steps": self._n_steps, "n_bad_steps": self._n_bad_steps,
        }

    def _set_fmu_state(self, state):
        # all or nothing: a state that cannot be applied is refused, the instance unchanged
        _rules.set_state_or_refuse(self, "SimulatedFog", state, self._apply_state, Fmi2Status.error)

    def _apply_state(self, state):
        if state.get("version") != STATE_VERSION:
            raise ValueError(f"state version {state.get('version')!r}, expected {STATE_VERSION}")
        for name in self._parameter_names:
            setattr(self, name, state["params"][name])
        self.true_rate = float(state["true_rate"])
        self.restart = bool(state["restart"])
        self.measured_rate = float(state["measured_rate"])
        self.restarted = bool(state["restarted"])
        self._n_steps = int(state["n_steps"])
        self._n_bad_steps = int(state["n_bad_steps"])
        if state["sim"] is None:
            self._sim = None
        else:
            self._make_stream()
            self._sim.set_state(state["sim"])
        self._failed = None
        self._initialised = self._sim is not None

    @staticmethod
    def _fmu_state_to_bytes(state):
        # pythonfmu's JSON with a checksum (see gyrodenoise_pythonfmu_rules.state_to_bytes)
        return _rules.state_to_bytes(state)

    @staticmethod
    def _fmu_state_from_bytes(state):
        # a corrupted or truncated state (checksum, JSON) becomes a marker: fmi2SetFMUstate
        # with it is refused with the reason (see gyrodenoise_pythonfmu_rules)
        return _rules.state_from_bytes(Fmi2Slave._fmu_state_from_bytes, state)


_rules.install_sequence_rules(SimulatedFog, "SimulatedFog", Fmi2Status.error)
_rules.guard(SimulatedFog, "SimulatedFog", Fmi2Status.error)


if locals() is not globals():
    # pythonfmu's exporter (findClass in PySlaveInstance.cpp) executes this file a second
    # time at every fmi2Instantiate, with the module's dict as globals and a new dict as
    # locals, and then Py_DECREFs the module dict, which PyModule_GetDict lent it (a
    # borrowed reference). Each instantiation thus takes one reference too many from the
    # dict; when the garbage collector of Py_FinalizeEx (the exporter's worker thread, at
    # process exit) frees the dict's users, the dict is freed twice: heap corruption, a
    # host crash at exit in a fraction of the runs. One reference is added back here for
    # each such execution (the dict lives until the interpreter ends anyway).
    globals().setdefault("_PYTHONFMU_MODULE_DICT_REFS", []).append(globals())
