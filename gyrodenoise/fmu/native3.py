"""The FMI 3.0 native FMUs: FogDenoiserNative3, SimulatedFogNative3 and FogDenoiserImuNative3.

Co-Simulation FMUs built from the same C core and the same FMI layer as the FMI 2.0 ones
(``sources/native/gdfmi.c``: the state machine, written once; ``gdfmi3.c``: the fmi3* entry
points over it), from the same variable declarations (:mod:`gyrodenoise.fmu.variables`):
same names, units, parameters and value references; FMI 3.0 types (Real is Float64, Integer
Int32). FogDenoiserImuNative3 is the denoiser for a whole IMU: ``raw_rate`` and
``filtered_rate`` are arrays of three values (``<Dimension start="3"/>``).

:func:`model_description3` writes their ``modelDescription.xml``; the build is
:func:`gyrodenoise.fmu.native.build_native_fmu` (binaries under the FMI 3.0 platform tuples of
:data:`FMI3_PLATFORM_FOLDERS`), :func:`build_native_fmus` builds them with the FMI 2.0 ones.

>>> from gyrodenoise.fmu.native3 import fmi3_platform_folder
>>> fmi3_platform_folder("linux64")
'x86_64-linux'
"""

from __future__ import annotations

import re
from xml.sax.saxutils import quoteattr

from gyrodenoise._version import __version__
from gyrodenoise.errors import InputError
from gyrodenoise.fmu.native import DENOISER, LOG_CATEGORIES, NATIVE_MODELS, build_native_fmu
from gyrodenoise.fmu.simnative import SIMULATED_FOG_NATIVE
from gyrodenoise.fmu.variables import FMI3_TYPES, FOG_DENOISER_IMU, UNITS, format_value, initial

#: build platform (a key of gyrodenoise.fmu.native.PLATFORMS) -> FMI 3.0 binaries folder
#: (the standard's <arch>-<os> platform tuple); one mapping for every platform
FMI3_PLATFORM_FOLDERS = {
    "linux64": "x86_64-linux",
    "win64": "x86_64-windows",
    "darwin64": "x86_64-darwin",
    "aarch64-linux": "aarch64-linux",
    "linux-aarch64": "aarch64-linux",
    "linuxarm64": "aarch64-linux",
    "aarch64-darwin": "aarch64-darwin",
    "darwin-aarch64": "aarch64-darwin",
    "darwinarm64": "aarch64-darwin",
}
_TUPLE = re.compile(r"(x86_64|aarch64|x86|i686)-(linux|windows|darwin)")


def fmi3_platform_folder(plat):
    """The FMI 3.0 binaries folder (platform tuple) of build platform ``plat``; InputError if none."""
    if plat in FMI3_PLATFORM_FOLDERS:
        return FMI3_PLATFORM_FOLDERS[plat]
    if _TUPLE.fullmatch(plat):
        return plat
    raise InputError(f"platform {plat!r}: no FMI 3.0 platform tuple known for it (add it to "
                     "gyrodenoise.fmu.native3.FMI3_PLATFORM_FOLDERS)")


def _variable(vr, v):
    type_ = FMI3_TYPES[v.type]
    attrs = [f'name="{v.name}"', f'valueReference="{vr}"', f'description={quoteattr(v.description)}',
             f'causality="{v.causality}"']
    if v.variability:
        attrs.append(f'variability="{v.variability}"')
    if v.causality == "output":
        attrs.append(f'initial="{initial(v, pythonfmu=False)}"')
    children = []
    if v.start is not None:
        if type_ == "String":
            children.append(f'<Start value={quoteattr(str(v.start))}/>')
        else:
            attrs.append("start=" + quoteattr(" ".join([format_value(v.start, v.type)] * v.size)))
    if v.unit:
        attrs.append(f'unit="{v.unit}"')
    for key in ("min", "max"):
        if getattr(v, key) is not None:
            attrs.append(f'{key}="{format_value(getattr(v, key), v.type)}"')
    if v.size > 1:
        children.append(f'<Dimension start="{v.size}"/>')
    if not children:
        return [f'    <{type_} {" ".join(attrs)}/>']
    return [f'    <{type_} {" ".join(attrs)}>', *(f"      {c}" for c in children), f'    </{type_}>']


def model_description3(token, spec):
    """modelDescription.xml (text, FMI 3.0 Co-Simulation) of ``spec`` with instantiation token ``token``."""
    cats = [(n, d.replace("fmi2", "fmi3")) for n, d in LOG_CATEGORIES]
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<fmiModelDescription fmiVersion="3.0" modelName="{spec.name}" instantiationToken="{token}" '
           f'description={quoteattr(spec.description)} author="gyrodenoise" version="{__version__}" license="MIT" '
           'generationTool="gyrodenoise.fmu.native3" variableNamingConvention="flat">',
           f'  <CoSimulation modelIdentifier="{spec.name}" needsExecutionTool="false" '
           'canBeInstantiatedOnlyOncePerProcess="false" canGetAndSetFMUState="true" '
           'canSerializeFMUState="true" providesDirectionalDerivatives="false" '
           'providesAdjointDerivatives="false" providesPerElementDependencies="false" '
           'canHandleVariableCommunicationStepSize="false" '
           f'fixedInternalStepSize="{spec.step_size!r}" maxOutputDerivativeOrder="0" '
           'providesIntermediateUpdate="false" mightReturnEarlyFromDoStep="false" '
           'canReturnEarlyAfterIntermediateUpdate="false" hasEventMode="false" '
           'providesEvaluateDiscreteStates="false"/>',
           '  <UnitDefinitions>']
    for unit, base in {**spec.units, "s": UNITS["s"]}.items():   # s: the unit of time
        attrs = " ".join(f'{k}="{v}"' for k, v in base.items())
        out += [f'    <Unit name="{unit}">', f'      <BaseUnit {attrs}/>', '    </Unit>']
    out += ['  </UnitDefinitions>', '  <LogCategories>']
    out += [f'    <Category name="{n}" description={quoteattr(d)}/>' for n, d in cats]
    out += ['  </LogCategories>',
            f'  <DefaultExperiment startTime="0.0" stepSize="{spec.step_size!r}"/>',
            '  <ModelVariables>']
    for vr, v in enumerate(spec.variables):
        out += _variable(vr, v)
    # the independent variable (FMI 3.0 requires one), after the model's variables so that
    # theirs keep the value references of the FMI 2.0 FMUs
    out += [f'    <Float64 name="time" valueReference="{len(spec.variables)}" causality="independent" '
            'variability="continuous" description="Simulation time" unit="s"/>']
    out += ['  </ModelVariables>', '  <ModelStructure>']
    out += [f'    <Output valueReference="{vr}"/>' for vr, v in enumerate(spec.variables)
            if v.causality == "output"]
    out += [f'    <InitialUnknown valueReference="{vr}"/>' for vr, v in enumerate(spec.variables)
            if initial(v, pythonfmu=False) == "calculated"]
    out += ['  </ModelStructure>', '</fmiModelDescription>', '']
    return "\n".join(out)


#: FogDenoiserNative3.fmu: FogDenoiserNative, FMI 3.0
DENOISER3 = DENOISER.replace(
    name="FogDenoiserNative3", unity="fogdenoiser_native3_all.c", fmi_version=3,
    xml_writer=model_description3, binary_folder=fmi3_platform_folder,
    extra_sources=DENOISER.extra_sources + (DENOISER.unity,),
    description=DENOISER.description.replace("native C:", "native C, FMI 3.0:"))
#: SimulatedFogNative3.fmu: SimulatedFogNative, FMI 3.0
SENSOR3 = SIMULATED_FOG_NATIVE.replace(
    name="SimulatedFogNative3", unity="simulatedfog_native3_all.c", fmi_version=3,
    xml_writer=model_description3, binary_folder=fmi3_platform_folder,
    extra_sources=SIMULATED_FOG_NATIVE.extra_sources + (SIMULATED_FOG_NATIVE.unity,),
    description=SIMULATED_FOG_NATIVE.description.replace("native C:", "native C, FMI 3.0:"))
#: FogDenoiserImuNative3.fmu: the 3-axis denoiser (FMI 3.0 only)
IMU3 = DENOISER.replace(
    name="FogDenoiserImuNative3", variables=FOG_DENOISER_IMU, c_source="fogdenoiser_imu_native.c",
    unity="fogdenoiser_imu_native3_all.c", fmi_version=3,
    xml_writer=model_description3, binary_folder=fmi3_platform_folder,
    description="Gyro denoiser for a whole IMU (three gyro axes, three independent filters: filtered_rate[j] "
                "= gd.denoise of axis j), native C, FMI 3.0: no Python needed. One communication step = "
                "one sample.")
#: every FMI 3.0 native FMU
NATIVE3_MODELS = (DENOISER3, SENSOR3, IMU3)


def build_native_fmus(out_dir="build", platforms=None, report=None, fmi_versions=(2, 3)):
    """Build every native FMU of ``fmi_versions`` (2: :data:`gyrodenoise.fmu.native.NATIVE_MODELS`,
    3: :data:`NATIVE3_MODELS`) into ``out_dir``; returns {name: path}. ``platforms`` and ``report``
    as for :func:`gyrodenoise.fmu.native.build_native_fmu` (the same compilers serve all)."""
    models = (NATIVE_MODELS if 2 in fmi_versions else ()) + (NATIVE3_MODELS if 3 in fmi_versions else ())
    return {spec.name: build_native_fmu(out_dir, platforms, report, spec) for spec in models}
