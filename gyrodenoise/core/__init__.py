"""The numerical core of gyrodenoise, in one place.

* ``kernels.py`` -- the per-sample filters (RLS, KF, SHAKF, outlier gate,
  ``motion``, ``lowpass``, state save/restore) as plain scalar Python over two
  flat float buffers: the executable specification;
* ``gdcore.h`` / ``gdcore.c`` -- the same functions in portable C99 (libm only),
  operation for operation; what every adapter runs;
* ``_gdcoremodule.c`` -- the CPython extension ``gyrodenoise.core._gdcore``
  (``step``, ``run``, ``restart`` over float64 buffers), built by ``pip install``
  through ``setup.py``;
* ``batch.py`` -- the array loop over the extension (or the kernels).

Adapters (``gyrodenoise.Denoiser``, the CLI, the bridge, the FMUs) call these
and contain no maths.
"""
