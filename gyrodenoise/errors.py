"""User-facing errors: one line that names the file, field or line and what is wrong.

The CLI turns `InputError` into that line on stderr and exit status 2,
with no traceback. Library callers get the exception.
"""

from __future__ import annotations

import os


class InputError(ValueError):
    """Bad input (file, field, parameter) from the user; message is one line."""

    def __init__(self, message: str, source: str | os.PathLike[str] | None = None) -> None:
        if source is not None:
            message = f"{source}: {message}"
        super().__init__(message)


class Terminated(BaseException):
    """Raised in the main thread by the CLI's SIGTERM handler (exit status 143), as
    KeyboardInterrupt is by SIGINT (130): ``finally`` blocks run, children are stopped."""
