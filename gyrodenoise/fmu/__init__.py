"""FMUs of the project, split by concern:

* :mod:`.build` -- ``gyrodenoise fmu build`` (pythonfmu, bundled core);
* :mod:`.host` -- one FMU instance through fmpy's ``FMU2Slave``;
* :mod:`.validation` -- the fmpy-scripted SimulatedFog -> FogDenoiser run;
* :mod:`.variables` -- every FMU's variables, declared once per model;
* :mod:`.native`, :mod:`.simnative` -- FogDenoiserNative.fmu and SimulatedFogNative.fmu (C, no Python),
  :mod:`.nativemodel` what they share;
* :mod:`.cosim` -- the SSP file and libcosimpy;
* ``sources/`` -- the FMUs' own sources (pythonfmu slaves, the native C FMI layer).

The ``gyrodenoise fmu`` subcommands live in :mod:`gyrodenoise.cli.fmu`.

The names below are re-exported so ``from gyrodenoise import fmu as F`` keeps working.
"""

from gyrodenoise.fmu.build import (CORE_INIT, FMU_SRC, FMUS, PACKAGE_DIR, build_all, build_fmu, compiled_core_files,
                    stage_core, stale_reason)
from gyrodenoise.fmu.cosim import cosim_run, system_parameters, write_ssp
from gyrodenoise.fmu.host import FmuInstance, FmuStepError, _stepper
from gyrodenoise.fmu.validation import compare_with_core, validation_run

__all__ = ["compiled_core_files", "CORE_INIT", "FMU_SRC", "FMUS", "PACKAGE_DIR", "build_all", "build_fmu", "stage_core",
           "stale_reason", "cosim_run", "system_parameters", "write_ssp", "FmuInstance",
           "FmuStepError", "_stepper", "compare_with_core", "validation_run"]
