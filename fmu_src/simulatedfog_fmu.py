"""SimulatedFog: the gyrodenoise model-card gyro as an FMI 2.0 co-simulation slave (pythonfmu).

One communication step is one sample: set ``true_rate`` (and ``restart``), call
fmi2DoStep, read ``measured_rate``. The sensor errors come from the core's
simulator (``gyrodenoise.simulator.SimStream``), bundled into the FMU's resources
as the package ``gdcore``, so for the same card and seed the FMU and
``gyrodenoise.simulate`` give the same numbers. Needs numpy on the host (scipy,
numba and an installed gyrodenoise are not needed). Build it with
``gyrodenoise fmu build``.
"""

import builtins
import ctypes
import functools
import hashlib
import importlib
import importlib.util
import math
import os
import sys

from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

DEFAULT_CARD = "paper_fog"
#: relative tolerance between the step size and the card's sample period
STEP_RTOL = 1e-6
STATE_VERSION = 1

#: Objects of instances that failed with an exception. pythonfmu answers an exception
#: with fmi2Fatal and releases its references to the instance, its log queue and the
#: class (PySlaveInstance::handle_py_exception -> cleanPyObject, pointers not cleared),
#: and releases them again in fmi2FreeInstance / fmi2Reset; these extra references keep
#: that from freeing live objects (a few bytes leaked per failure). Without them the
#: next call on the instance after such an fmi2Fatal uses freed memory (a host crash).
_REFUSED = []


def _import_without_scipy(name, globals=None, locals=None, fromlist=(), level=0):
    """``__import__`` of the bundled simulator: scipy is reported missing.

    The simulator then takes its plain-numpy path (same two operations per sample as
    scipy's lfilter, same numbers). With scipy imported, the interpreter's finalisation
    that pythonfmu's exporter runs at process exit (Py_FinalizeEx in its worker thread)
    frees a type still in use while tearing down scipy's ``_uarray`` module (valgrind:
    invalid read in dict_tp_clear of a block freed by _uarray's globals_free): a host
    crash at exit in a fraction of the runs. The host's own scipy is not affected.
    """
    if level == 0 and (name == "scipy" or name.startswith("scipy.")):
        raise ImportError(f"{name}: not used by the SimulatedFog FMU (see _import_without_scipy)")
    return builtins.__import__(name, globals, locals, fromlist, level)


_CORE_BUILTINS = dict(builtins.__dict__, __import__=_import_without_scipy)


def _load_core(resources):
    """Import the gyrodenoise core bundled in ``resources/gdcore``.

    The package gets a private name derived from its contents, so an installed
    ``gyrodenoise`` (or another build of this FMU) in the same process is never
    used instead, and identical copies are imported only once. Its modules see
    scipy as missing (:func:`_import_without_scipy`).
    """
    pkg_dir = os.path.join(resources, "gdcore")
    digest = hashlib.sha1()
    for name in sorted(os.listdir(pkg_dir)):
        if name.endswith(".py"):
            with open(os.path.join(pkg_dir, name), "rb") as fh:
                digest.update(name.encode() + b"\0" + fh.read())
    modname = "_gdcore_" + digest.hexdigest()[:16] + "_noscipy"
    for name, path, sub in ((modname, "__init__.py", [pkg_dir]),
                            (modname + ".errors", "errors.py", None),
                            (modname + ".simulator", "simulator.py", None)):
        if name in sys.modules:
            continue
        spec = importlib.util.spec_from_file_location(name, os.path.join(pkg_dir, path),
                                                      submodule_search_locations=sub)
        module = importlib.util.module_from_spec(spec)
        module.__dict__["__builtins__"] = _CORE_BUILTINS
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[name]
            raise
        if sub is None:
            setattr(sys.modules[modname], name.rpartition(".")[2], module)
    return sys.modules[modname + ".simulator"]


#: FMU libraries (path: handle) whose interpreter finalisation is hooked to exit().
_EXIT_HOOKS = {}


def _finalize_before_static_destructors(resources, model_identifier):
    """Work around pythonfmu's exit crash (Linux).

    pythonfmu's exporter keeps the interpreter in a static ``std::shared_ptr<PyState>``
    (PySlaveInstance.cpp) whose destructor, run by exit() as a C++ static destructor,
    finalises Python; its ``__attribute__((destructor)) onLibraryUnload`` then runs in
    _dl_fini and assigns nullptr to that already destroyed shared_ptr, releasing its
    freed control block once more (a write into freed heap memory: "free(): corrupted
    unsorted chunks" or a segfault later in exit). Registering the library's exported
    ``finalizePythonInterpreter`` with exit() from here makes it run first (exit
    handlers run last-registered first): the interpreter is finalised as before, the
    shared_ptr is left empty, and the two later calls have nothing to release. A
    reference to the library is kept so that a host's dlclose cannot unmap the handler.
    """
    if not sys.platform.startswith("linux"):
        return
    path = os.path.realpath(os.path.join(resources, os.pardir, "binaries", "linux64",
                                         model_identifier + ".so"))
    if path in _EXIT_HOOKS:
        return
    try:   # only if this very library is loaded in this process (not at build time)
        lib = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LOCAL)
        hook = ctypes.cast(lib.finalizePythonInterpreter, ctypes.c_void_p)
        cxa_atexit = ctypes.CDLL(None).__cxa_atexit
    except (OSError, AttributeError):
        return
    cxa_atexit.argtypes = (ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)
    cxa_atexit.restype = ctypes.c_int
    if cxa_atexit(hook, None, None) == 0:
        _EXIT_HOOKS[path] = lib


class SimulatedFog(Fmi2Slave):
    """A gyro described by a model card: measured = true rate + simulated sensor errors."""

    author = "gyrodenoise"
    description = ("Simulated gyro from a gyrodenoise model card (TOML): measured_rate = true_rate + "
                   "sensor errors. One communication step = one sample.")
    license = "MIT"
    version = "0.1.0"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._S = _load_core(self.resources)
        _finalize_before_static_destructors(self.resources, type(self).__name__)

        self.true_rate = 0.0
        self.restart = False
        self.card = DEFAULT_CARD
        self.seed = 0
        self.strict_step_size = False
        self.measured_rate = 0.0
        self.restarted = False

        self._sim = None
        self._period = None
        self._n_steps = 0
        self._n_bad_steps = 0
        self._failed = None         # reason why stepping is refused, if any
        self._initialised = False   # fixed parameters are frozen from fmi2ExitInitializationMode on
        self._terminated = False
        self._pending_error = None  # a forbidden call since the last step: the next step is refused

        P, C, I = Fmi2Causality, Fmi2Variability, Fmi2Initial
        par = dict(causality=P.parameter, variability=C.fixed)
        self.register_variable(Real("true_rate", causality=P.input, description="True angular rate [deg/s]"))
        self.register_variable(Boolean("restart", causality=P.input, variability=C.discrete,
                                       description="True on the first sample after a gyro restart (fresh "
                                                   "turn-on bias draw, turn-on transient restarts) [1]"))
        self.register_variable(Real("measured_rate", causality=P.output, initial=I.exact,
                                    description="Measured angular rate: true_rate + sensor errors [deg/s]"))
        self.register_variable(Boolean("restarted", causality=P.output, initial=I.exact, variability=C.discrete,
                                       description="The restart input of the step that produced measured_rate; "
                                                   "connect it to FogDenoiser.restart [1]"))
        self.register_variable(String("card", **par,
                                      description="Model card: its TOML text (gyrodenoise spec section 4; term "
                                                  "units as there: deg, deg/sqrt(h), deg/h, deg/h^1.5, deg/h^2, "
                                                  "s, Hz), or a card file path, or the name of a card bundled "
                                                  "in the FMU ('paper_fog', the paper's FOG, default) [-]"))
        self.register_variable(Integer("seed", **par, description="Seed of the noise generator (same seed, "
                                                                   "same card: same numbers as "
                                                                   "gyrodenoise.simulate) [1]"))
        self.register_variable(Boolean("strict_step_size", **par,
                                       description="If true, a step whose size differs from the card's sample "
                                                   "period is refused (fmi2Discard); if false it is processed "
                                                   "and a warning is logged [1]"))
        # FMI 2.0 forbids setting an output, and a fixed parameter after
        # initialisation. pythonfmu would set them silently and cannot return
        # fmi2Error from a setter: the write is refused with a logged error and
        # the next fmi2DoStep is refused (fmi2Discard) with the reason.
        for var in self.vars.values():
            if var.causality == P.output:
                var.setter = self._refusing_setter(var.name, "it is an output")
            elif var.causality == P.parameter:
                var.setter = self._fixed_setter(var.name, var.setter)

    # ------------------------------------------------- forbidden writes
    def _refuse(self, msg):
        self.log(msg, Fmi2Status.error)
        self._pending_error = msg

    def _refusing_setter(self, name, why):
        def refuse(value):
            self._refuse(f"SimulatedFog: fmi2Set of {name!r} refused ({why}); value unchanged")
        return refuse

    def _fixed_setter(self, name, setter):
        def set_fixed(value):
            if self._initialised:
                self._refuse(f"SimulatedFog: fmi2Set of fixed parameter {name!r} after initialisation "
                             f"refused (fixed parameters change only before fmi2ExitInitializationMode; "
                             f"fmi2Reset to change it); kept at {getattr(self, name)!r}")
            elif setter is None:
                setattr(self, name, value)
            else:
                setter(value)
        return set_fixed

    def _keep_alive(self):
        """Called just before an exception reaches pythonfmu (see :data:`_REFUSED`)."""
        _REFUSED.append((self, self.log_queue, type(self)))

    def _check_refs(self, call, vrs):
        """Unknown value references: a logged reason, then fmi2Fatal (pythonfmu's only
        failure status for fmi2Get*/fmi2Set*), without the use-after-free."""
        unknown = [vr for vr in vrs if vr not in self.vars]
        if unknown:
            msg = (f"SimulatedFog: {call}: unknown value reference(s) {unknown} "
                   f"(this FMU has {sorted(self.vars)})")
            self.log(msg, Fmi2Status.error)
            self._keep_alive()
            raise KeyError(msg)

    # ---------------------------------------------------------- lifecycle
    def _make_stream(self):
        """Parse the card and build the core's SimStream; ValueError (InputError) if invalid."""
        if isinstance(self.seed, bool) or int(self.seed) < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        text = str(self.card)
        if "\n" in text or "[" in text:
            card = self._S.parse_card(text, source="parameter card")
        else:
            card = self._S.load_card(text.strip())
        self._sim = self._S.SimStream(card, seed=int(self.seed))
        self._period = 1.0 / card.sample_rate_hz

    def exit_initialization_mode(self):
        try:
            self._make_stream()
        except ValueError as exc:
            msg = f"SimulatedFog: invalid parameter: {exc}"
            self._failed = msg
            self.log(msg, Fmi2Status.error)
            # pythonfmu turns the exception into fmi2Fatal from fmi2ExitInitializationMode
            # (the guard below keeps the instance's objects alive)
            raise ValueError(msg) from None
        self._failed = None
        self._initialised = True

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
        if not (step_size > 0.0 and math.isfinite(step_size)):
            # FMI 2.0: the communication step size must be > 0 (NaN used to pass the
            # size test below and be processed as a sample)
            self.log(f"SimulatedFog: communication step size {step_size!r} s at t={current_time!r} s "
                     f"is not a positive finite number; step refused", Fmi2Status.error)
            return False
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

    def terminate(self):
        self._terminated = True
        if self._n_bad_steps:
            self.log(f"SimulatedFog: {self._n_bad_steps} of {self._n_steps} step(s) had a step size "
                     f"different from the card's sample period {self._period!r} s", Fmi2Status.warning)

    # -------------------------------------------------------------- state
    _PARAMS = ("card", "seed", "strict_step_size")

    def _get_fmu_state(self):
        """Parameters, inputs, outputs and the simulator's generator state and buffers."""
        return {
            "version": STATE_VERSION,
            "params": {name: getattr(self, name) for name in self._PARAMS},
            "true_rate": self.true_rate, "restart": self.restart,
            "measured_rate": self.measured_rate, "restarted": self.restarted,
            "sim": None if self._sim is None else self._sim.get_state(),
            "n_steps": self._n_steps, "n_bad_steps": self._n_bad_steps,
        }

    def _set_fmu_state(self, state):
        try:
            if state.get("corrupted"):
                raise ValueError(state["corrupted"])
            if state.get("version") != STATE_VERSION:
                raise ValueError(f"state version {state.get('version')!r}, expected {STATE_VERSION}")
            for name in self._PARAMS:
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
        except Exception as exc:  # pythonfmu ignores a return value here: refuse the next steps
            self._sim = None
            self._failed = f"SimulatedFog: fmi2SetFMUstate failed: {type(exc).__name__}: {exc}"
            self.log(self._failed, Fmi2Status.error)

    @staticmethod
    def _fmu_state_from_bytes(state):
        # pythonfmu calls this on the class: an exception here would be fmi2Fatal and
        # release the calling instance's objects (see _REFUSED) though no instance is at
        # hand to keep them alive. A corrupted state becomes a marker instead:
        # fmi2SetFMUstate with it logs the reason and the next fmi2DoStep is refused.
        try:
            value = Fmi2Slave._fmu_state_from_bytes(state)
            if not isinstance(value, dict):
                raise ValueError(f"not a state object: {type(value).__name__}")
            return value
        except Exception as exc:
            return {"corrupted": f"corrupted serialized FMU state ({type(exc).__name__}: {exc})"}


def _guard(name, refs=None):
    """Wrap the slave method ``name`` that pythonfmu calls: check value references
    (argument 0) if ``refs`` names the FMI call, and keep the instance's objects
    alive before any exception reaches pythonfmu (see :data:`_REFUSED`)."""
    method = getattr(SimulatedFog, name)

    @functools.wraps(method)
    def guarded(self, *args):
        if refs is not None:
            self._check_refs(refs, args[0])
        try:
            return method(self, *args)
        except BaseException:
            self._keep_alive()
            raise
    setattr(SimulatedFog, name, guarded)


for _kind in ("integer", "real", "boolean", "string"):
    _guard(f"get_{_kind}", f"fmi2Get{_kind.capitalize()}")
    _guard(f"set_{_kind}", f"fmi2Set{_kind.capitalize()}")
for _name in ("setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step",
              "terminate", "_get_fmu_state", "_set_fmu_state"):
    _guard(_name)
del _kind, _name


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
