"""The optional parts of the package, by user: which extra installs what.

``pip install gyrodenoise`` brings numpy, scipy and the C core (denoise, allan, simulate,
gap, demo, the CLI for recordings). The rest comes with an extra (pyproject.toml
``[project.optional-dependencies]``, which holds the versions); a command that needs one
calls :func:`require` before it starts, and a missing extra is one line naming it
(:class:`MissingExtra`, an :class:`~gyrodenoise.errors.InputError`: exit 2 from the CLI).
"""

from __future__ import annotations

import importlib.util

from gyrodenoise.errors import InputError

#: extra -> the modules (top-level import names) of the distributions it installs
EXTRAS: dict[str, tuple[str, ...]] = {
    "logs": ("pymavlink", "pyulog", "rosbags", "tqdm"),
    "fmu": ("fmpy", "pythonfmu", "ziglang"),
    "report": ("matplotlib", "plotly"),
    "cluster": ("distributed", "fsspec"),
    "mat": ("h5py",),
    "fleet": ("pyarrow", "duckdb"),
    "fast": ("pyarrow",),        # optional speed: the CSV reader falls back to its own loop without it
}


class MissingExtra(InputError):
    """A command needs modules of an extra that is not installed."""

    def __init__(self, what: str, extra: str, missing: list[str]) -> None:
        self.extra = extra
        self.missing = missing
        super().__init__(f"{what} needs {', '.join(missing)}, not installed: "
                         f"pip install 'gyrodenoise[{extra}]'")


def missing(extra: str, *modules: str) -> list[str]:
    """The modules of ``extra`` (all of them, or those named) that cannot be imported here."""
    if extra not in EXTRAS:
        raise ValueError(f"unknown extra {extra!r}; known: {', '.join(EXTRAS)}")
    names = modules or EXTRAS[extra]
    unknown = [m for m in names if m not in EXTRAS[extra]]
    if unknown:
        raise ValueError(f"{', '.join(unknown)} is not a module of the extra {extra!r}")
    return [m for m in names if importlib.util.find_spec(m) is None]


def require(extra: str, *modules: str, what: str = "this command") -> None:
    """Raise :class:`MissingExtra` (one line: what needs which modules, the pip command) unless
    the modules of ``extra`` (all of them, or those named) can be imported."""
    absent = missing(extra, *modules)
    if absent:
        raise MissingExtra(what, extra, absent)


def extra_of(module: str | None) -> str | None:
    """The extra that installs ``module`` (a dotted name: its top level counts), or None."""
    top = (module or "").partition(".")[0]
    return next((extra for extra, mods in EXTRAS.items() if top in mods), None)
