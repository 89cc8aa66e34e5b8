"""The version of gyrodenoise: one place, read by the package, its FMUs and pyproject.toml."""

__version__ = "0.1.0"
