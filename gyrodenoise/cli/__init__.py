"""The ``gyrodenoise`` command line: one thin layer over the library.

* :mod:`gyrodenoise.cli.program` -- the top-level parser, the one-line error form, exit statuses;
* :mod:`gyrodenoise.cli.options` -- the options several commands share, with the core's defaults;
* :mod:`gyrodenoise.cli.commands` -- ``demo``, ``denoise``, ``allan``, ``compare``;
* :mod:`gyrodenoise.cli.gap` -- ``gap``;
* :mod:`gyrodenoise.cli.fmu` -- ``fmu build`` / ``fmu run`` / ...;
* :mod:`gyrodenoise.cli.mavlink` -- ``mavlink``.

Nothing below the CLI imports it.
"""

from gyrodenoise.cli.program import OneLineErrorParser, build_parser, emit_json, entry, main

__all__ = ["OneLineErrorParser", "build_parser", "emit_json", "entry", "main"]
