"""The ``gyrodenoise`` command: a thin argparse layer over the core.

Each subcommand module exposes ``register_cli(subparsers)``, which adds its
parser and sets ``func`` (a callable taking the parsed namespace and returning
an exit status). No maths here.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys

from gyrodenoise.errors import InputError, Terminated

# modules that add subcommands: (module path, attribute)
_SUBCOMMAND_MODULES = [
    "gyrodenoise.cli.commands",   # demo, denoise, allan, compare
    "gyrodenoise.cli.gap",        # gap
    "gyrodenoise.cli.mavlink",    # mavlink
    "gyrodenoise.cli.fmu",        # fmu build / run / ...
    "gyrodenoise.cli.fleet",      # fleet-trends
]


class OneLineErrorParser(argparse.ArgumentParser):
    """argparse with the contract's error form: one line on stderr naming the command
    and what was wrong, exit 2 (argparse prints the whole usage block first). Unknown
    options are reported by the (sub)command that was given them, not by the top level.
    Subcommand parsers inherit the class (``add_subparsers`` uses the parent's type).

    ``json_errors=True`` (``add_parser(..., json_errors=True)``), for a command with
    ``--json``: its usage errors take the form of its input errors,
    ``gyrodenoise: error: NAME: message``, and when ``--json`` was given one JSON object
    ``{"error": ..., "exit_status": 2}`` is printed on stdout too."""

    def __init__(self, *args, json_errors=False, **kwargs):
        super().__init__(*args, **kwargs)
        self.json_errors = json_errors
        self._json_requested = False

    def parse_known_args(self, args=None, namespace=None):
        self._json_requested = self.json_errors and args is not None and "--json" in list(args)
        ns, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return ns, extras

    def error(self, message):
        if self.json_errors:
            message = f"{self.prog.removeprefix('gyrodenoise ')}: {message}"
            if self._json_requested:
                emit_json({"error": message, "exit_status": 2})
            print(f"gyrodenoise: error: {message} (see {self.prog} --help)", file=sys.stderr)
        else:
            print(f"{self.prog}: error: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)


def build_parser():
    import importlib
    parser = OneLineErrorParser(
        prog="gyrodenoise",
        description="Gyro denoising: online improved AR(n) model + modified Sage-Husa AKF, "
                    "Allan variance, simulated gyros, FMUs and a MAVLink bridge.")
    from gyrodenoise import __version__
    parser.add_argument("--version", action="version", version=f"gyrodenoise {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for modname in _SUBCOMMAND_MODULES:
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as exc:
            if exc.name and modname.startswith(exc.name):
                continue  # that part is not there yet
            raise
        if hasattr(mod, "register_cli"):
            mod.register_cli(sub)
    return parser


def emit_json(obj):
    """Print exactly one JSON object on stdout (strict JSON: no NaN or inf), flushed."""
    sys.stdout.write(json.dumps(obj, indent=None, allow_nan=False) + "\n")
    sys.stdout.flush()


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        with _interrupts_as_exceptions():
            return int(args.func(args) or 0)
    except InputError as exc:
        if getattr(args, "json", False):        # --json: the error is also one JSON object on stdout
            emit_json({"error": str(exc), "exit_status": 2})
        print(f"gyrodenoise: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        # a module of an extra that is not installed, reached past the commands' own checks
        from gyrodenoise._extras import extra_of
        extra = extra_of(exc.name)
        if extra is None:
            raise
        print(f"gyrodenoise: error: this command needs {exc.name}, not installed: "
              f"pip install 'gyrodenoise[{extra}]'", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"gyrodenoise: interrupted (SIGINT), stopped{_stop_note(exc)}", file=sys.stderr)
        return 130
    except Terminated as exc:
        print(f"gyrodenoise: terminated (SIGTERM), stopped{_stop_note(exc)}", file=sys.stderr)
        return 143


def _stop_note(exc):
    """'; <what was kept>' when the command said so on the exception (``stop_note``)."""
    note = getattr(exc, "stop_note", None)
    return f"; {note}" if note else ""


@contextlib.contextmanager
def _interrupts_as_exceptions():
    """SIGINT raises KeyboardInterrupt and SIGTERM :class:`Terminated` in the main
    thread, once: the first one starts the clean-up (``finally`` blocks stop the
    child processes and delete partial files), further ones while it runs are
    ignored (a second Ctrl-C would break the clean-up with a traceback), and
    stay so until the exit. Without a signal the previous handlers are restored
    on the way out. Exit status 130 / 143 (spec)."""
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = []

    def handler(signum, frame):
        if fired:
            return
        fired.append(signum)
        raise KeyboardInterrupt if signum == signal.SIGINT else Terminated()

    old = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        if not fired:
            for sig, h in old.items():
                signal.signal(sig, h)


def entry():
    """Console-script entry point: :func:`main`, then a fast exit.

    Everything the command writes is closed before :func:`main` returns; what
    is left is interpreter teardown (matplotlib, scipy module graphs),
    measured at ~0.3 s per run by the bridge benchmark. So flush the
    standard streams and leave with ``os._exit``. Tests call :func:`main`.

    An interrupted run (130, 143) leaves through the normal exit instead: its
    process pool's finalizers then release the pool's semaphores (a pool of spawned
    workers registers them with multiprocessing's resource tracker, which would
    otherwise print "leaked semaphore" warnings after the one-line message).
    """
    import os
    status = main()
    if status in (130, 143):
        sys.exit(status)
    try:
        sys.stdout.flush()
    except (BrokenPipeError, ValueError):
        pass  # reader went away (e.g. `| head`) or stream already closed
    try:
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):
        pass
    os._exit(status)


if __name__ == "__main__":
    entry()
