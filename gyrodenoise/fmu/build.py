"""Build the FMUs: ``gyrodenoise fmu build``.

Packages ``gyrodenoise/fmu/sources/fogdenoiser_fmu.py`` and ``gyrodenoise/fmu/sources/simulatedfog_fmu.py`` with
pythonfmu (in a subprocess) into ``FogDenoiser.fmu`` and ``SimulatedFog.fmu``.
The FMUs carry a copy of the core (package ``gdcore`` in their resources: the
plain-Python kernels, the compiled C core ``core/_gdcore*.so`` of this build, used
when the host's Python and platform fit it, and the variable declaration
``fmu/variables.py``), so they run wherever Python is, from any directory,
without this package installed. Everything is read from the package itself
(an installed copy builds its FMUs); only the output folder is the caller's.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from gyrodenoise.errors import InputError

PACKAGE_DIR = Path(__file__).resolve().parents[1]   # gyrodenoise/
FMU_SRC = Path(__file__).resolve().parent / "sources"

#: model name -> (slave script, modules of the package bundled as ``gdcore``, paths relative to
#: PACKAGE_DIR); the variable declaration ``fmu/variables.py`` is bundled with each
FMUS = {
    "FogDenoiser": ("fogdenoiser_fmu.py", ("core/__init__.py", "core/kernels.py", "core/methods.py", "denoiser.py",
                                           "errors.py", "fmu/variables.py")),
    "SimulatedFog": ("simulatedfog_fmu.py", ("core/__init__.py", "core/methods.py", "core/simkernels.py",
                                             "errors.py", "simulator.py", "units.py", "fmu/variables.py")),
}


#: Shared by the pythonfmu slaves, bundled next to each slave script (FMI rules and
#: pythonfmu work-arounds; gyrodenoise/fmu/sources/gyrodenoise_pythonfmu_rules.py)
SLAVE_HELPERS = ("gyrodenoise_pythonfmu_rules.py",)


def compiled_core_files():
    """The built C core extension(s) beside core/kernels.py (none if not built)."""
    return sorted((PACKAGE_DIR / "core").glob("_gdcore*.so")) + sorted((PACKAGE_DIR / "core").glob("_gdcore*.pyd"))

CORE_INIT = '''"""Plain-Python part of the gyrodenoise core, bundled into an FMU.

Copied from gyrodenoise {version} by ``gyrodenoise fmu build``; the FMU's slave imports
it under a private name. Only the per-sample path is here (no numba, no scipy).
"""
__version__ = "{version}"
'''


def _sources_dir(src_dir=None):
    d = Path(src_dir) if src_dir is not None else FMU_SRC
    if not d.is_dir():
        raise InputError(f"{d}: FMU sources not found (gyrodenoise/fmu/sources/ of the package)")
    return d


def stage_core(dest, modules):
    """Write the minimal core package ``gdcore`` into ``dest``; return its path."""
    from gyrodenoise._version import __version__
    pkg = Path(dest) / "gdcore"
    pkg.mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text(CORE_INIT.format(version=__version__))
    for name in modules:
        src = PACKAGE_DIR / name
        if not src.is_file():
            raise InputError(f"{src}: core module missing, cannot bundle it into the FMU")
        (pkg / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, pkg / name)
    if "core/__init__.py" in modules:   # the C core, as built for this Python and platform
        for so in compiled_core_files():
            shutil.copy2(so, pkg / "core" / so.name)
    if "simulator.py" in modules:   # the embedded model cards (load_card by name)
        (pkg / "data").mkdir(exist_ok=True)
        for card in sorted((PACKAGE_DIR / "data").glob("*.toml")):
            shutil.copy2(card, pkg / "data" / card.name)
    return pkg


def build_fmu(name, out_dir="build", src_dir=None, python=None):
    """Build one FMU (``name`` in :data:`FMUS`) into ``out_dir``; return its path.

    pythonfmu runs in a subprocess so that it imports the staged copy of the
    slave script, never the source tree or a module cached in this process.
    """
    if name not in FMUS:
        raise InputError(f"unknown FMU {name!r}; known: {', '.join(FMUS)}")
    script, modules = FMUS[name]
    src = _sources_dir(src_dir) / script
    if not src.is_file():
        raise InputError(f"{src}: slave script not found")
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"gd_fmu_{name}_") as tmp:
        stage = Path(tmp) / "stage"
        stage.mkdir()
        shutil.copy2(src, stage / script)
        for helper in SLAVE_HELPERS:
            shutil.copy2(src.parent / helper, stage / helper)
        pkg = stage_core(stage, modules)
        cmd = [python or sys.executable, "-m", "pythonfmu", "build",
               "-f", str(stage / script), "-d", str(out),
               "--handle-state", "--serialize-state", str(pkg)] + [str(stage / h) for h in SLAVE_HELPERS]
        env = dict(os.environ)
        env.pop("PYTHONPATH", None)
        proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"pythonfmu build of {name} failed ({proc.returncode}):\n"
                               f"{proc.stdout}\n{proc.stderr}")
    path = out / f"{name}.fmu"
    if not path.is_file():
        raise RuntimeError(f"pythonfmu did not write {path}")
    from gyrodenoise.fmu.model_description import complete
    complete(path)      # units, DefaultExperiment, min/max (pythonfmu cannot declare them)
    return add_documentation(path, name)


def add_documentation(fmu_path, name):
    """Add the reference results of model ``name`` (:func:`gyrodenoise.fmu.reference.reference_documents`:
    ``documentation/<name>_in.csv`` and ``_ref.csv``) to the FMU at ``fmu_path``; returns the path."""
    import zipfile

    from gyrodenoise.fmu.reference import reference_documents
    docs = reference_documents(name)
    with zipfile.ZipFile(fmu_path, "a", zipfile.ZIP_DEFLATED) as z:
        present = set(z.namelist())
        for fname, data in sorted(docs.items()):
            if f"documentation/{fname}" not in present:
                z.writestr(f"documentation/{fname}", data)
    return Path(fmu_path)


def stale_reason(fmu_path, src_dir=None):
    """Why the FMU at ``fmu_path`` no longer matches the package's sources, or None.

    Compares the bundled core modules and slave script with the package's files.
    """
    import zipfile
    name = Path(fmu_path).stem
    if name not in FMUS:
        return None
    script, modules = FMUS[name]
    if not Path(fmu_path).is_file():
        return "missing"
    wanted = {f"resources/gdcore/{m}": PACKAGE_DIR / m for m in modules}
    if "core/__init__.py" in modules:
        wanted.update({f"resources/gdcore/core/{so.name}": so for so in compiled_core_files()})
    src = _sources_dir(src_dir) / script
    if src.is_file():
        wanted[f"resources/{script}"] = src
        wanted.update({f"resources/{h}": src.parent / h for h in SLAVE_HELPERS})
    with zipfile.ZipFile(fmu_path) as z:
        names = set(z.namelist())
        for arc, local in wanted.items():
            if arc not in names or z.read(arc) != local.read_bytes():
                return f"{arc} differs from {local}"
    return None


def build_all(out_dir="build", src_dir=None, names=None):
    """Build the FMUs (all by default); return {name: path}."""
    return {n: build_fmu(n, out_dir, src_dir) for n in (names or FMUS)}
