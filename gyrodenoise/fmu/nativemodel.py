"""What makes one native FMU (:class:`NativeModel`), and where its C sources are.

Shared by the native FMUs' modules: :mod:`gyrodenoise.fmu.native` (FogDenoiserNative, and
the build of any native FMU) and :mod:`gyrodenoise.fmu.simnative` (SimulatedFogNative).
Every path is inside the installed package.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parents[1]      # gyrodenoise/
CORE_DIR = PACKAGE_DIR / "core"                        # gdcore.c, gdsim.c and their headers
NATIVE_SRC = Path(__file__).resolve().parent / "sources" / "native"
#: the FMI layer shared by every native FMU (in NATIVE_SRC)
LAYER_FILES = ("gdfmi.c", "gdfmi2.c", "gdfmi3.c", "gdfmi.h", "gdfmi_libm.h")


class NativeModel:
    """One native FMU: its name, variables, C sources and resources.

    ``variables``: a tuple of :class:`gyrodenoise.fmu.variables.Variable` in value-reference
    order. ``c_source``: the model's hooks (in :data:`NATIVE_SRC`), ``unity``: the one file
    compiled (it includes ``c_source``, the FMI layer and the core files), ``core_files``:
    paths of the core's C files, ``units``: {FMI unit name: BaseUnit attributes} declared.
    ``header_lines``: extra lines of the generated C header, or a function () -> lines
    (read at build time); ``resources``: None or a function () -> {path in resources/: bytes}.
    ``extra_sources``: more C files of :data:`NATIVE_SRC` the unity file includes;
    ``fmi_version``: 2 or 3 (the unity file of a 3 defines ``GD_FMI_VERSION 3``);
    ``xml_writer``: None (FMI 2.0) or a function (guid, model) -> modelDescription.xml text;
    ``binary_folder``: None (the FMI 2.0 platform name) or a function (platform) -> the folder
    under binaries/.
    """

    def __init__(self, name, description, variables, step_size, c_source, unity, core_files,
                 units, header_lines=(), resources=None, extra_sources=(), fmi_version=2,
                 xml_writer=None, binary_folder=None):
        self.name = name
        self.description = description
        self.variables = variables
        self.step_size = step_size
        self.c_source = c_source
        self.unity = unity
        self.vars_header = c_source.replace(".c", "_vars.h")
        self.core_files = core_files
        self.units = units
        self.header_lines = header_lines
        self.resources = resources
        self.extra_sources = tuple(extra_sources)
        self.fmi_version = fmi_version
        self.xml_writer = xml_writer
        self.binary_folder = binary_folder

    def replace(self, **changes):
        """A copy with the attributes in ``changes`` (the constructor's names) replaced."""
        fields = ("name", "description", "variables", "step_size", "c_source", "unity", "core_files",
                  "units", "header_lines", "resources", "extra_sources", "fmi_version", "xml_writer",
                  "binary_folder")
        kw = {f: getattr(self, f) for f in fields}
        kw.update(changes)
        return NativeModel(**kw)

    def value_references(self):
        """{variable name: value reference}."""
        return {v.name: i for i, v in enumerate(self.variables)}
