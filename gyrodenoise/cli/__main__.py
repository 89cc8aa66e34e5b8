"""``python -m gyrodenoise.cli``: the same as the ``gyrodenoise`` command."""

from gyrodenoise.cli.program import entry

entry()
