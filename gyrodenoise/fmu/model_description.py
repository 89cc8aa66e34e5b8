"""Complete the modelDescription.xml that pythonfmu writes (issue 14).

pythonfmu cannot declare units, a DefaultExperiment or min/max. The slave
scripts state each variable's unit at the end of its description, in
brackets (``[deg/s]``); :func:`complete` turns that into a ``unit`` attribute
with its ``UnitDefinitions`` entry, adds the DefaultExperiment (the step size
the FMU expects) and the bounds of the bounded parameters, in the element
order the FMI 2.0 schema requires, and rewrites the FMU in place.
"""

from __future__ import annotations

import math
import re
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

DEG = math.pi / 180.0
#: unit as written in a description -> (FMI unit name, BaseUnit attributes)
UNITS = {
    "deg/s": ("deg/s", {"rad": "1", "s": "-1", "factor": repr(DEG)}),
    "(deg/s)^2": ("deg2/s2", {"rad": "2", "s": "-2", "factor": repr(DEG * DEG)}),
    "s": ("s", {"s": "1"}),
    "Hz": ("Hz", {"s": "-1"}),
}

#: FMI 2.0 ``min``/``max`` are inclusive: a parameter that must be > 0 declares the smallest
#: positive normal double (sys.float_info.min), one that must be < 1 the largest double below 1
POSITIVE_MIN = sys.float_info.min
BELOW_ONE = 1.0 - sys.float_info.epsilon / 2.0

#: per FMU: default communication step size (s) and {parameter: (min, max)}
SPECS = {
    "FogDenoiser": (0.005, {
        "ar_order": (1, 6), "sample_period": (POSITIVE_MIN, None), "lam": (POSITIVE_MIN, 1.0),
        "b": (POSITIVE_MIN, BELOW_ONE), "gamma": (1.0, None), "q0": (0.0, None), "r0": (0.0, None),
        "p0_rls": (POSITIVE_MIN, None), "p0_kf": (POSITIVE_MIN, None), "warmup_s": (0.0, None),
        "r_floor": (POSITIVE_MIN, None),
        "outlier_sigma": (0.0, None), "outlier_run": (1, None), "cutoff_hz": (0.0, None),
        "lowpass_order": (1, 8), "max_motion_hz": (0.0, None)}),
    "SimulatedFog": (0.005, {"seed": (0, None)}),
}

_UNIT_RE = re.compile(r"\[([^\[\]]+)\]\s*$")
# FMI 2.0 order of the children of fmiModelDescription
_ORDER = ["ModelExchange", "CoSimulation", "UnitDefinitions", "TypeDefinitions", "LogCategories",
          "DefaultExperiment", "VendorAnnotations", "ModelVariables", "ModelStructure"]


def complete_xml(xml_text, name):
    """Return ``xml_text`` with units, UnitDefinitions, DefaultExperiment and
    min/max added for the FMU called ``name`` (a key of :data:`SPECS`)."""
    step_s, bounds = SPECS[name]
    root = ET.fromstring(xml_text)
    used = {}
    for sv in root.iter("ScalarVariable"):
        real = sv.find("Real")
        m = _UNIT_RE.search(sv.get("description", ""))
        if real is not None and m and m.group(1) in UNITS:
            unit, base = UNITS[m.group(1)]
            real.set("unit", unit)
            used[unit] = base
        lim = bounds.get(sv.get("name"))
        if lim is not None:
            typed = next(iter(sv))
            for attr, v in zip(("min", "max"), lim):
                if v is not None:
                    typed.set(attr, repr(float(v)) if typed.tag == "Real" else str(int(v)))
    for old in root.findall("UnitDefinitions") + root.findall("DefaultExperiment"):
        root.remove(old)
    if used:
        ud = ET.Element("UnitDefinitions")
        for unit, base in sorted(used.items()):
            u = ET.SubElement(ud, "Unit", {"name": unit})
            ET.SubElement(u, "BaseUnit", base)
        root.append(ud)
    root.append(ET.Element("DefaultExperiment", {"startTime": "0.0", "stepSize": repr(step_s)}))
    children = sorted(list(root), key=lambda e: _ORDER.index(e.tag) if e.tag in _ORDER else len(_ORDER))
    for e in list(root):
        root.remove(e)
    root.extend(children)
    ET.indent(root, space="\t")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def complete(fmu_path):
    """Rewrite ``fmu_path``'s modelDescription.xml with :func:`complete_xml`."""
    fmu_path = Path(fmu_path)
    name = fmu_path.stem
    with tempfile.TemporaryDirectory() as tmp:
        new = Path(tmp) / fmu_path.name
        with zipfile.ZipFile(fmu_path) as src, zipfile.ZipFile(new, "w", zipfile.ZIP_DEFLATED) as dst:
            for item in src.infolist():
                data = src.read(item)
                if item.filename == "modelDescription.xml":
                    data = complete_xml(data.decode("utf-8"), name).encode("utf-8")
                dst.writestr(item, data)
        shutil.move(str(new), fmu_path)
    return fmu_path
