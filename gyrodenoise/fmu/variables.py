"""The FMUs' variables, declared once per model.

Each model's variables are a tuple of :class:`Variable`, in value-reference order
(value reference = position). Both kinds of FMU are built from these tuples:

* the pythonfmu slaves (``sources/fogdenoiser_fmu.py``, ``sources/simulatedfog_fmu.py``)
  register their variables from them, and :mod:`gyrodenoise.fmu.model_description`
  adds the units and bounds pythonfmu cannot declare;
* the native FMUs' ``modelDescription.xml`` and C header are generated from them
  (:mod:`gyrodenoise.fmu.native`, :mod:`gyrodenoise.fmu.native3`).

How the two kinds differ, by rule rather than by a second declaration: a pythonfmu
slave declares every output ``initial="exact"`` with its value before the first step
(0 or false) as start, and appends the unit to each description in brackets
(``[deg/s]``, ``[1]`` for a number without unit, ``[-]`` for a string); a native FMU
declares an output ``initial="exact"`` with its ``start`` where the declaration gives
one, else ``initial="calculated"``. An output declared ``initial="calculated"`` (the
sensor's ``measured_rate`` and ``restarted``: its sample at the start time is taken at
fmi2ExitInitializationMode) is ``calculated``, without a start value, in both kinds.

The filter's parameters (type, start, range, unit, description) are declared once, in the
method registry :mod:`gyrodenoise.core.methods`; this module imports nothing else from
gyrodenoise: ``gyrodenoise fmu build`` bundles the two into the pythonfmu FMUs
(``resources/gdcore/fmu/variables.py``, ``resources/gdcore/core/methods.py``).

>>> from gyrodenoise.fmu.variables import FOG_DENOISER
>>> [v.name for v in FOG_DENOISER][:3]
['raw_rate', 'restart', 'filtered_rate']
"""

from __future__ import annotations

import math
import sys
from typing import NamedTuple

from ..core import methods  # noqa: TID252 - relative: the FMUs bundle the two as package gdcore

#: phi_1 .. phi_MAX_AR_ORDER are declared; phi_k for k > ar_order reads 0
MAX_AR_ORDER = methods.FMU_MAX_AR_ORDER
#: DefaultExperiment stepSize of every FMU, s (200 Hz: the default sample_period and paper_fog's rate)
DEFAULT_STEP_SIZE_S = 0.005

#: FMI 2.0 ``min``/``max`` are inclusive: a parameter that must be > 0 declares the smallest
#: positive normal double (sys.float_info.min), one that must be < 1 the largest double below 1
POSITIVE_MIN = methods.POSITIVE_MIN
BELOW_ONE = 1.0 - sys.float_info.epsilon / 2.0

DEG = math.pi / 180.0
#: FMI unit name -> BaseUnit attributes (SI: rad, s), in UnitDefinitions order
UNITS = {
    "deg/s": {"rad": "1", "s": "-1", "factor": repr(DEG)},
    "deg2/s2": {"rad": "2", "s": "-2", "factor": repr(DEG * DEG)},
    "s": {"s": "1"},
    "Hz": {"s": "-1"},
    "deg/h": {"rad": "1", "s": "-1", "factor": repr(DEG / 3600.0)},
}
#: FMI unit name -> how a pythonfmu slave writes it at the end of a description
UNIT_LABELS = {"deg/s": "deg/s", "deg2/s2": "(deg/s)^2", "s": "s", "Hz": "Hz", "deg/h": "deg/h"}


class Variable(NamedTuple):
    """One FMI 2.0 scalar variable."""

    name: str
    type: str                     # "Real", "Integer", "Boolean" or "String"
    causality: str                # "input", "output" or "parameter"
    description: str
    variability: str | None = None   # None: the FMI default (continuous for Real)
    start: object = None
    unit: str | None = None       # a key of UNITS
    min: float | int | None = None
    max: float | int | None = None
    #: "calculated": an output computed at fmi2ExitInitializationMode, with no start value in
    #: either FMU kind; None: the kind's rule (see the module's docstring)
    initial: str | None = None
    #: values: 1 for a scalar; an array variable's length (FMI 3.0 only: ``<Dimension start="size"/>``)
    size: int = 1


def _input(name, type_, description, start, unit=None):
    return Variable(name, type_, "input", description, "discrete" if type_ == "Boolean" else None, start, unit)


def _output(name, type_, description, unit=None, start=None, initial=None):
    variability = None if type_ == "Real" else "discrete"
    return Variable(name, type_, "output", description, variability, start, unit, initial=initial)


def _parameter(name, type_, start, description, unit=None, min=None, max=None):
    return Variable(name, type_, "parameter", description, "fixed", start, unit, min, max)


METHOD_DOC = (f"Filter, one of: {methods.method_doc()}; case and surrounding blanks ignored; any other value "
              "is refused at fmi2ExitInitializationMode")


def _description(p):
    """An FMU parameter's description: the registry's help, the method it applies to, its range
    (checked whatever the method)."""
    where = f"method '{p.methods[0]}': " if p.methods else ""
    text = p.help[0].upper() + p.help[1:] if not where else p.help
    return f"{where}{text}; {p.fmu_rule()}"


def _registry_parameter(name):
    """The FMU parameter ``name`` as the registry declares it (gyrodenoise.core.methods)."""
    p = methods.BY_FMU[name]
    lo, hi = p.fmu_bounds()
    return _parameter(name, "Integer" if p.type is int else "Real", p.fmu_default(), _description(p), p.unit,
                      min=lo, max=hi)


def _registry_parameters(*names):
    return tuple(_registry_parameter(n) for n in names)


#: the output bias_hat (one an axis in the 3-axis FMUs), after "method 'motion', "
BIAS_HAT_DOC = ("bias_tracking = 1: the gyro bias removed from filtered_rate (estimated while still, less the "
                "Earth-rate floor on a navigation-grade record); 0 when off")

#: FogDenoiser.fmu and FogDenoiserNative.fmu: the order of the variables (= value references) is
#: kept from release to release, the parameters' declarations are the registry's
FOG_DENOISER = (
    _input("raw_rate", "Real", "Raw angular rate of the gyro", 0.0, "deg/s"),
    _input("restart", "Boolean", "True on the first sample after a gyro restart: the filter re-identifies "
           "the AR model from that sample on", False),
    _output("filtered_rate", "Real", "Filtered angular rate; the raw sample during the warm-up after each "
            "restart", "deg/s"),
    *(_output(f"phi_{k}", "Real", f"AR coefficient phi_{k} of the improved AR(n) model, Eq. (4) (0 when {k} > "
              "ar_order, and for the methods without an AR model: motion, lowpass, one_euro)")
      for k in range(1, MAX_AR_ORDER + 1)),
    _output("c", "Real", "Constant term c of the improved AR model, Eq. (4) (0 for the methods motion, "
            "lowpass and one_euro)", "deg/s"),
    _output("R_hat", "Real", "Estimated measurement-noise variance (motion: the sensor's white-noise "
            "estimate)", "deg2/s2"),
    _output("Q_hat", "Real", "Estimated process-noise variance (motion: of the rate increment per sample)",
            "deg2/s2"),
    _output("innovation", "Real", "Last innovation v_k = z_k - H X_pred", "deg/s"),
    _output("converged", "Boolean", "True once the AR model has converged since the last restart (the "
            "output is filtered from then on)"),
    _registry_parameter("ar_order"),
    _parameter("method", "String", methods.DEFAULT_METHOD, METHOD_DOC),
    _parameter("sample_period", "Real", DEFAULT_STEP_SIZE_S, "Sample period, > 0; every communication step "
               "must have this size", "s", min=POSITIVE_MIN),
    *_registry_parameters("lam", "b", "gamma", "q0", "r0", "p0_rls", "p0_kf", "warmup_s", "r_floor",
                          "outlier_sigma", "outlier_run", "cutoff_hz", "lowpass_order"),
    _output("n_rejected", "Integer", "Samples kept out of the filter by the outlier gate since "
            "initialisation"),
    _parameter("strict_step_size", "Boolean", False, "If true, a step whose size differs from sample_period "
               "is refused (fmi2Discard); if false it is processed and a warning is logged"),
    *_registry_parameters("max_motion_hz", "min_cutoff_hz", "beta", "d_cutoff_hz"),
    *_registry_parameters("bias_tracking", "bias_still_s", "bias_memory_s", "earth_rate_floor_deg_h"),
    _output("bias_hat", "Real", f"method 'motion', {BIAS_HAT_DOC}", "deg/s"),
)
assert {v.name for v in FOG_DENOISER} >= set(methods.BY_FMU), "an FMU parameter of the registry is not declared"

#: FogDenoiserImuNative3.fmu (FMI 3.0 only): the denoiser for a whole IMU, three gyro axes with
#: independent filter states; raw_rate and filtered_rate are arrays of IMU_AXES values, one
#: restart for the three axes, the parameters of FOG_DENOISER
IMU_AXES = 3
FOG_DENOISER_IMU = (
    _input("raw_rate", "Real", "Raw angular rates of the IMU's three gyro axes", 0.0, "deg/s")._replace(size=IMU_AXES),
    _input("restart", "Boolean", "True on the first sample after an IMU restart: the three filters re-identify "
           "their AR models from that sample on", False),
    _output("filtered_rate", "Real", "Filtered angular rates, one a gyro axis (gd.denoise of each axis); the raw "
            "samples during the warm-up after each restart", "deg/s")._replace(size=IMU_AXES),
    *(v for v in FOG_DENOISER if v.causality == "parameter"),
    _output("bias_hat", "Real", f"Method 'motion', one a gyro axis: {BIAS_HAT_DOC}", "deg/s")._replace(size=IMU_AXES),
)

#: the axes' suffixes of FOG_DENOISER_IMU_XYZ's scalar variables (axis j: IMU_AXIS_NAMES[j])
IMU_AXIS_NAMES = ("x", "y", "z")
#: FogDenoiserImuNative.fmu (FMI 2.0): FogDenoiserImuNative3 with one scalar variable an axis
#: (raw_rate_x, raw_rate_y, raw_rate_z; filtered_rate_x, ...) for hosts without FMI 3.0 arrays
#: (FMI 2.0 hosts; OMSimulator reads one value of an FMI 3.0 array)
FOG_DENOISER_IMU_XYZ = (
    *(_input(f"raw_rate_{a}", "Real", f"Raw angular rate of the IMU's {a} gyro axis", 0.0, "deg/s")
      for a in IMU_AXIS_NAMES),
    _input("restart", "Boolean", "True on the first sample after an IMU restart: the three filters re-identify "
           "their AR models from that sample on", False),
    *(_output(f"filtered_rate_{a}", "Real", f"Filtered angular rate of the {a} axis (gd.denoise of that axis); "
              "the raw sample during the warm-up after each restart", "deg/s") for a in IMU_AXIS_NAMES),
    *(v for v in FOG_DENOISER if v.causality == "parameter"),
    *(_output(f"bias_hat_{a}", "Real", f"Method 'motion', the {a} axis: {BIAS_HAT_DOC}", "deg/s")
      for a in IMU_AXIS_NAMES),
)

#: SimulatedFog.fmu (pythonfmu): the card parameter takes a TOML card
SIMULATED_FOG = (
    _input("true_rate", "Real", "True angular rate", 0.0, "deg/s"),
    _input("restart", "Boolean", "True on the first sample after a gyro restart (fresh turn-on bias draw, "
           "turn-on transient restarts)", False),
    # the sample at the start time is taken at fmi2ExitInitializationMode (initial="calculated",
    # both kinds): a Jacobi master passes sample 0 to the denoiser at the first step
    _output("measured_rate", "Real", "Measured angular rate: true_rate + sensor errors; the sample at the "
            "start time from fmi2ExitInitializationMode on (from the inputs set before it), then the sample "
            "at the end of each step (from the inputs set before the step)", "deg/s", initial="calculated"),
    _output("restarted", "Boolean", "The restart input of the sample in measured_rate; connect it to the "
            "denoiser's restart", initial="calculated"),
    _parameter("card", "String", "paper_fog", "Model card: its TOML text (gyrodenoise spec section 4; term "
               "units as there: deg, deg/sqrt(h), deg/h, deg/h^1.5, deg/h^2, s, Hz), or a card file path, or "
               "the name of a card bundled in the FMU ('paper_fog', the paper's FOG, default)"),
    _parameter("seed", "Integer", 0, "Seed of the noise generator (same seed, same card: same numbers as "
               "gyrodenoise.simulate)", min=0),
    _parameter("strict_step_size", "Boolean", False, "If true, a step whose size differs from the card's "
               "sample period is refused (fmi2Discard); if false it is processed and a warning is logged"),
)

_NATIVE_CHANGES = {
    "card": {"description": "Model card: the name of a card bundled in the FMU (resources/cards: paper_fog, "
                            "the paper's FOG, default), a compiled card file's path, or a compiled card's "
                            "text ('gdcard 1 ...': gyrodenoise fmu card CARD.toml, its fields one a line or "
                            "on one line separated by '|'; a TOML card is refused at "
                            "fmi2ExitInitializationMode with this reason)"},
}

#: SimulatedFogNative.fmu: SimulatedFog's variables; its card parameter takes a compiled card
SIMULATED_FOG_NATIVE = tuple(v._replace(**_NATIVE_CHANGES.get(v.name, {})) for v in SIMULATED_FOG)

#: FMU model name -> its variables
MODELS = {
    "FogDenoiser": FOG_DENOISER,
    "FogDenoiserNative": FOG_DENOISER,
    "SimulatedFog": SIMULATED_FOG,
    "SimulatedFogNative": SIMULATED_FOG_NATIVE,
    "FogDenoiserImuNative": FOG_DENOISER_IMU_XYZ,
}
#: FMI 3.0 FMU model name -> its variables (all native; Real is Float64, Integer Int32 there)
FMI3_MODELS = {
    "FogDenoiserNative3": FOG_DENOISER,
    "SimulatedFogNative3": SIMULATED_FOG_NATIVE,
    "FogDenoiserImuNative3": FOG_DENOISER_IMU,
}
#: FMI 2.0 type -> FMI 3.0 type of the same variable
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}
#: the FMUs built by pythonfmu (the others are native)
PYTHONFMU_MODELS = ("FogDenoiser", "SimulatedFog")

#: the value of an output of a type before it has one (a pythonfmu output's start; what an output
#: declared initial="calculated" reads before fmi2ExitInitializationMode)
ZERO = {"Real": 0.0, "Integer": 0, "Boolean": False, "String": ""}


def start_value(v: Variable, pythonfmu: bool) -> object:
    """The start value ``v`` declares in the FMU kind (pythonfmu or native), or None."""
    if v.initial == "calculated":
        return None
    if pythonfmu and v.causality == "output" and v.start is None:
        return ZERO[v.type]
    return v.start


def initial(v: Variable, pythonfmu: bool) -> str | None:
    """The ``initial`` attribute of output ``v`` in the FMU kind, or None for a non-output."""
    if v.causality != "output":
        return None
    if v.initial is not None:
        return v.initial
    return "exact" if start_value(v, pythonfmu) is not None else "calculated"


def pythonfmu_description(v: Variable) -> str:
    """The description a pythonfmu slave gives ``v``: with its unit in brackets."""
    label = UNIT_LABELS[v.unit] if v.unit else ("-" if v.type == "String" else "1")
    return f"{v.description} [{label}]"


def format_value(value: float | int | bool | str, type_: str) -> str:
    """``value`` as written in a modelDescription.xml attribute of a variable of ``type_``."""
    if type_ == "Real":
        return repr(float(value))
    if type_ == "Boolean":
        return "true" if value else "false"
    return str(value)


# ------------------------------------------------------------ Markdown
_COLUMNS = ("name", "causality", "type", "unit", "start", "min", "max", "description")


def _cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(model):
    pythonfmu = model in PYTHONFMU_MODELS
    fmi3 = model in FMI3_MODELS
    lines = ["| " + " | ".join(_COLUMNS) + " |", "|" + "---|" * len(_COLUMNS)]
    for v in (FMI3_MODELS if fmi3 else MODELS)[model]:
        start = start_value(v, pythonfmu)
        type_ = (FMI3_TYPES[v.type] + (f"[{v.size}]" if v.size > 1 else "")) if fmi3 else v.type
        cells = (f"`{v.name}`", v.causality, type_, v.unit or "",
                 "" if start is None else f"`{format_value(start, v.type)}`",
                 "" if v.min is None else format_value(v.min, v.type),
                 "" if v.max is None else format_value(v.max, v.type), v.description)
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return lines


def markdown_tables(fmi_version: int = 2) -> str:
    """Markdown tables of the FMUs' variables of ``fmi_version`` (2 or 3: FMI 3.0 types, an array's
    length in brackets), one per FMU (FMUs with identical tables share one), with the columns name,
    causality, type, unit, start, min, max and description. Value reference = row number - 1."""
    groups: dict[str, list[str]] = {}
    for model in (FMI3_MODELS if fmi_version == 3 else MODELS):
        groups.setdefault("\n".join(_table(model)), []).append(model)
    out = []
    for table, models in groups.items():
        out += ["### " + " and ".join(f"{m}.fmu" for m in models), "", table, ""]
    return "\n".join(out)
