"""FMI rules and pythonfmu 0.7.0 work-arounds shared by the project's pythonfmu slaves.

``gyrodenoise fmu build`` bundles this file next to each slave script (the FMU's
``resources/``); the slaves import it from there. Nothing here is maths.

* :func:`install_write_rules`: FMI 2.0 forbids setting an output, and a fixed
  parameter after initialisation. pythonfmu would set them silently and cannot
  return fmi2Error from a setter: the write is refused with a logged error, the
  value kept, and the slave refuses its next fmi2DoStep with the reason (the
  slave checks ``_pending_error``).
* :func:`install_sequence_rules`: fmi2EnterInitializationMode twice,
  fmi2ExitInitializationMode outside initialisation mode, fmi2SetupExperiment
  after it, a second fmi2Terminate, are refused the same way; :func:`install_write_rules` also refuses every write after fmi2Terminate.
* :func:`guard`: pythonfmu answers an exception with fmi2Fatal and releases its
  references to the instance, its log queue and the class
  (``PySlaveInstance::handle_py_exception`` -> ``cleanPyObject``, pointers not
  cleared), then releases them again in fmi2FreeInstance / fmi2Reset: the next
  call after a fatal one used freed memory (a host crash). Every method pythonfmu
  calls is wrapped so that the objects are kept alive (:data:`REFUSED`) before
  any exception reaches it, and unknown value references get a logged reason.
* :func:`finalize_before_static_destructors`: the exporter's exit crash (its static
  interpreter state is released twice at process exit; Linux).
* :func:`load_core`: imports the gyrodenoise core bundled in ``resources/gdcore``
  under a private name.
* :func:`register_declared`: registers a slave's variables from their declaration
  (``gyrodenoise/fmu/variables.py``, bundled in ``resources/gdcore/fmu``).
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import importlib
import importlib.util
import json
import os
import sys

#: Objects of instances that failed with an exception, kept alive on purpose (a
#: few bytes leaked per failure) so that pythonfmu's second release frees nothing live.
REFUSED = []

#: FMU libraries (path: handle) whose interpreter finalisation is hooked to exit().
_EXIT_HOOKS = {}


def bundled_version(here):
    """The version of gyrodenoise whose core is bundled beside the slave script in ``here``
    (``gdcore/__init__.py``'s ``__version__``, written from gyrodenoise/_version.py by
    ``gyrodenoise fmu build``: the one place of the version)."""
    with open(os.path.join(here, "gdcore", "__init__.py"), encoding="utf-8") as fh:
        for line in fh:
            if line.startswith("__version__ = "):
                return line.split("=", 1)[1].strip().strip("\"'")
    raise RuntimeError(f"{here}/gdcore/__init__.py names no __version__")


def load_core(resources, *modules):
    """Import the gyrodenoise core bundled in ``resources/gdcore``; its ``modules``.

    The package gets a private name derived from its contents (the built C core
    extension included), so an installed ``gyrodenoise`` (or another build of an
    FMU) in the same process is never used instead, and identical copies are
    imported only once.
    """
    pkg_dir = os.path.join(resources, "gdcore")
    digest = hashlib.sha1()
    for root, dirs, files in os.walk(pkg_dir):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith((".py", ".so", ".pyd")):
                path = os.path.join(root, name)
                with open(path, "rb") as fh:
                    digest.update(os.path.relpath(path, pkg_dir).encode() + b"\0" + fh.read())
    modname = "_gdcore_" + digest.hexdigest()[:16]
    if modname not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            modname, os.path.join(pkg_dir, "__init__.py"),
            submodule_search_locations=[pkg_dir])
        module = importlib.util.module_from_spec(spec)
        sys.modules[modname] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[modname]
            raise
    return tuple(importlib.import_module(modname + "." + m) for m in modules)


def register_declared(slave, variables, declared, getters=None):
    """Give ``slave`` the variables ``declared`` (a tuple of ``variables.Variable``, in
    value-reference order; ``variables`` is the bundled declaration module) and return the
    names of its parameters.

    Inputs and parameters start at their declared start values, outputs without a getter
    (``getters``: {name: function () -> value}) at the value they declare in a pythonfmu
    FMU (0 or false for one declared ``initial="calculated"``); pythonfmu writes each
    attribute's value as the variable's start where the variable has one.
    """
    from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Variability, Integer, Real, String
    kinds = {"Real": Real, "Integer": Integer, "Boolean": Boolean, "String": String}
    getters = getters or {}
    for v in declared:
        if v.name not in getters:
            # an output declared initial="calculated" has no start: it reads 0 (false) until
            # fmi2ExitInitializationMode computes it
            start = variables.start_value(v, pythonfmu=True)
            setattr(slave, v.name, variables.ZERO[v.type] if start is None else start)
    for v in declared:
        kw = {"causality": Fmi2Causality[v.causality], "description": variables.pythonfmu_description(v)}
        if v.variability is not None:
            kw["variability"] = Fmi2Variability[v.variability]
        if v.causality == "output":
            kw["initial"] = Fmi2Initial[variables.initial(v, pythonfmu=True)]
        if v.name in getters:
            kw["getter"] = getters[v.name]
        slave.register_variable(kinds[v.type](v.name, **kw))
    return tuple(v.name for v in declared if v.causality == "parameter")


def keep_alive(slave):
    """Called just before an exception reaches pythonfmu (see :data:`REFUSED`)."""
    REFUSED.append((slave, slave.log_queue, type(slave)))


def install_write_rules(slave, label, output_causality, parameter_causality, error_status):
    """Refuse writes to outputs, and to parameters once ``slave._initialised`` is
    true, with a logged error; the slave's next step reports ``slave._pending_error``."""
    def refuse(msg):
        slave.log(msg, error_status)
        slave._pending_error = msg

    def rule(name, kind, original):
        # one setter per variable (inputs are set every step: one call, no chain)
        def setter(value):
            if slave._terminated:
                # no step follows fmi2Terminate (each is refused): the log is the answer
                slave.log(f"{label}: fmi2Set of {name!r} after fmi2Terminate refused (only fmi2Get*, "
                          f"fmi2Reset and fmi2FreeInstance are allowed then); value unchanged", error_status)
            elif kind == "output":
                refuse(f"{label}: fmi2Set of {name!r} refused (it is an output); value unchanged")
            elif kind == "parameter" and slave._initialised:
                refuse(f"{label}: fmi2Set of fixed parameter {name!r} after initialisation refused "
                       f"(fixed parameters change only before fmi2ExitInitializationMode; fmi2Reset to "
                       f"change it); kept at {getattr(slave, name)!r}")
            elif original is None:
                setattr(slave, name, value)
            else:
                original(value)
        return setter

    for var in slave.vars.values():
        kind = ("output" if var.causality == output_causality else
                "parameter" if var.causality == parameter_causality else None)
        if kind is not None or var.setter is not None:
            var.setter = rule(var.name, kind, var.setter)


def install_sequence_rules(cls, label, error_status):
    """The FMI 2.0 call sequence around initialisation, on slave class ``cls``:
    fmi2SetupExperiment only before, fmi2EnterInitializationMode once after
    fmi2Instantiate (or fmi2Reset, which makes a new slave object),
    fmi2ExitInitializationMode only in initialisation mode, fmi2Terminate once. pythonfmu answers fmi2OK to any call that returns (and fmi2Fatal to an
    exception): an out-of-sequence call does nothing, logs an error, and the next
    fmi2DoStep is refused (fmi2Discard) with the reason. Uses the slave's
    ``_initialised``, ``_terminated`` and ``_pending_error``; adds ``_in_init``."""
    enter, leave = cls.enter_initialization_mode, cls.exit_initialization_mode
    setup, term = cls.setup_experiment, cls.terminate

    def refuse(self, msg):
        self.log(msg, error_status)
        self._pending_error = msg

    @functools.wraps(enter)
    def enter_initialization_mode(self):
        why = ("after fmi2Terminate" if self._terminated else
               "already in initialisation mode" if getattr(self, "_in_init", False) else
               "the instance is already initialised" if self._initialised else None)
        if why:
            return refuse(self, f"{label}: fmi2EnterInitializationMode refused: {why} (it is allowed once, "
                                f"after fmi2Instantiate or fmi2Reset)")
        self._in_init = True
        return enter(self)

    @functools.wraps(leave)
    def exit_initialization_mode(self):
        if not getattr(self, "_in_init", False):
            return refuse(self, f"{label}: fmi2ExitInitializationMode refused: not in initialisation mode "
                                f"(call fmi2EnterInitializationMode first)")
        result = leave(self)
        self._in_init = False
        return result

    @functools.wraps(setup)
    def setup_experiment(self, *args):
        if self._terminated or getattr(self, "_in_init", False) or self._initialised:
            return refuse(self, f"{label}: fmi2SetupExperiment refused: only allowed before "
                                f"fmi2EnterInitializationMode")
        return setup(self, *args)

    @functools.wraps(term)
    def terminate(self):
        if self._terminated:   # nothing follows that a pending error could refuse
            return self.log(f"{label}: fmi2Terminate refused: already terminated", error_status)
        return term(self)

    cls.enter_initialization_mode = enter_initialization_mode
    cls.exit_initialization_mode = exit_initialization_mode
    cls.setup_experiment = setup_experiment
    cls.terminate = terminate


def guard(cls, label, error_status):
    """Wrap the methods of slave class ``cls`` that pythonfmu calls (see the module)."""
    def wrap(name, refs=None):
        method = getattr(cls, name)

        @functools.wraps(method)
        def guarded(self, *args):
            try:
                return method(self, *args)
            except BaseException:
                keep_alive(self)
                # the reason for the usual failure of a get/set, looked for only once it
                # failed (a check before every call cost ~10 % of an FMU step)
                unknown = [] if refs is None else [vr for vr in args[0] if vr not in self.vars]
                if not unknown:
                    raise
                msg = f"{label}: {refs}: unknown value reference(s) {unknown} (this FMU has {sorted(self.vars)})"
                self.log(msg, error_status)
                raise KeyError(msg) from None
        setattr(cls, name, guarded)

    for kind in ("integer", "real", "boolean", "string"):
        wrap(f"get_{kind}", f"fmi2Get{kind.capitalize()}")
        wrap(f"set_{kind}", f"fmi2Set{kind.capitalize()}")
    for name in ("setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step",
                 "terminate", "_get_fmu_state", "_set_fmu_state"):
        wrap(name)


#: the key of the checksum in a serialized FMU state (a JSON object)
STATE_CHECKSUM_KEY = "sha256"


def _state_digest(state):
    """SHA-256 of the state's canonical JSON (sorted keys; floats as repr, NaN as NaN)."""
    return hashlib.sha256(json.dumps(state, sort_keys=True).encode("utf-8")).hexdigest()


def state_to_bytes(state):
    """A state as pythonfmu serializes it (one JSON object, the fields at the top level)
    with the SHA-256 of its canonical form added, so that a flipped byte that still
    parses (a digit of a number) is found on reading, as a truncation is."""
    if STATE_CHECKSUM_KEY in state:
        raise ValueError(f"a state field is named {STATE_CHECKSUM_KEY!r}")
    return json.dumps({**state, STATE_CHECKSUM_KEY: _state_digest(state)}).encode("utf-8")


def state_from_bytes(base, state):
    """``base(state)`` (pythonfmu's deserialiser) checked against the checksum that
    :func:`state_to_bytes` wrote, or a marker dict ``{"corrupted": reason}`` instead of
    an exception: pythonfmu calls it on the class, where an exception would be fmi2Fatal
    with no instance to keep alive. fmi2SetFMUstate with the marker is refused."""
    try:
        value = base(state)
        if not isinstance(value, dict):
            raise ValueError(f"not a state object: {type(value).__name__}")
        digest = value.pop(STATE_CHECKSUM_KEY, None)
        if digest is None:
            raise ValueError(f"no {STATE_CHECKSUM_KEY} checksum (not written by this FMU)")
        if digest != _state_digest(value):
            raise ValueError(f"{STATE_CHECKSUM_KEY} checksum mismatch: the bytes were changed")
        return value
    except Exception as exc:  # noqa: BLE001 - any corruption becomes the marker
        return {"corrupted": f"corrupted serialized FMU state ({len(state)} bytes; {type(exc).__name__}: {exc})"}


def set_state_or_refuse(slave, label, state, apply, error_status):
    """fmi2SetFMUstate: ``apply(state)`` (the slave's own), all or nothing. A state that
    cannot be applied (the marker of :func:`state_from_bytes`, another version, a missing
    or wrong field) leaves the instance as it was (its own state applied again), the
    reason is logged, and ValueError is raised: pythonfmu 0.7.0 answers fmi2SetFMUstate
    only with fmi2OK (returned) or fmi2Fatal (raised), so the refusal is fmi2Fatal, the
    instance kept alive and usable (:func:`guard`)."""
    before = slave._get_fmu_state()
    failed, pending = slave._failed, slave._pending_error
    try:
        if not isinstance(state, dict):
            raise ValueError(f"not a state object: {type(state).__name__}")
        if state.get("corrupted"):
            raise ValueError(state["corrupted"])
        apply(state)
    except Exception as exc:  # noqa: BLE001 - every reason refuses the state
        apply(before)
        slave._failed, slave._pending_error = failed, pending
        msg = f"{label}: fmi2SetFMUstate refused: {type(exc).__name__}: {exc}; the instance is unchanged"
        slave.log(msg, error_status)
        raise ValueError(msg) from None


def check_host(label, min_python=(3, 11), modules=()):
    """Refuse to start, with a reason pythonfmu logs (fmi2Instantiate returns NULL), where
    the host's Python cannot run this FMU: older than ``min_python``, or one of
    ``modules`` not importable (numpy)."""
    where = f"the host's Python is {sys.version.split()[0]} ({sys.prefix})"
    if sys.version_info < min_python:
        raise RuntimeError(f"{label}: needs Python >= {'.'.join(map(str, min_python))} with numpy in the "
                           f"host's environment; {where} (see docs/cosim/requirements.md)")
    for name in modules:
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise RuntimeError(f"{label}: needs {name} in the host's Python environment; {where}: "
                               f"{type(exc).__name__}: {exc} (see docs/cosim/requirements.md)") from None


def load_core_or_refuse(label, resources, *modules):
    """:func:`load_core`, an ImportError turned into a one-line reason naming the host's Python."""
    try:
        return load_core(resources, *modules)
    except ImportError as exc:
        raise RuntimeError(f"{label}: the bundled gyrodenoise core does not import in the host's Python "
                           f"{sys.version.split()[0]} ({sys.prefix}): {type(exc).__name__}: {exc} "
                           f"(see docs/cosim/requirements.md)") from None


def finalize_before_static_destructors(resources, model_identifier):
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
