"""Complete the modelDescription.xml that pythonfmu writes.

pythonfmu cannot declare units, a DefaultExperiment or min/max, and declares every slave
able to handle a variable communication step size. :func:`complete` adds the first ones
from the FMU's variable declaration (:mod:`gyrodenoise.fmu.variables`): each Real's
``unit`` with its ``UnitDefinitions`` entry, the DefaultExperiment (the step size the FMU
expects), the bounds of the bounded parameters and the InitialUnknowns (the outputs
computed at fmi2ExitInitializationMode), in the element order the FMI 2.0
schema requires, declares ``canHandleVariableCommunicationStepSize="false"`` (one step is
one sample), and rewrites the FMU in place.
"""

from __future__ import annotations

import shutil
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from gyrodenoise.fmu.variables import DEFAULT_STEP_SIZE_S, MODELS, UNITS, format_value, initial

# FMI 2.0 order of the children of fmiModelDescription
_ORDER = ["ModelExchange", "CoSimulation", "UnitDefinitions", "TypeDefinitions", "LogCategories",
          "DefaultExperiment", "VendorAnnotations", "ModelVariables", "ModelStructure"]


def complete_xml(xml_text, name):
    """Return ``xml_text`` with units, UnitDefinitions, DefaultExperiment and
    min/max added for the FMU called ``name`` (a key of :data:`gyrodenoise.fmu.variables.MODELS`)."""
    declared = {v.name: v for v in MODELS[name]}
    root = ET.fromstring(xml_text)
    used = {}
    for sv in root.iter("ScalarVariable"):
        v = declared[sv.get("name")]
        typed = next(iter(sv))
        if v.unit:
            typed.set("unit", v.unit)
            used[v.unit] = UNITS[v.unit]
        for attr in ("min", "max"):
            if getattr(v, attr) is not None:
                typed.set(attr, format_value(getattr(v, attr), v.type))
    # FMI 2.0: the outputs computed at initialisation (initial="calculated") are listed as
    # InitialUnknowns (pythonfmu lists only the Outputs)
    calculated = [i for i, sv in enumerate(root.iter("ScalarVariable"), start=1)
                  if sv.get("initial") == "calculated"
                  and initial(declared[sv.get("name")], pythonfmu=True) == "calculated"]
    for structure in root.findall("ModelStructure"):
        for old in structure.findall("InitialUnknowns"):
            structure.remove(old)
        if calculated:
            unknowns = ET.SubElement(structure, "InitialUnknowns")
            for i in calculated:
                ET.SubElement(unknowns, "Unknown", {"index": str(i)})
    for cs in root.findall("CoSimulation"):
        # one communication step is one sample: a step of another size is refused
        # (strict_step_size) or processed with a warning, never resampled
        cs.set("canHandleVariableCommunicationStepSize", "false")
    for old in root.findall("UnitDefinitions") + root.findall("DefaultExperiment"):
        root.remove(old)
    if used:
        ud = ET.Element("UnitDefinitions")
        for unit, base in sorted(used.items()):
            u = ET.SubElement(ud, "Unit", {"name": unit})
            ET.SubElement(u, "BaseUnit", base)
        root.append(ud)
    root.append(ET.Element("DefaultExperiment", {"startTime": "0.0", "stepSize": repr(DEFAULT_STEP_SIZE_S)}))
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
